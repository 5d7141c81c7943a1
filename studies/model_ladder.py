"""The model ladder on the observables: how far is each cheaper model from the two-phase reference?

    python studies/model_ladder.py                                   # every run (30 min on a shared 2-core machine)
    python studies/model_ladder.py --reference-from out/convergence  # a = 2 references of column_convergence.py
    python studies/model_ladder.py --replot                          # redraw the figure from the stored table

For the column of the paper (L_c = 0.20 m, glass beads, α_b = 15°, κ_f = 0.035 m² s⁻¹,
β_s = 0.9) at aspect ratios a = H_c/L_c = 0.5, 1, 2, 4, fluidised and not, this script runs four
rungs at ny = 32,

1. ``depth-averaged``: the depth-averaged model on the same channel (``--model depth-averaged``,
   Δx = min(L_c, H_c)/64, Savage & Hutter's active earth-pressure coefficient), about a second;
2. ``granular``: the granular-only two-phase model, the air not resolved (``--model granular``);
3. ``window``: the two-phase model on its active region, a band of WINDOW_BAND cells of air with
   the default window sides (walls; ``--active-region 16``, docs/models.md);
4. ``two-phase``: the two-phase model on the whole domain (``granrs run column --ny 32
   --aspect-ratio A [--no-fluidised]``),

and the reference, the two-phase model at ny = REFERENCE_NY = 64 on the open active window of the
grid study (``--active-region 4 --active-region-sides open-right-top``, 4.3 times cheaper than the
whole domain at ny = 64, docs/models.md). At a = 2 the whole domain at ny = 64 is run too (or read
from ``--reference-from``, the folder of studies/column_convergence.py) and tabulated as the rung
``two-phase-64``: the reference's own error. For every
rung and scene it tabulates the relative error (rung − reference)/reference of the
well-conditioned observables of summary.json["observables"] (granrs.observables, docs/validation.md
"Observables": the 20 mm front, the travel of the centre of mass, the 50 and 90 % quantiles, the
heights at the back wall and the gate) and of the lowest-row run-out, with the run's wall time.
Outputs: ``docs/img/model_ladder.csv`` (one row per scene and rung, the reference's own values and
wall time in rows with rung ``reference``), ``docs/img/model_ladder.png``, run folders in
``out/ladder/``. Finished runs are re-read, not rerun (delete a folder to rerun it).

A two-phase run at ny = 32 that reaches the far end of its default channel (L_c + 8.25 H_c) is
rerun on a channel twice as long; the other rungs and the reference then use the same channel.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from dataclasses import replace
from pathlib import Path

from granrs import ActiveRegion, SimulationError
from granrs.cases.column import ColumnCase, ColumnGeometry, Fluidisation, run_column

ASPECT_RATIOS = (0.5, 1.0, 2.0, 4.0)
#: the rungs, cheapest first, and the case fields that make them
RUNGS = {
    "depth-averaged": dict(model="depth-averaged"),
    "granular": dict(model="granular"),
    "window": dict(model="two-phase", active_region=ActiveRegion(16)),
    "two-phase": dict(model="two-phase"),
}
WINDOW_BAND = RUNGS["window"]["active_region"].band
REFERENCE_NY = 64
#: the reference's numerics: the open window of the grid study from ny = 128 up
#: (studies/column_convergence.py), BAND = REFERENCE_NY/16 cells of air with open right and top
#: sides; its error against the whole domain is measured at a = 2 (rung "two-phase-64")
REFERENCE_WINDOW = dict(active_region=ActiveRegion(REFERENCE_NY // 16, sides="open-right-top"))
#: the observables compared (summary.json["observables"] keys, and the lowest-row run-out)
OBSERVABLES = {
    "front_h20mm_m": "20 mm front",
    "centre_of_mass_travel_m": "centre-of-mass travel",
    "q50_m": "50 % quantile",
    "q90_m": "90 % quantile",
    "h_back_wall_m": "h at the back wall",
    "h_gate_m": "h at the gate",
    "runout_m": "run-out, lowest row",
}
ROOT = Path(__file__).resolve().parents[1]


#: with ``--read-only``: tabulate the finished runs only, leave the others blank
READ_ONLY = False


def finished(summary: dict) -> bool:
    """Whether a summary.json is a finished run's (run_column rewrites a partial one every 0.1 s)."""
    return "wall_s" in summary and "observables" in summary and not summary["stop_reason"].startswith("error")


