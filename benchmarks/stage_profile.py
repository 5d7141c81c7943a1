"""The share of each stage in the time of the column's step, from the wall time of each stage
that every step reports (``Model.step()['stage_seconds']``, models/step.rs).

    .venv/bin/python benchmarks/stage_profile.py --ny 64 [--dry] [--model two-phase|granular]
        [--threads 1] [--warmup 10] [--steps 30] [--active-region B --sides S] [--restart CHECKPOINT]
        [--speeds] [--option KEY=VALUE ...] [--out FILE.json]

The column of ``granrs.cases.column`` is built, advanced ``--warmup`` steps, then stepped
``--steps`` times one step at a time; the table gives each stage's mean seconds per step and
its share of the step as the binding measures it (``binding`` is the rest: the state copy
before the step, the binding's conversions). The Python-side observation of a run
(``granrs run column``: the front, the area, the energy budget, the granular speed and the
profiles every 0.01 s of simulated time) is not part of a step; ``--observe`` times its field reads (Φ, the area, the
energy budget, the centre velocity) once per step here, an upper bound of its share (a run observes every 0.01 s, that is every 20–50 steps).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from column_bench import warm_column_model

STAGES = (
    "choose_dt",
    "interface",
    "properties",
    "pore_pressure",
    "rheology",
    "predictor_setup",
    "predictor_solves",
    "projections",
    "pressure_projection",
    "diagnostics",
)


def profile(m, steps: int, observe: bool = False) -> tuple[float, dict, dict]:
    """Step ``m`` ``steps`` times, one step at a time: the mean wall seconds per step (as the
    binding measures it), each stage's mean seconds per step (``binding`` the rest) and the
    medians of the iteration counts."""
    import numpy as np

    sums = dict.fromkeys(STAGES, 0.0)
    walls, obs = [], []
    iters: dict = {"picard_iterations": [], "pressure_iterations": [], "viscous_iterations": []}
    for _ in range(steps):
        t0 = time.perf_counter()
        d = m.step()
        walls.append(time.perf_counter() - t0)
        for k in STAGES:
            sums[k] += d["stage_seconds"][k]
        for k, (group, key) in {
            "picard_iterations": ("picard", "iterations"),
            "pressure_iterations": ("pressure", "iterations"),
            "viscous_iterations": ("viscous", "iterations"),
        }.items():
            iters[k].append(d[group][key])
        if observe:
            t0 = time.perf_counter()
            (m.phi > 0).any(axis=0).nonzero()  # the front's column
            m.dense_area()
            m.energy_budget()
            uc, vc = m.centre_velocity()
            inside = m.phi > 0
            float(np.max(np.hypot(uc, vc)[inside])) if inside.any() else 0.0
            obs.append(time.perf_counter() - t0)
    step = sum(walls) / steps
    rows = {k: sums[k] / steps for k in STAGES}
    rows["binding"] = step - sum(rows.values())
    if obs:
        rows["observation (per step, upper bound)"] = sum(obs) / steps
    return step, rows, {k: statistics.median(v) for k, v in iters.items() if v}


def largest_speeds(m) -> str:
    """Where the flow is fastest: what sets the adaptive step (time_stepping/clock.rs)."""
    import numpy as np

    uc, vc = m.centre_velocity()
    speed = np.hypot(uc, vc)
    j, i = np.unravel_index(int(np.argmax(speed)), speed.shape)
    grains = m.phi > 0
    in_grains = float(speed[grains].max()) if grains.any() else 0.0
    return (
        f"t = {m.time:.4f} s: largest speed {speed[j, i]:.3f} m/s at cell ({i}, {j}), Φ/h = {m.phi[j, i] / m.grid.dy:.1f}; "
        f"largest in the grains {in_grains:.3f} m/s"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ny", type=int, default=64)
    ap.add_argument("--dry", action="store_true")
    ap.add_argument("--model", default="two-phase", choices=["two-phase", "granular"])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--warmup", type=int, default=10)
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--active-region", type=int, default=None)
    ap.add_argument("--sides", default="open-right-top")
    ap.add_argument("--restart", default=None, help="start from this checkpoint.npz of the same case")
    ap.add_argument("--at-time", type=float, default=None, help="start at this time of the run (s)")
    ap.add_argument("--cache", default=None, help="folder keeping the state at --at-time between calls")
    ap.add_argument("--observe", action="store_true", help="also time the run's observation once per step")
    ap.add_argument(
        "--speeds",
        action="store_true",
        help="first print the largest cell-centre speed, its cell and Φ/h there, and the largest in the grains (Φ > 0)",
    )
    ap.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a model option changed from the column's default by its schema key (`granrs keys`; repeat)",
    )
    ap.add_argument("--out", default=None)
    args = ap.parse_args()

    m = warm_column_model(args)
    if args.speeds:
        print(largest_speeds(m))
    n = args.steps
    step, rows, medians = profile(m, n, args.observe)
    cells = m.grid.nx * m.grid.ny
    window = m.active_window
    print(
        f"column ny = {args.ny} ({m.grid.nx} x {m.grid.ny} = {cells} cells), {args.model}, "
        f"{'dry' if args.dry else 'fluidised'}, {args.threads} thread(s), steps {args.warmup + 1}-{args.warmup + n}, "
        f"t = {m.time:.4f} s; medians per step: " + ", ".join(f"{k} {v:g}" for k, v in medians.items())
    )
    print("| stage | ms per step | share |")
    print("|---|---|---|")
    for k, v in rows.items():
        print(f"| {k} | {v * 1e3:.2f} | {100 * v / step:.1f} % |")
    print(f"| step (binding's wall) | {step * 1e3:.2f} | 100 % |")
    if args.out:
        Path(args.out).write_text(
            json.dumps(
                {
                    "args": vars(args),
                    "cells": cells,
                    "window": list(window) if window else None,
                    "time_s": m.time,
                    "s_per_step": step,
                    "stages_s": rows,
                    "iterations_median": medians,
                },
                indent=2,
            )
            + "\n"
        )


if __name__ == "__main__":
    main()
