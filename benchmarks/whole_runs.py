"""Whole-run benchmarks from Python: cost per step and cell-steps per second for the cavity and the
column collapse, with 1 and 2 threads (median of repeats). Refuses a debug build.

    .venv/bin/python benchmarks/whole_runs.py [--quick] [--out benchmarks/results.json]
    .venv/bin/python benchmarks/whole_runs.py --column [--threads 1 2] [--model granular] [--repeats R] [--out benchmarks/column_scaling.json]
    .venv/bin/python benchmarks/whole_runs.py --window [--repeats R] [--band B --sides S --out F]   # cost against the channel length (benchmarks/window_scaling.json)

``--column``: the two-phase column step of the main job (D-P bi-projection, Coulomb walls, pore
pressure, WENO5 level set and redistancing: everything a step does) from ny = 23 (4.5 k cells,
about 64²) to ny = 362 (1.0 M cells, about 1024²); cost per step over steps 11–30 of the collapse
(after the BDF1 start and the growth of δt from a tenth of the stable step), the log-log slope of
cost per step against cells, and cost per Picard iteration.

``--window``: the column at ny = 64 on channels of 3.6, 7.2 and 14.4 m (the granular mass the
same, the domain 1×, 2×, 4×), two-phase and granular-only, whole domain and active region
(BAND = 8), one thread: the active region's cost per step should not grow with the domain.

The figures quoted in docs/benchmarks.md come from this script (and `cargo bench`).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import granrs
import granrs.model


def cavity_cost(n: int, threads: int, steps: int, repeats: int) -> dict:
    times = []
    for _ in range(repeats):
        m = granrs.Model(
            granrs.Grid(n, n, 1.0, 1.0),
            granrs.Material(1.0, 1e-3),
            bc=granrs.BoundaryConditions(top=granrs.Velocity(tangential=1.0)),
            threads=threads,
        )
        m.advance(max_steps=20)  # warm up: past the BDF1 start and the small first steps
        t0 = time.perf_counter()
        log = m.advance(max_steps=steps)
        times.append((time.perf_counter() - t0) / steps)
    med = statistics.median(times)
    return {
        "case": "cavity-re1000",
        "n": n,
        "cells": n * n,
        "threads": threads,
        "s_per_step": med,
        "cell_steps_per_s": n * n / med,
        "pressure_iterations_median": statistics.median(log["pressure_iterations"]),
        "viscous_iterations_median": statistics.median(log["viscous_iterations"]),
    }


def column_cost(ny: int, threads: int, steps: int, repeats: int, model: str = "two-phase") -> dict:
    from granrs.cases.column import ColumnCase, build_model

    times, its = [], []
    for _ in range(repeats):
        m = build_model(ColumnCase(ny=ny, threads=threads, model=model))
        try:
            m.advance(max_steps=10)
        except granrs.SimulationError as e:  # recorded, not hidden: a grid the default numerics cannot start
            return {
                "case": "column-fluidised",
                "model": model,
                "ny": ny,
                "nx": m.grid.nx,
                "cells": m.grid.nx * ny,
                "threads": threads,
                "failed": str(e),
            }
        t0 = time.perf_counter()
        log = m.advance(max_steps=steps)
        times.append((time.perf_counter() - t0) / steps)
        its.append(statistics.mean(log["picard_iterations"]))
    med = statistics.median(times)
    cells = m.grid.nx * m.grid.ny
    return {
        "case": "column-fluidised",
        "model": model,
        "ny": ny,
        "nx": m.grid.nx,
        "cells": cells,
        "threads": threads,
        "s_per_step": med,
        "cell_steps_per_s": cells / med,
        "picard_iterations_mean": statistics.mean(its),
        "s_per_picard_iteration": med / max(statistics.mean(its), 1.0),
        "pressure_iterations_median": statistics.median(log["pressure_iterations"]),
        "viscous_iterations_median": statistics.median(log["viscous_iterations"]),
    }


def window_cost(
    ny: int, length: float, model: str, band: int | None, steps: int, repeats: int, sides: str = "walls"
) -> dict:
    """Cost per step of the column's steps 11–30 on a channel of `length` m: with the active
    region the cost should follow the granular area (fixed here), not the domain."""
    from granrs import ActiveRegion
    from granrs.cases.column import ColumnCase, ColumnGeometry, build_model

    times = []
    for _ in range(repeats):
        region = None if band is None else ActiveRegion(band, sides=sides)
        m = build_model(ColumnCase(ny=ny, geometry=ColumnGeometry(length=length), model=model, active_region=region))
        m.advance(max_steps=10)
        t0 = time.perf_counter()
        m.advance(max_steps=steps)
        times.append((time.perf_counter() - t0) / steps)
    return {
        "case": "column-window",
        "model": model,
        "ny": ny,
        "length_m": length,
        "nx": m.grid.nx,
        "cells": m.grid.nx * m.grid.ny,
        "active_region": band,
        "active_region_sides": sides if band else None,
        "s_per_step": statistics.median(times),
    }


def slope(rows: list, key: str) -> float:
    import math

    x = [math.log(r["cells"]) for r in rows]
    y = [math.log(r[key]) for r in rows]
    mx, my = sum(x) / len(x), sum(y) / len(y)
    return sum((a - mx) * (b - my) for a, b in zip(x, y)) / sum((a - mx) ** 2 for a in x)


def main() -> None:
    info = granrs.build_info()
    if info["profile"] != "release":
        raise SystemExit("benchmarks need a release build (make install builds one)")
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None)
    ap.add_argument("--column", action="store_true")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--ny", type=int, nargs="+", default=[23, 32, 45, 64, 90, 128, 181, 256, 362])
    ap.add_argument(
        "--model",
        default="two-phase",
        choices=["two-phase", "granular"],
        help="--column: the 2D model whose step is timed (granular: the granular-only model)",
    )
    ap.add_argument(
        "--repeats", type=int, default=None, help="--column: repeats per point (default 3 up to ny = 128, else 1)"
    )
    ap.add_argument(
        "--window", action="store_true", help="cost per step against the channel length, whole domain and active region"
    )
    ap.add_argument("--band", type=int, default=8, help="--window: the active region's band in cells (default 8)")
    ap.add_argument(
        "--sides",
        default="walls",
        choices=granrs.model.ACTIVE_REGION_SIDES,
        help="--window: the window's sides (open ones: the two-phase model only)",
    )
    args = ap.parse_args()
    if args.window:
        rows = []
        for model in ("two-phase", "granular") if args.sides == "walls" else ("two-phase",):
            for band in (None, args.band):
                for length in (3.6, 7.2, 14.4):
                    rows.append(
                        window_cost(64, length, model, band, steps=20, repeats=args.repeats or 3, sides=args.sides)
                    )
                    print(json.dumps(rows[-1]), flush=True)
        out = {
            "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform()},
            "version": info["version"],
            "rows": rows,
        }
        Path(args.out or "benchmarks/window_scaling.json").write_text(json.dumps(out, indent=2) + "\n")
        return
    if args.column:
        rows = []
        for threads in args.threads:
            for ny in args.ny:
                reps = args.repeats or (3 if ny <= 128 else 1)
                rows.append(column_cost(ny, threads, steps=20, repeats=reps, model=args.model))
                print(json.dumps(rows[-1]), flush=True)
        fits = {}
        for threads in args.threads:
            sel = [r for r in rows if r["threads"] == threads and "failed" not in r]
            if len(sel) > 1:
                fits[f"slope_s_per_step_{threads}t"] = slope(sel, "s_per_step")
                fits[f"slope_s_per_picard_iteration_{threads}t"] = slope(sel, "s_per_picard_iteration")
        print(json.dumps(fits))
        out = {
            "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform()},
            "version": info["version"],
            "rows": rows,
            "fits": fits,
        }
        Path(args.out or "benchmarks/column_scaling.json").write_text(json.dumps(out, indent=2) + "\n")
        return
    args.out = args.out or "benchmarks/results.json"
    sizes = [64, 128] if args.quick else [64, 128, 256, 512]
    rows = []
    for n in sizes:
        for threads in (1, 2):
            steps = max(10, int(2e6 / (n * n)))
            rows.append(cavity_cost(n, threads, steps, repeats=3))
            print(json.dumps(rows[-1]))
    out = {
        "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform()},
        "version": info["version"],
        "rows": rows,
    }
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