def run(case: ColumnCase, out: Path):
    """Runs the case into ``out`` (or re-reads it); on 'reached the far end' doubles the channel.
    With READ_ONLY, the finished run's summary or None."""
    summary_path = out / "summary.json"
    if summary_path.exists():
        s = json.loads(summary_path.read_text())
        if finished(s):
            return s
    if READ_ONLY:
        return None
    print(f"  running {out.name} ...", flush=True)
    while True:
        try:
            return run_column(case, out, progress=False)
        except SimulationError as err:
            if "far end" not in str(err):
                raise
            case = replace(case, geometry=replace(case.geometry, length=2.0 * case.domain()[0]))
            print(f"  {out.name}: reached the far end, rerun with length {case.geometry.length:.2f} m", flush=True)


def scene(aspect_ratio: float, fluidised: bool, length=None, **fields) -> ColumnCase:
    """The column of aspect ratio a, fluidised or dry, on a channel of ``length`` m (None: the
    column's own), with the other ``fields`` of the case."""
    geometry = ColumnGeometry(aspect_ratio=aspect_ratio, length=length)
    return ColumnCase(geometry=geometry, fluidisation=Fluidisation(fluidised=fluidised), **fields)


def value(summary, key: str):
    if summary is None:
        return None
    return summary["runout_m"] if key == "runout_m" else summary["observables"].get(key)


def run_facts(summary) -> dict:
    keys = ("wall_s", "stop_reason", "t_end_s")
    return {k: (summary[k] if summary else None) for k in keys}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ny", type=int, default=32, help="the rungs' grid (default 32)")
    ap.add_argument(
        "--reference-from",
        dest="reference_from",
        default=None,
        help="a folder of studies/column_convergence.py whose {fluidised,dry}-64 runs are the a = 2 references",
    )
    ap.add_argument("--read-only", dest="read_only", action="store_true", help="tabulate the finished runs only")
    ap.add_argument(
        "--replot", action="store_true", help="redraw docs/img/model_ladder.png from docs/img/model_ladder.csv, no runs"
    )
    args = ap.parse_args()
    if args.replot:
        rows = read_table(ROOT / "docs" / "img" / "model_ladder.csv")
        plot(
            rows,
            ROOT / "docs" / "img" / "model_ladder.png",
            int(next(r["ny"] for r in rows if r["rung"] == "two-phase")),
        )
        return
    global READ_ONLY
    READ_ONLY = args.read_only
    out = ROOT / "out" / "ladder"
    t_start = time.perf_counter()
    scenes = [(fl, a) for fl in (True, False) for a in ASPECT_RATIOS]
    tag = {s: f"a{s[1]:g}-{'fluidised' if s[0] else 'dry'}" for s in scenes}
    rungs: dict = {}
    # the cheap rungs of every scene first, then the references
    for fluidised, a in scenes:
        base = scene(a, fluidised, ny=args.ny)
        tp = run(replace(base, **RUNGS["two-phase"]), out / f"two-phase-{tag[fluidised, a]}")
        length = tp["case"]["geometry"]["length"] if tp else None  # None unless the channel had to be lengthened
        rungs[fluidised, a] = {"two-phase": tp}
        for name in ("depth-averaged", "granular", "window"):
            rungs[fluidised, a][name] = run(
                replace(base, geometry=replace(base.geometry, length=length), **RUNGS[name]),
                out / f"{name}-{tag[fluidised, a]}",
            )
    references = {}
    for fluidised, a in scenes:
        tp = rungs[fluidised, a]["two-phase"]
        length = tp["case"]["geometry"]["length"] if tp else None
        references[fluidised, a] = run(
            scene(a, fluidised, length=length, ny=REFERENCE_NY, **REFERENCE_WINDOW),
            out / f"reference-{REFERENCE_NY}-{tag[fluidised, a]}",
        )
    # the reference's own error: the whole domain at ny = REFERENCE_NY, a = 2
    whole = {}
    for fluidised in (True, False):
        folder = out / f"two-phase-{REFERENCE_NY}-{tag[fluidised, 2.0]}"
        if args.reference_from:
            folder = Path(args.reference_from) / f"{'fluidised' if fluidised else 'dry'}-{REFERENCE_NY}"
            while not READ_ONLY and not (
                (folder / "summary.json").exists() and finished(json.loads((folder / "summary.json").read_text()))
            ):  # still running in column_convergence.py
                time.sleep(20)
        whole[fluidised, 2.0] = run(scene(2.0, fluidised, ny=REFERENCE_NY), folder)

    rows = []
    for fluidised, a in scenes:
        ref = references[fluidised, a]
        row = {"aspect_ratio": a, "fluidised": fluidised, "rung": "reference", "ny": REFERENCE_NY}
        row.update({k: value(ref, k) for k in OBSERVABLES})
        row.update(run_facts(ref))
        rows.append(row)
        cheaper = dict(rungs[fluidised, a])
        if (fluidised, a) in whole:
            cheaper[f"two-phase-{REFERENCE_NY}"] = whole[fluidised, a]
        for name, s in cheaper.items():
            ny = REFERENCE_NY if name == f"two-phase-{REFERENCE_NY}" else args.ny
            row = {"aspect_ratio": a, "fluidised": fluidised, "rung": name, "ny": ny}
            row.update({k: value(s, k) for k in OBSERVABLES})
            for k in OBSERVABLES:
                v, r = value(s, k), value(ref, k)
                row[f"rel_{k}"] = (v - r) / r if v is not None and r else None
            row.update(run_facts(s))
            rows.append(row)
            print(
                json.dumps(
                    {
                        "a": a,
                        "fluidised": fluidised,
                        "rung": name,
                        **{OBSERVABLES[k]: round(100 * row[f"rel_{k}"], 1) for k in OBSERVABLES if row[f"rel_{k}"]},
                        "wall_s": round(s["wall_s"], 1) if s else None,
                    },
                    ensure_ascii=False,
                ),
                flush=True,
            )
    img = ROOT / "docs" / "img"
    img.mkdir(parents=True, exist_ok=True)
    keys = (
        ["aspect_ratio", "fluidised", "rung", "ny"]
        + list(OBSERVABLES)
        + [f"rel_{k}" for k in OBSERVABLES]
        + ["wall_s", "stop_reason", "t_end_s"]
    )
    with open(img / "model_ladder.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow(
                {
                    k: (f"{r[k]:.6g}" if isinstance(r.get(k), float) else ("" if r.get(k) is None else r[k]))
                    for k in keys
                }
            )
    plot(rows, img / "model_ladder.png", args.ny)
    print(f"total wall time {time.perf_counter() - t_start:.0f} s")


