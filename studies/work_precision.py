"""Work-precision chart of the column collapse: error against wall time, for every grid and every
model or method variant granrs offers.

    python studies/work_precision.py                          # ny = 16, 32, 64 (+ 128 if present)
    python studies/work_precision.py --ny 16 32 64 128        # the fine reference runs too (hours)
    python studies/work_precision.py --ny 128 --variants "D-P (default)" "granular (no air)"
    python studies/work_precision.py                          # then the rest; stored runs are reused
    python studies/work_precision.py --plot-only              # redraw from the stored CSV
    python studies/work_precision.py --rows-of depth-averaged --reference-from docs/img/ny256
                                                              # one variant's rows rerun in the stored CSV

Each run is the paper's column (``granrs run column``, docs/reference-data.md) to t = 3 s, one
thread, fluidised and not, kept in ``OUT/<variant>/<fluidised|dry>-<ny>/`` and skipped when the
script is run again (the same layout as ``studies/column_convergence.py``, whose runs can be
pointed at with ``--reference-from``). Errors, for each run:

* ``runout_err_ref``: |run-out − run-out of the finest D-P run| / that run-out (the finest grid
  present, fluidised or dry alike) — the discretisation error as far as the finest grid can tell;
* ``runout_err_exp``: |run-out − 1.8443 m| / 1.8443 m, fluidised runs only (the experiment;
  the paper's own simulation is at 8.5 %);
* ``front_err_ref``: RMS over t ∈ [0, 3 s] of the front-position difference with the finest run,
  over its run-out (the whole front curve, not only its end).

Writes ``docs/img/work_precision.csv`` and ``docs/img/work_precision.png`` (log-log, one line per
variant through its grids, fluidised solid, dry dashed). Run time on the 2-core development
machine, one run at a time: ny = 16 ≈ 5 s, 32 ≈ 15 s, 64 ≈ 3 min, 128 ≈ 25 min per run and variant.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from granrs import ActiveRegion, DepthAveraged, PorePressure, TimeStepping
from granrs.cases.column import PAPER_RUNOUT_EXP, ColumnCase, Fluidisation, jop_mu_i, run_column

# variant name → ColumnCase keyword arguments (the baseline first: the finest of its runs is the
# reference). Models and methods that granrs offers for this scene.
VARIANTS = {
    "D-P (default)": {},
    "mu(I)": {"rheology": jop_mu_i(27.0, grain_diameter=75e-6, grain_density=2500.0, viscosity=0.1)},
    "D-P, CFL 0.25": {"time": TimeStepping(cfl=0.25)},
    "D-P, p_f kappa-infinity": {"pore_pressure": PorePressure(0.035, kappa_air=1e8, formulation="kappa-infinity")},
    # the depth-averaged rung of the model ladder (docs/models.md); "ny" sets its cells per column
    # width in proportion (ColumnCase.depth_averaged.resolution is left at its default: its run-out changes by
    # < 1 % with Δx/2)
    "depth-averaged": {"model": "depth-averaged"},
    # the granular-only rung: no air, a free surface at p = 0 (docs/models.md)
    "granular (no air)": {"model": "granular"},
    # the active region (docs/models.md): the work restricted to the grains and a band of 8 cells
    "D-P, active region 8": {"active_region": ActiveRegion(8)},
    "granular, active region 8": {"model": "granular", "active_region": ActiveRegion(8)},
}
BASELINE = "D-P (default)"


def folder_of(out: Path, variant: str) -> Path:
    return out / variant.replace(" ", "_").replace("(", "").replace(")", "").replace(",", "").replace(".", "p")


def run_or_load(variant: str, kwargs: dict, ny: int, fluidised: bool, out: Path, allow_run: bool) -> dict | None:
    folder = folder_of(out, variant) / f"{'fluidised' if fluidised else 'dry'}-{ny}"
    summary = folder / "summary.json"
    if not summary.exists():
        if not allow_run:
            return None
        print(f"running {variant}, ny = {ny}, {'fluidised' if fluidised else 'dry'} ...", flush=True)
        if kwargs.get("model") == "depth-averaged":  # its resolution: ny cells per column width
            kwargs = {**kwargs, "depth_averaged": DepthAveraged(resolution=ny)}
        try:
            run_column(
                ColumnCase(ny=ny, fluidisation=Fluidisation(fluidised=fluidised), **kwargs), folder, progress=False
            )
        except Exception as e:  # a failed run is a point of the chart too: reported, not plotted
            print(f"  failed: {e}", flush=True)
    if not summary.exists():
        return None
    s = json.loads(summary.read_text())
    if s.get("error"):
        print(f"  {variant} ny = {ny}: {s['error']}")
        return None
    data = np.genfromtxt(folder / "front.csv", delimiter=",", skip_header=1)
    s["front_t"], s["front_x"] = data[:, 0], data[:, 1]
    return s


def front_error(run: dict, ref: dict) -> float:
    t = np.linspace(0.0, min(run["front_t"][-1], ref["front_t"][-1]), 301)
    a = np.interp(t, run["front_t"], run["front_x"])
    b = np.interp(t, ref["front_t"], ref["front_x"])
    return float(np.sqrt(np.mean((a - b) ** 2)) / ref["runout_m"])


def plot(rows: list[dict], png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(16, 6.0))
    panels = [
        ("runout_err_ref", "run-out error vs finest D-P run"),
        ("runout_err_exp", f"run-out error vs experiment ({PAPER_RUNOUT_EXP} m)"),
        ("front_err_ref", "front-curve error (RMS) vs finest D-P run"),
    ]
    variants = list(dict.fromkeys(r["variant"] for r in rows))
    colours = dict(zip(variants, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
    for ax, (key, title) in zip(axes, panels):
        for v in variants:
            for fl, ls, mk in ((1, "-", "o"), (0, "--", "s")):
                pts = sorted(
                    (r["wall_s"], r[key], r["ny"])
                    for r in rows
                    if r["variant"] == v and r["fluidised"] == fl and r[key] not in ("", None) and float(r[key]) > 0
                )
                if not pts:
                    continue
                w, e, n = zip(*pts)
                ax.loglog(
                    w,
                    e,
                    ls,
                    marker=mk,
                    color=colours[v],
                    label=f"{v}, {'fluidised' if fl else 'dry'}",
                    mfc="white" if not fl else colours[v],
                )
                for wi, ei, ni in pts:
                    ax.annotate(
                        f"{int(ni)}", (wi, ei), textcoords="offset points", xytext=(4, 4), fontsize=7, color=colours[v]
                    )
        if key == "runout_err_exp":
            ax.axhline(0.085, color="grey", lw=0.8, ls=":")
            ax.text(
                ax.get_xlim()[0] if ax.has_data() else 1,
                0.085,
                " paper's simulation (8.5 %)",
                fontsize=8,
                va="bottom",
                color="grey",
            )
        ax.set_xlabel("wall time of the run [s] (one thread)")
        ax.set_ylabel("relative error")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=5, fontsize=8, frameon=False)
    fig.suptitle(
        "Column collapse (a = 2) to t = 3 s: work-precision (numbers at the points: ny; "
        "depth-averaged: cells per column width)"
    )
    fig.tight_layout(rect=(0, 0.1, 1, 0.97))
    fig.savefig(png, dpi=110)
    plt.close(fig)


def load_reference(folder: Path, fluidised: bool, ny: int) -> dict:
    """The finest D-P run's summary and front curve: FOLDER/{fluidised,dry}-NY/ (a run folder), or
    FOLDER/observables_{fluidised,dry}_summary.json and _front.csv (docs/img/ny256)."""
    state = "fluidised" if fluidised else "dry"
    run = folder / f"{state}-{ny}"
    summary, front = (
        (run / "summary.json", run / "front.csv")
        if run.is_dir()
        else (folder / f"observables_{state}_summary.json", folder / f"observables_{state}_front.csv")
    )
    s = json.loads(summary.read_text())
    data = np.genfromtxt(front, delimiter=",", skip_header=1)
    s["front_t"], s["front_x"] = data[:, 0], data[:, 1]
    return s


def update_rows(variants: list, nys: list, out: Path, csv_path: Path, png: Path, reference_from: Path) -> None:
    """The stored CSV with the rows of ``variants`` rerun at ``nys`` (the other rows kept), and the
    figure redrawn."""
    with open(csv_path) as f:
        rows = list(csv.DictReader(f))
    finest = int(rows[0]["reference_ny"])
    refs = {fl: load_reference(reference_from, fl, finest) for fl in (True, False)}
    kept = [r for r in rows if r["variant"] not in variants]
    for v in variants:
        for ny in nys:
            for fl in (True, False):
                r = run_or_load(v, VARIANTS[v], ny, fl, out, allow_run=True)
                if r is None:
                    continue
                ref = refs[fl]
                kept.append(
                    {
                        "variant": v,
                        "ny": ny,
                        "fluidised": int(fl),
                        "wall_s": r["wall_s"],
                        "steps": r["steps"],
                        "runout_m": r["runout_m"],
                        "runout_err_ref": abs(r["runout_m"] / ref["runout_m"] - 1),
                        "runout_err_exp": abs(r["runout_m"] / PAPER_RUNOUT_EXP - 1) if fl else "",
                        "front_err_ref": front_error(r, ref),
                        "reference_ny": finest,
                    }
                )
    order = {v: k for k, v in enumerate(dict.fromkeys(r["variant"] for r in rows))}
    kept.sort(key=lambda r: (order[r["variant"]], int(r["ny"]), -int(r["fluidised"])))
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(kept)
    plot([{k: (float(v) if k != "variant" and v != "" else v) for k, v in r.items()} for r in kept], png)
    print(f"wrote {csv_path} and {png}: the rows of {', '.join(variants)} (reference: D-P at ny = {finest})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ny", type=int, nargs="+", default=[16, 32, 64])
    ap.add_argument("--out", default="out/work_precision")
    ap.add_argument(
        "--reference-from",
        default=None,
        help="a column_convergence.py output folder whose {fluidised,dry}-NY runs serve as the baseline",
    )
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--docs", default="docs/img")
    ap.add_argument("--plot-only", action="store_true")
    ap.add_argument(
        "--rows-of",
        dest="rows_of",
        nargs="+",
        choices=list(VARIANTS),
        default=None,
        help="rerun only these variants and replace their rows in the stored CSV; the finest D-P run's "
        "front curves from --reference-from (FOLDER/{fluidised,dry}-NY/, or the observables_*_front.csv and "
        "_summary.json of docs/img/ny256)",
    )
    args = ap.parse_args()
    out, docs = Path(args.out), Path(args.docs)
    csv_path, png = docs / "work_precision.csv", docs / "work_precision.png"
    if args.rows_of:
        update_rows(args.rows_of, sorted(args.ny), out, csv_path, png, Path(args.reference_from))
        return
    if args.plot_only:
        with open(csv_path) as f:
            rows = [
                {k: (float(v) if k not in ("variant",) and v != "" else v) for k, v in r.items()}
                for r in csv.DictReader(f)
            ]
        plot(rows, png)
        return
    if args.reference_from:  # reuse the convergence study's runs as the baseline variant
        base = folder_of(out, BASELINE)
        base.mkdir(parents=True, exist_ok=True)
        for src in Path(args.reference_from).glob("*-*"):
            dst = base / src.name
            if src.is_dir() and not dst.exists():
                dst.symlink_to(src.resolve())
    runs = {}
    for v in [BASELINE] + [v for v in args.variants if v != BASELINE]:
        for ny in sorted(args.ny):
            for fl in (True, False):
                if not fl and "pore_formulation" in VARIANTS[v]:
                    continue  # a pore-pressure variant is the baseline when not fluidised
                r = run_or_load(v, VARIANTS[v], ny, fl, out, allow_run=True)
                if r is not None:
                    runs[(v, ny, fl)] = r
    # plus any runs stored in OUT on other grids (e.g. ny = 128 runs made by an earlier call with
    # --ny 128 --variants ...): the finest baseline grid that has both runs is the reference
    for v in [BASELINE] + [v for v in args.variants if v != BASELINE]:
        stored = sorted(
            {int(p.name.split("-")[1]) for p in folder_of(out, v).glob("*-*") if (p / "summary.json").exists()}
        )
        for ny in stored:
            for fl in (True, False):
                if (v, ny, fl) not in runs:
                    r = run_or_load(v, VARIANTS[v], ny, fl, out, allow_run=False)
                    if r is not None:
                        runs[(v, ny, fl)] = r
    finest = max(ny for (v, ny, fl) in runs if v == BASELINE and (BASELINE, ny, not fl) in runs)
    rows = []
    for (v, ny, fl), r in sorted(runs.items(), key=lambda kv: (kv[0][0], kv[0][1], not kv[0][2])):
        ref = runs[(BASELINE, finest, fl)]
        is_ref = (v, ny) == (BASELINE, finest)
        rows.append(
            {
                "variant": v,
                "ny": ny,
                "fluidised": int(fl),
                "wall_s": r["wall_s"],
                "steps": r["steps"],
                "runout_m": r["runout_m"],
                "runout_err_ref": "" if is_ref else abs(r["runout_m"] / ref["runout_m"] - 1),
                "runout_err_exp": abs(r["runout_m"] / PAPER_RUNOUT_EXP - 1) if fl else "",
                "front_err_ref": "" if is_ref else front_error(r, ref),
                "reference_ny": finest,
            }
        )
    docs.mkdir(parents=True, exist_ok=True)
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    plot(rows, png)
    print(f"wrote {csv_path} and {png} (reference: D-P at ny = {finest})")


if __name__ == "__main__":
    main()
