"""Two cores, two ways: one run on two threads against two runs side by side on one thread each.

    .venv/bin/python benchmarks/throughput.py [--ny 32 64 128] [--rounds 3] [--out FILE.json]

The case is the column of the paper's reference configuration at the grid ``--ny``: two-phase,
fluidised, to t = 3 s, on the active window open to the right and the top with a band of
max(2, ny/16) cells (``granrs run column --ny N --active-region N/16 --active-region-sides
open-right-top``; ny = 256 is the paper's reference case). Each round runs three layouts, in a
different order each round (rotated) so that a drift of the machine's load falls on all of them:

* ``1 run x 1 thread``: one run, ``--threads 1``;
* ``1 run x 2 threads``: one run, ``--threads 2``;
* ``2 runs x 1 thread``: two runs started together, ``--threads 1`` each; its wall time is
  the time until both have finished.

Each run is a process of its own (``reference_runs.run_column``); the wall times are those of the
processes (start-up and the run's plots included, as a user waits for them). The table gives
the medians over the rounds and two ratios against one run on one thread: the speed-up of one run
on two threads (what one run gains from the second core) and the throughput of two runs side by
side (runs per hour over those of one run on one thread: what a sweep or an ensemble gains from
it). Every run of a grid must give the same step count and run-out: the answer does not depend on
the thread count (a difference fails the script).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reference_runs import run_column  # noqa: E402
from thread_curve import cpu_model  # noqa: E402

#: layout → (threads per run, runs)
LAYOUTS = {"1 run x 1 thread": (1, 1), "1 run x 2 threads": (2, 1), "2 runs x 1 thread": (1, 2)}


def options(ny: int, threads: int) -> list[str]:
    band = max(2, ny // 16)
    return [
        "--ny",
        str(ny),
        "--threads",
        str(threads),
        "--active-region",
        str(band),
        "--active-region-sides",
        "open-right-top",
    ]


def run_layout(layout: str, ny: int, tmp: Path) -> dict:
    """The layout's wall time (until its last run has finished) and its runs' summaries."""
    threads, count = LAYOUTS[layout]
    outs = [tmp / f"ny{ny}-{layout.replace(' ', '')}-{k}-{time.monotonic_ns()}" for k in range(count)]
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=count) as pool:
        runs = list(pool.map(lambda out: run_column(None, options(ny, threads), out), outs))
    wall = time.perf_counter() - t0
    return {"layout": layout, "wall_s": wall, "runs": runs}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ny", type=int, nargs="+", default=[32, 64, 128])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if args.rounds < 1 or any(n < 16 for n in args.ny):
        ap.error("--rounds must be at least 1 and every --ny at least 16")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for ny in args.ny:
            walls = {lay: [] for lay in LAYOUTS}
            answers = set()
            for k in range(args.rounds):
                names = list(LAYOUTS)
                order = names[k % 3 :] + names[: k % 3]
                for lay in order:
                    r = run_layout(lay, ny, Path(tmp))
                    for run in r["runs"]:
                        if "error" in run:
                            sys.exit(f"ny = {ny}, {lay}: the run failed: {run['error']}")
                        answers.add((run["steps"], run["runout_m"]))
                    walls[lay].append(r["wall_s"])
                    print(json.dumps({"ny": ny, "round": k, **r}), flush=True)
            if len(answers) != 1:
                sys.exit(f"ny = {ny}: the layouts gave different answers (steps, run-out): {sorted(answers)}")
            med = {lay: statistics.median(w) for lay, w in walls.items()}
            one = med["1 run x 1 thread"]
            rows.append(
                {
                    "ny": ny,
                    "steps": next(iter(answers))[0],
                    "walls_s": walls,
                    "median_wall_s": med,
                    "speedup_one_run_two_threads": one / med["1 run x 2 threads"],
                    "throughput_two_runs_side_by_side": 2 * one / med["2 runs x 1 thread"],
                }
            )
    print(
        "\n| ny | steps | 1 run x 1 thread | 1 run x 2 threads | 2 runs x 1 thread | speed-up of one run | throughput of two runs |"
    )
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        m = r["median_wall_s"]
        print(
            f"| {r['ny']} | {r['steps']} | " + " | ".join(f"{m[lay]:.1f} s" for lay in LAYOUTS) + " | "
            f"{r['speedup_one_run_two_threads']:.2f} | {r['throughput_two_runs_side_by_side']:.2f} |"
        )
    if args.out:
        meta = {
            "cpu": cpu_model(),
            "cores": os.cpu_count(),
            "python": platform.python_version(),
            "date": time.strftime("%Y-%m-%d"),
        }
        Path(args.out).write_text(json.dumps({"args": vars(args), "machine": meta, "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