def read_table(path: Path) -> list:
    """The rows of a model_ladder.csv written by :func:`main`, with their numbers and flags parsed
    (blank cells are None)."""
    rows = []
    with open(path, newline="") as f:
        for raw in csv.DictReader(f):
            row: dict = {}
            for k, v in raw.items():
                if k == "fluidised":
                    row[k] = v == "True"
                elif k in ("rung", "stop_reason"):
                    row[k] = v
                else:
                    row[k] = float(v) if v != "" else None
            rows.append(row)
    return rows


def plot(rows: list, path: Path, ny: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    fig, axes = plt.subplots(2, 4, figsize=(16, 7.5))
    styles = {
        "depth-averaged": "C0s",
        "granular": "C1^",
        "window": "C2D",
        "two-phase": "C3o",
        f"two-phase-{REFERENCE_NY}": "C4*",
    }
    for ax, key in zip(axes.flat, OBSERVABLES):
        for name, style in styles.items():
            for fluidised, ls in ((True, "-"), (False, "--")):
                rs = [r for r in rows if r["rung"] == name and r["fluidised"] == fluidised]
                ax.plot(
                    [r["aspect_ratio"] for r in rs],
                    [100 * r[f"rel_{key}"] if r[f"rel_{key}"] is not None else float("nan") for r in rs],
                    style + ls,
                    mfc="none" if not fluidised else None,
                    ms=5,
                    lw=1.2,
                    label=f"{name}, {'fluidised' if fluidised else 'dry'}",
                )
        ax.axhspan(-5, 5, color="0.88")
        ax.axhline(0, color="k", lw=0.8)
        ax.set(title=OBSERVABLES[key], ylabel=f"(rung − two-phase ny = {REFERENCE_NY}) / it (%)")
    ax = axes.flat[-1]
    for name, style in list(styles.items()) + [("reference", "k*")]:
        for fluidised, ls in ((True, "-"), (False, "--")):
            rs = [r for r in rows if r["rung"] == name and r["fluidised"] == fluidised]
            ax.plot(
                [r["aspect_ratio"] for r in rs],
                [r["wall_s"] if r["wall_s"] is not None else float("nan") for r in rs],
                style + ls,
                mfc="none" if not fluidised else None,
                ms=5,
                lw=1.2,
                label=f"{name if name != 'reference' else f'two-phase ny = {REFERENCE_NY}'}, "
                f"{'fluidised' if fluidised else 'dry'}",
            )
    ax.set(title="wall time (one thread, shared machine)", ylabel="s")
    if any(r["wall_s"] for r in rows):
        ax.set_yscale("log")
    for ax in axes.flat:
        ax.set_xscale("log")
        ax.set_xlim(0.4, 5.0)
        ax.set_xticks(ASPECT_RATIOS, [f"{v:g}" for v in ASPECT_RATIOS])
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("aspect ratio a = H_c / L_c")
        ax.grid(alpha=0.3)
    # one legend for every panel, below them, so that no panel's points are hidden under it
    handles, labels = axes.flat[-1].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=6, fontsize=8, frameon=False)
    fig.suptitle(
        f"Model ladder at ny = {ny} against the two-phase model at ny = {REFERENCE_NY} (grey: ±5 %)", fontsize=11
    )
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
