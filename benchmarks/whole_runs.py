"""Whole-run benchmarks from Python: cost per step and cell-steps per second for the cavity and the
column collapse, with 1 and 2 threads (median of repeats). Refuses a debug build.

    .venv/bin/python benchmarks/whole_runs.py [--quick] [--out benchmarks/results.json]

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


def cavity_cost(n: int, threads: int, steps: int, repeats: int) -> dict:
    times = []
    for _ in range(repeats):
        m = granrs.Model(granrs.Grid(n, n, 1.0, 1.0), granrs.Material(1.0, 1e-3),
                         bc=granrs.BoundaryConditions(top=granrs.Velocity(tangential=1.0)), threads=threads)
        m.advance(max_steps=20)  # warm up: past the BDF1 start and the small first steps
        t0 = time.perf_counter()
        log = m.advance(max_steps=steps)
        times.append((time.perf_counter() - t0) / steps)
    med = statistics.median(times)
    return {"case": "cavity-re1000", "n": n, "cells": n * n, "threads": threads, "s_per_step": med,
            "cell_steps_per_s": n * n / med, "pressure_iterations_median": statistics.median(log["pressure_iterations"]),
            "viscous_iterations_median": statistics.median(log["viscous_iterations"])}


def main() -> None:
    info = granrs.build_info()
    if info["profile"] != "release":
        raise SystemExit("benchmarks need a release build (make install builds one)")
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default="benchmarks/results.json")
    args = ap.parse_args()
    sizes = [64, 128] if args.quick else [64, 128, 256, 512]
    rows = []
    for n in sizes:
        for threads in (1, 2):
            steps = max(10, int(2e6 / (n * n)))
            rows.append(cavity_cost(n, threads, steps, repeats=3))
            print(json.dumps(rows[-1]))
    out = {"machine": {"cpu_count": os.cpu_count(), "platform": platform.platform()}, "version": info["version"], "rows": rows}
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
