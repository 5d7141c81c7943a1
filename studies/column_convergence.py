"""Grid convergence of the column collapse: run-out against the cell size, fluidised and not.

    python studies/column_convergence.py                      # ny = 32, 64, 128, 256: what docs/validation.md reports
    python studies/column_convergence.py --ny 32 64 --threads 2 --out out/convergence
    python studies/column_convergence.py --ny 32 64 128 --jobs 2 --out out/convergence   # two runs at a time
    python studies/column_convergence.py --channel-width 0.1 --out out/convergence-walls   # with side walls
    python studies/column_convergence.py --ny 32 64 --literal-sign --out out/convergence  # + the literal air supply
    python studies/column_convergence.py --ensemble fluidised=out/ens-fl32 dry=out/ens-dry32   # round-off spreads
    python studies/column_convergence.py --interface-transport clsvof --out out/convergence-clsvof   # conservative interface

Grids from ny = 128 up run on the active region with open right and top sides (BAND = ny/16
cells of air, the same 28 mm at every grid; `--active-region BAND --active-region-sides
open-right-top`, docs/models.md), coarser ones on the whole domain. Run time on the 2-core
development machine, one thread per run (default numerics):
ny = 32 about 10 s per run, ny = 64 about 1–2.5 min, ny = 128 about 2–3 min, ny = 256 about
23 min dry and 25–30 min fluidised (about 1 h for the whole study, two runs at a time:
``--jobs 2`` runs them side by side, each in a process of its own, the finest grids first). Each
finished run is kept in ``OUT/{fluidised,dry}-{ny}/`` and skipped when the script is run again,
so a study can be extended one grid at a time; a run that was killed, interrupted or failed is
run again (``granrs.cases.column.run_finished``).

What it writes into ``OUT``:

* ``convergence.csv``: ny, h, run-out (fluidised, dry), their ratio, the differences between
  successive grids, wall times, the largest change of the dense area (``mass_rel_error``) and,
  with ``--interface-transport clsvof``, of the conserved volume (``volume_rel_error``);
* ``runout_vs_h.png``: run-out against h with the paper's simulated (1.6874 m) and experimental
  (1.8443 m) fluidised run-outs;
* ``front_curves.png``: front position against time for every run;
* ``observables.csv``: every observable of summary.json["observables"] (granrs.observables:
  thickness fronts, deposit quantiles, centre of mass and its travel, heights at the back wall and
  the gate) and the lowest-row run-out, per state (fluidised, dry, and with ``--literal-sign`` the
  fluidised column with the printed sign of the air supply, an outflow: Fluidisation.air_supply =
  'literal'), at each grid, with the successive differences d_k = x_k − x_{k−1}, their ratio
  r = d_k/d_{k−1}, a Richardson extrapolation x_∞ = x_N + d_N r/(1 − r) with the error bar |x_∞ − x_N|
  where the last three grids give 0 < r < 1 (monotone convergence), and the round-off spread (the
  standard deviation of the ny = 32 round-off ensemble, tests/data/column_observables_ensemble.csv)
  beside it.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from granrs import ActiveRegion, SideWalls, options
from granrs.cases.column import PAPER_RUNOUT_EXP, PAPER_RUNOUT_SIM, ColumnCase, Fluidisation, run_columns, run_finished
from granrs.observables import observable_keys

#: the round-off spread of every observable at ny = 32 (std over the members of
#: studies/runout_ensemble.py, tests/data/column_observables_ensemble.csv)
ENSEMBLE = Path(__file__).resolve().parents[1] / "tests" / "data" / "column_observables_ensemble.csv"


# from this grid up the runs take the active region with open right and top sides
ACTIVE_REGION_FROM_NY = 128


def case_for(
    ny: int, fluidised: bool, threads: int, channel_width, air_supply: str = "injection", transport: str | None = None
) -> ColumnCase:
    """The study's case on the grid ny: the whole domain below ACTIVE_REGION_FROM_NY, the open
    active window (BAND = ny/16) from it up; with ``transport = "clsvof"`` the interface moves the
    conserved volume fraction and the global mass correction is off."""
    window = dict(active_region=ActiveRegion(ny // 16, sides="open-right-top")) if ny >= ACTIVE_REGION_FROM_NY else {}
    side_walls = None if channel_width is None else SideWalls(channel_width, ColumnCase().base.friction_angle)
    fluidisation = Fluidisation(fluidised=fluidised, air_supply=air_supply)
    case = ColumnCase(ny=ny, fluidisation=fluidisation, threads=threads, side_walls=side_walls, **window)
    if transport == "clsvof":
        case = case.with_options(interface_transport="clsvof", mass_correction=False)
    return case


def run_folder(out: Path, ny: int, fluidised: bool, air_supply: str = "injection") -> Path:
    name = ("fluidised" if fluidised else "dry") + ("-literal" if air_supply == "literal" else "")
    return out / f"{name}-{ny}"


def load(out: Path, ny: int, fluidised: bool, air_supply: str = "injection") -> dict:
    """The finished run's summary.json."""
    return json.loads((run_folder(out, ny, fluidised, air_supply) / "summary.json").read_text())


