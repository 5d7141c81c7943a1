"""The model ladder: where does the cheap depth-averaged model reproduce the two-phase run-out?

    python examples/model_ladder.py            # all runs, ~6 min on one core (the two-phase runs)
    python examples/model_ladder.py --reuse    # re-read finished runs from out/ladder, seconds

For the column of the paper (L_c = 0.20 m, glass beads, α_b = 15°, κ_f = 0.035 m² s⁻¹,
β_s = 0.9) at aspect ratios a = H_c/L_c = 0.5, 1, 2, 4, fluidised and not, this script runs

1. the two-phase model at ny = 32, i.e. ``granrs run column --ny 32 --aspect-ratio A
   [--no-fluidised]`` (15–60 s each);
2. the depth-averaged model on the same channel (``--model depth-averaged``, Δx = min(L_c, H_c)/64,
   about a second), with the column case's earth-pressure coefficient (Savage & Hutter's active k
   from α = 27° and α_b = 15°, reduced by the pore pressure), again at Δx/2 to show its run-out is
   converged in Δx, and with the hydrostatic k = 1 for comparison;

and tabulates the run-outs (front from the gate at the end of the run: rest or t = 3 s) and the
relative difference (depth-averaged − two-phase)/two-phase. Both fronts are read at the same layer
thickness, half a two-phase cell (the level-set front cannot see thinner layers; see
``granrs.cases.column.depth_averaged_front_depth``). Outputs: ``docs/img/model_ladder.csv``,
``docs/img/model_ladder.png``, run folders in ``out/ladder/``; the script prints, per
fluidisation state, the aspect ratios up to which the two models agree within RUNOUT_TOLERANCE
(docs/models.md, "No automatic choice of model").

A two-phase run that reaches the far end of its default channel (L_c + 8.25 H_c) is rerun on a
channel twice as long; the depth-averaged run then uses the same channel.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from dataclasses import replace
from pathlib import Path

from granrs import SimulationError
from granrs.cases.column import ColumnCase, run_column

#: relative run-out difference counted as agreement (docs/models.md)
RUNOUT_TOLERANCE = 0.05

ASPECT_RATIOS = (0.5, 1.0, 2.0, 4.0)
ROOT = Path(__file__).resolve().parents[1]


def run(case: ColumnCase, out: Path, reuse: bool = False) -> dict:
    """Runs the case into ``out`` (or re-reads it); on 'reached the far end' doubles the channel."""
    summary_path = out / "summary.json"
    if reuse and summary_path.exists():
        s = json.loads(summary_path.read_text())
        if not s["stop_reason"].startswith("error"):
            return s
    while True:
        try:
            return run_column(case, out, progress=False)
        except SimulationError as err:
            if "far end" not in str(err):
                raise
            case = replace(case, length=2.0 * case.domain()[0])
            print(f"  {out.name}: reached the far end, rerun with length {case.length:.2f} m", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reuse", action="store_true", help="re-read finished two-phase runs from out/ladder")
    ap.add_argument("--ny", type=int, default=32)
    args = ap.parse_args()
    out = ROOT / "out" / "ladder"
    rows = []
    t_start = time.perf_counter()
    for fluidised in (True, False):
        for a in ASPECT_RATIOS:
            tag = f"a{a:g}-{'fluidised' if fluidised else 'dry'}"
            base = ColumnCase(aspect_ratio=a, fluidised=fluidised, ny=args.ny)
            tp = run(replace(base, model="two-phase"), out / f"two-phase-{tag}", args.reuse)
            length = tp["case"]["length"]  # None unless the channel had to be lengthened
            da = run(replace(base, model="depth-averaged", length=length), out / f"depth-averaged-{tag}")
            fine = run(
                replace(base, model="depth-averaged", length=length, da_resolution=128),
                out / f"depth-averaged-fine-{tag}",
            )
            k1 = run(
                replace(base, model="depth-averaged", length=length, earth_pressure=1.0),
                out / f"depth-averaged-k1-{tag}",
            )
            rel = (da["runout_m"] - tp["runout_m"]) / tp["runout_m"]
            row = {
                "aspect_ratio": a,
                "fluidised": fluidised,
                "runout_two_phase_m": tp["runout_m"],
                "runout_depth_averaged_m": da["runout_m"],
                "rel_diff": rel,
                "within_tolerance": abs(rel) <= RUNOUT_TOLERANCE,
                "runout_depth_averaged_fine_m": fine["runout_m"],
                "runout_depth_averaged_thin_m": da["runout_thin_m"],
                "runout_depth_averaged_k1_m": k1["runout_m"],
                "rel_diff_k1": (k1["runout_m"] - tp["runout_m"]) / tp["runout_m"],
                "front_depth_m": da["front_depth_m"],
                "t_end_two_phase_s": tp["t_end_s"],
                "t_end_depth_averaged_s": da["t_end_s"],
                "stop_two_phase": tp["stop_reason"],
                "stop_depth_averaged": da["stop_reason"],
                "wall_two_phase_s": tp["wall_s"],
                "wall_depth_averaged_s": da["wall_s"],
                "cells_two_phase": tp["cells"],
                "cells_depth_averaged": da["cells"],
                "channel_m": tp["nx"] * tp["h_m"],
            }
            rows.append(row)
            print(
                json.dumps(
                    {
                        k: (round(v, 4) if isinstance(v, float) else v)
                        for k, v in row.items()
                        if k
                        in (
                            "aspect_ratio",
                            "fluidised",
                            "runout_two_phase_m",
                            "runout_depth_averaged_m",
                            "rel_diff",
                            "runout_depth_averaged_fine_m",
                            "rel_diff_k1",
                            "wall_two_phase_s",
                            "wall_depth_averaged_s",
                        )
                    }
                ),
                flush=True,
            )
    img = ROOT / "docs" / "img"
    img.mkdir(parents=True, exist_ok=True)
    with open(img / "model_ladder.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    plot(rows, img / "model_ladder.png")
    for fluidised in (True, False):
        ok = [r["within_tolerance"] for r in rows if r["fluidised"] == fluidised]
        n_ok = next((i for i, v in enumerate(ok) if not v), len(ok))
        a_max = ASPECT_RATIOS[n_ok - 1] if n_ok else None
        print(
            f"agreement within {RUNOUT_TOLERANCE:.0%}, {'fluidised' if fluidised else 'non-fluidised'}: from the smallest a up to a = {a_max}"
        )
    print(f"total wall time {time.perf_counter() - t_start:.0f} s")


def plot(rows: list, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for k, fluidised in enumerate((True, False)):
        rs = [r for r in rows if r["fluidised"] == fluidised]
        a = [r["aspect_ratio"] for r in rs]
        name = "fluidised" if fluidised else "non-fluidised"
        ax1.plot(a, [r["runout_two_phase_m"] for r in rs], f"C{k}o-", label=f"two-phase, ny = 32, {name}")
        ax1.plot(
            a,
            [r["runout_depth_averaged_m"] for r in rs],
            f"C{k}s--",
            mfc="none",
            label=f"depth-averaged (Savage–Hutter k), {name}",
        )
        ax1.plot(
            a,
            [r["runout_depth_averaged_k1_m"] for r in rs],
            f"C{k}^:",
            mfc="none",
            alpha=0.6,
            label=f"depth-averaged, k = 1, {name}",
        )
        ax2.plot(a, [100 * r["rel_diff"] for r in rs], f"C{k}s--", mfc="none", label=f"Savage–Hutter k, {name}")
        ax2.plot(a, [100 * r["rel_diff_k1"] for r in rs], f"C{k}^:", mfc="none", alpha=0.6, label=f"k = 1, {name}")
    ax1.set(
        xscale="log",
        xlabel="aspect ratio a = H_c / L_c",
        ylabel="run-out from the gate (m)",
        title="Column collapse: run-out of the two models",
    )
    ax2.axhspan(-100 * RUNOUT_TOLERANCE, 100 * RUNOUT_TOLERANCE, color="0.85", label="±5 %")
    ax2.axhline(0, color="k", lw=0.8)
    ax2.set(
        xscale="log",
        xlabel="aspect ratio a = H_c / L_c",
        ylabel="(depth-averaged − two-phase) / two-phase (%)",
        title="Relative difference of the run-out",
    )
    from matplotlib.ticker import NullFormatter

    for ax in (ax1, ax2):
        ax.set_xticks(ASPECT_RATIOS, [f"{v:g}" for v in ASPECT_RATIOS])
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
