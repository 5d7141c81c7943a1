"""Grid convergence of the column collapse: run-out against the cell size, fluidised and not.

    python examples/column_convergence.py                      # ny = 32, 64, 128, 256: what docs/validation.md reports
    python examples/column_convergence.py --ny 32 64 --threads 2 --out out/convergence
    python examples/column_convergence.py --channel-width 0.1 --out out/convergence-walls   # with side walls

Grids from ny = 128 up run on the active region with open right and top sides (BAND = ny/16
cells of air, the same 28 mm at every grid; `--active-region BAND --active-region-sides
open-right-top`, docs/models.md), coarser ones on the whole domain. Run time on the 2-core
development machine, one thread per run (default numerics):
ny = 32 about 10 s per run, ny = 64 about 1–2.5 min, ny = 128 about 2–3 min, ny = 256 about
23 min dry and 25–30 min fluidised (about 1 h for the whole study, two runs at a time). Each
finished run is kept in ``OUT/{fluidised,dry}-{ny}/`` and skipped when the script is run again,
so a study can be extended one grid at a time.

What it writes into ``OUT``:

* ``convergence.csv``: ny, h, run-out (fluidised, dry), their ratio, the differences between
  successive grids, wall times;
* ``runout_vs_h.png``: run-out against h with the paper's simulated (1.6874 m) and experimental
  (1.8443 m) fluidised run-outs;
* ``front_curves.png``: front position against time for every run.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from granrs.cases.column import PAPER_RUNOUT_EXP, PAPER_RUNOUT_SIM, ColumnCase, run_column


# from this grid up the runs take the active region with open right and top sides
ACTIVE_REGION_FROM_NY = 128


def case_for(ny: int, fluidised: bool, threads: int, channel_width) -> ColumnCase:
    """The study's case on the grid ny: the whole domain below ACTIVE_REGION_FROM_NY, the open
    active window (BAND = ny/16) from it up."""
    window = dict(active_region=ny // 16, active_region_sides="open-right-top") if ny >= ACTIVE_REGION_FROM_NY else {}
    return ColumnCase(ny=ny, fluidised=fluidised, threads=threads, channel_width=channel_width, **window)


def run_or_load(ny: int, fluidised: bool, out: Path, threads: int, channel_width=None) -> dict:
    """The run's summary.json, running the case first if it is not there yet."""
    folder = out / f"{'fluidised' if fluidised else 'dry'}-{ny}"
    summary = folder / "summary.json"
    if not summary.exists():
        print(f"running ny = {ny}, {'fluidised' if fluidised else 'dry'} ...", flush=True)
        run_column(case_for(ny, fluidised, threads, channel_width), folder, progress=True)
    return json.loads(summary.read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ny", type=int, nargs="+", default=[32, 64, 128, 256])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", default="out/convergence")
    ap.add_argument("--channel-width", dest="channel_width", type=float, default=None,
                    help="friction of side walls this far apart (m; not in the paper's 2D model)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    rows = []
    for ny in sorted(args.ny):
        wet, dry = (run_or_load(ny, fl, out, args.threads, args.channel_width) for fl in (True, False))
        rows.append({"ny": ny, "h_m": wet["h_m"], "runout_fluidised_m": wet["runout_m"], "runout_dry_m": dry["runout_m"],
                     "ratio": wet["runout_m"] / dry["runout_m"], "wall_fluidised_s": wet["wall_s"], "wall_dry_s": dry["wall_s"],
                     "mass_rel_error_max": max(wet["mass_rel_error"], dry["mass_rel_error"])})
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

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h = np.array([r["h_m"] for r in rows]) * 1e3
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    ax.plot(h, [r["runout_fluidised_m"] for r in rows], "o-", label="fluidised (β = 0.9)")
    ax.plot(h, [r["runout_dry_m"] for r in rows], "s-", label="non-fluidised")
    ax.axhline(PAPER_RUNOUT_SIM, color="k", ls="--", lw=1, label=f"paper, simulation (h = 1.76 mm): {PAPER_RUNOUT_SIM} m")
    ax.axhline(PAPER_RUNOUT_EXP, color="k", ls=":", lw=1.5, label=f"paper, experiment: {PAPER_RUNOUT_EXP} m")
    ax.axvline(0.45 / 256 * 1e3, color="grey", lw=0.8)
    walls = f", side walls {100 * args.channel_width:g} cm apart" if args.channel_width else ""
    ax.set(xscale="log", xlabel="cell size h (mm)", ylabel="run-out from the gate (m)",
           title=f"Column collapse{walls}: run-out against the grid")
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
            data = np.genfromtxt(out / f"{'fluidised' if fl else 'dry'}-{row['ny']}" / "front.csv", delimiter=",",
                                 skip_header=1, ndmin=2)
            ax.plot(data[:, 0], data[:, 1], style, color=f"C{k}", lw=1.5,
                    label=f"ny = {row['ny']}, {'fluidised' if fl else 'dry'}")
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