def run_missing(runs: list, out: Path, args: argparse.Namespace) -> None:
    """Runs the study's unfinished runs (ny, fluidised, air_supply) with
    :func:`granrs.cases.column.run_columns`: one after the other in the order given, with their
    progress lines, or ``args.jobs`` at a time, the finest grids first (they take longest)."""
    todo = [r for r in runs if not run_finished(run_folder(out, *r))]
    if args.jobs > 1:
        todo.sort(key=lambda r: -r[0])
    for ny, fl, supply in todo:
        print(f"running ny = {ny}, {run_folder(out, ny, fl, supply).name} ...", flush=True)
    cases = [
        (
            case_for(ny, fl, args.threads, args.channel_width, supply, args.interface_transport),
            run_folder(out, ny, fl, supply),
        )
        for ny, fl, supply in todo
    ]
    run_columns(cases, jobs=args.jobs, progress=args.jobs == 1)


def round_off_spread() -> dict:
    """(state, observable) → the standard deviation over the ny = 32 round-off ensemble."""
    if not ENSEMBLE.exists():
        return {}
    lines = [line for line in ENSEMBLE.read_text().splitlines() if line and not line.startswith("#")]
    rows = csv.DictReader(lines)
    return {(r["state"], r["observable"]): float(r["std_m"]) for r in rows if int(r["ny"]) == 32}


def convergence_rows(state: str, summaries: list) -> list:
    """One row per observable of ``summaries`` (one per grid, coarse to fine): the values, the
    successive differences, their last ratio and, where it shows monotone convergence, the
    Richardson extrapolation with its error bar."""
    spread = round_off_spread()
    rows = []
    for key in ["runout_m"] + observable_keys() + ["centre_of_mass_travel_m"]:
        vals = [s["runout_m"] if key == "runout_m" else s["observables"].get(key) for s in summaries]
        row = {"state": state, "observable": key}
        for s, v in zip(summaries, vals):
            row[f"ny{s['ny']}"] = v
        diffs = [b - a if a is not None and b is not None else None for a, b in zip(vals, vals[1:])]
        for s, d in zip(summaries[1:], diffs):
            row[f"d{s['ny']}"] = d
        if len(diffs) >= 2 and diffs[-2] and diffs[-1] is not None:
            r = diffs[-1] / diffs[-2]
            row["ratio"] = r
            if 0.0 < r < 1.0:
                row["extrapolated"] = vals[-1] + diffs[-1] * r / (1.0 - r)
                row["error_bar"] = abs(row["extrapolated"] - vals[-1])
        row["round_off_std_ny32"] = spread.get((state, key))
        rows.append(row)
    return rows


def write_ensemble_statistics(specs: list, path: Path = ENSEMBLE) -> None:
    """``--ensemble STATE=DIR ...``: the mean, standard deviation (ddof = 1), min and max of every
    observable over the members ``DIR/member-K/summary.json`` of studies/runout_ensemble.py
    ensembles, into ``path`` (tests/data/column_observables_ensemble.csv)."""
    rows = []
    for spec in specs:
        state, folder = spec.split("=", 1)
        members = sorted(Path(folder).glob("member-*/summary.json"))
        summaries = [json.loads(m.read_text()) for m in members]
        for key in ["runout_m"] + observable_keys() + ["centre_of_mass_travel_m"]:
            vals = np.array(
                [s["runout_m"] if key == "runout_m" else s["observables"][key] for s in summaries], dtype=float
            )
            rows.append(
                {
                    "ny": summaries[0]["ny"],
                    "state": state,
                    "observable": key,
                    "members": len(vals),
                    "mean_m": vals.mean(),
                    "std_m": vals.std(ddof=1),
                    "min_m": vals.min(),
                    "max_m": vals.max(),
                }
            )
    with open(path, "w", newline="") as f:
        f.write(
            '# Round-off ensembles of the column\'s observables (granrs.observables; summary.json["observables"]):\n'
            "# studies/runout_ensemble.py --ny 32 --members 8 [--dry], member k with the column width scaled by\n"
            "# 1 + k*1e-12, then studies/column_convergence.py --ensemble fluidised=DIR dry=DIR.\n"
            "# 2-core x86-64 VM, 2026-12-01. Statistics over the members (std with ddof = 1): regression reference.\n"
        )
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for row in rows:
            w.writerow({k: (f"{v:.8g}" if isinstance(v, float) else v) for k, v in row.items()})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ny", type=int, nargs="+", default=[32, 64, 128, 256])
    ap.add_argument("--threads", type=int, default=1, help="threads of each run")
    ap.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="runs side by side, each in a process of its own (at most the free cores / --threads)",
    )
    ap.add_argument("--out", default="out/convergence")
    ap.add_argument(
        "--channel-width",
        dest="channel_width",
        type=float,
        default=None,
        help="friction of side walls this far apart (m; not in the paper's 2D model)",
    )
    ap.add_argument(
        "--literal-sign",
        dest="literal_sign",
        action="store_true",
        help="also run the fluidised column with the printed sign of the air supply (an outflow)",
    )
    ap.add_argument(
        "--interface-transport",
        dest="interface_transport",
        choices=list(options.spec("interface_transport").choices),
        default=options.spec("interface_transport").default,
        help="the interface's transport (Interface.transport); clsvof runs without the global mass correction",
    )
    ap.add_argument(
        "--ensemble",
        nargs="+",
        metavar="STATE=DIR",
        default=None,
        help="write the round-off spreads of the observables of these ensembles and stop",
    )
    args = ap.parse_args()
    if args.ensemble:
        write_ensemble_statistics(args.ensemble)
        return
    if args.jobs < 1:
        raise SystemExit(f"invalid parameter `--jobs` = {args.jobs}: allowed an integer >= 1")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    states = [("fluidised", True, "injection"), ("dry", False, "injection")]
    if args.literal_sign:
        states.append(("fluidised-literal", True, "literal"))
    run_missing([(ny, fl, supply) for _, fl, supply in states for ny in sorted(args.ny)], out, args)

    rows = []
    for ny in sorted(args.ny):
        wet, dry = (load(out, ny, fl) for fl in (True, False))
        rows.append(
            {
                "ny": ny,
                "h_m": wet["h_m"],
                "runout_fluidised_m": wet["runout_m"],
                "runout_dry_m": dry["runout_m"],
                "ratio": wet["runout_m"] / dry["runout_m"],
                "wall_fluidised_s": wet["wall_s"],
                "wall_dry_s": dry["wall_s"],
                "mass_rel_error_max": max(wet["mass_rel_error"], dry["mass_rel_error"]),
            }
        )
        # the conserved volume Σ F dx dy of clsvof runs (the level set's area is not conserved there)
        volume = [s["volume_rel_error"] for s in (wet, dry) if s.get("volume_rel_error") is not None]
        if volume:
            rows[-1]["volume_rel_error_max"] = max(volume)
    for prev, row in zip(rows, rows[1:]):
        row["diff_fluidised_m"] = row["runout_fluidised_m"] - prev["runout_fluidised_m"]
        row["diff_dry_m"] = row["runout_dry_m"] - prev["runout_dry_m"]
    keys = list(rows[-1].keys()) if len(rows) > 1 else list(rows[0].keys())
    with open(out / "convergence.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for row in rows:
            w.writerow({k: (f"{row[k]:.6g}" if isinstance(row.get(k), float) else row.get(k, "")) for k in keys})
    for row in rows:
        print(json.dumps(row))

    obs_rows = []
    for state, fl, supply in states:
        summaries = [load(out, ny, fl, supply) for ny in sorted(args.ny)]
        obs_rows += convergence_rows(state, summaries)
    keys = (
        ["state", "observable"]
        + [f"ny{ny}" for ny in sorted(args.ny)]
        + [f"d{ny}" for ny in sorted(args.ny)[1:]]
        + ["ratio", "extrapolated", "error_bar", "round_off_std_ny32"]
    )
    with open(out / "observables.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for row in obs_rows:
            w.writerow(
                {
                    k: (f"{row[k]:.5g}" if isinstance(row.get(k), float) else ("" if row.get(k) is None else row[k]))
                    for k in keys
                }
            )

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h = np.array([r["h_m"] for r in rows]) * 1e3
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    ax.plot(h, [r["runout_fluidised_m"] for r in rows], "o-", label="fluidised (β = 0.9)")
    ax.plot(h, [r["runout_dry_m"] for r in rows], "s-", label="non-fluidised")
    ax.axhline(
        PAPER_RUNOUT_SIM, color="k", ls="--", lw=1, label=f"paper, simulation (h = 1.76 mm): {PAPER_RUNOUT_SIM} m"
    )
    ax.axhline(PAPER_RUNOUT_EXP, color="k", ls=":", lw=1.5, label=f"paper, experiment: {PAPER_RUNOUT_EXP} m")
    ax.axvline(0.45 / 256 * 1e3, color="grey", lw=0.8)
    walls = f", side walls {100 * args.channel_width:g} cm apart" if args.channel_width else ""
    ax.set(
        xscale="log",
        xlabel="cell size h (mm)",
        ylabel="run-out from the gate (m)",
        title=f"Column collapse{walls}: run-out against the grid",
    )
    ax.grid(alpha=0.3, which="both")
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    ax.xaxis.set_major_formatter(ScalarFormatter())
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xticks(sorted(set(np.round(h, 2).tolist() + [round(0.45 / 256 * 1e3, 2)])))
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "runout_vs_h.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for k, row in enumerate(rows):
        for fl, style in ((True, "-"), (False, "--")):
            data = np.genfromtxt(
                out / f"{'fluidised' if fl else 'dry'}-{row['ny']}" / "front.csv", delimiter=",", skip_header=1, ndmin=2
            )
            ax.plot(
                data[:, 0],
                data[:, 1],
                style,
                color=f"C{k}",
                lw=1.5,
                label=f"ny = {row['ny']}, {'fluidised' if fl else 'dry'}",
            )
    ax.axhline(PAPER_RUNOUT_SIM, color="k", ls="--", lw=0.8)
    ax.axhline(PAPER_RUNOUT_EXP, color="k", ls=":", lw=1.2)
    ax.set(xlabel="t (s)", ylabel="front position from the gate (m)", title=f"Column collapse{walls}: front curves")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(out / "front_curves.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
