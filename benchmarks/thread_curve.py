"""Cost of the column's step against the number of threads, stage by stage: the curve of the
paper's reference case and of the granular-only rung at ny = 256.

    .venv/bin/python benchmarks/thread_curve.py [--threads 1 2 4 8 12 16] [--ny 256] [--warmup 10]
        [--steps 20] [--repeats 2] [--configs reference granular whole-domain] [--out benchmarks/thread_curve.json]

The configurations are those of the step benchmarks (step_cost.py, stage_profile.py):

- ``reference``: the two-phase fluidised column with the active region of 16 cells open to the
  right and the top (the paper's reference case as the docs time it);
- ``granular``: the granular-only model, fluidised, active region of 16 cells with walls (the
  granular-only rung);
- ``whole-domain``: the two-phase fluidised column on the whole domain (no active region): the
  same physics on arrays 4–5 times larger in these early steps.

Each point runs in its own process: the column is built, advanced ``--warmup`` steps, then
stepped ``--steps`` times one step at a time (stage_profile.profile: each stage's wall time as
the step reports it). The thread counts run in a different order in each repeat (ascending,
then descending, ...) so that a drift of the machine's load falls on all of them; the table
gives the medians over the repeats, the speed-up against one thread and the parallel
efficiency (speed-up / threads), per stage too. Every point must reach the same state: a
digest of u, v, p, Φ (and p_f) after the timed steps is compared across thread counts, and a
mismatch fails the script (the results of granrs do not depend on the thread count).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

CONFIGS = {
    "reference": {"model": "two-phase", "active_region": 16, "sides": "open-right-top"},
    "granular": {"model": "granular", "active_region": 16, "sides": "walls"},
    "whole-domain": {"model": "two-phase", "active_region": None, "sides": "walls"},
}


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def worker(spec: dict) -> None:
    from column_bench import state_digest, warm_column_model
    from stage_profile import profile

    args = argparse.Namespace(
        ny=spec["ny"],
        threads=spec["threads"],
        model=spec["model"],
        dry=False,
        active_region=spec["active_region"],
        sides=spec["sides"],
        warmup=spec["warmup"],
    )
    t0 = time.perf_counter()
    m = warm_column_model(args)
    setup = time.perf_counter() - t0
    step, rows, medians = profile(m, spec["steps"])
    print(
        json.dumps(
            {
                "s_per_step": step,
                "stages_s": rows,
                "iterations_median": medians,
                "time": m.time,
                "setup_and_warmup_s": setup,
                "digest": state_digest(m),
            }
        ),
        flush=True,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2, 4, 8, 12, 16])
    ap.add_argument("--ny", type=int, default=256)
    ap.add_argument("--warmup", type=int, default=10)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    ap.add_argument("--out", default=None)
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(json.loads(args.worker))
        return
    for name, v in (("--ny", args.ny), ("--steps", args.steps), ("--repeats", args.repeats)):
        if v < 1:
            raise SystemExit(f"{name} = {v}: allowed an integer >= 1")
    if args.warmup < 0 or min(args.threads) < 1:
        raise SystemExit("--warmup must be >= 0 and every --threads >= 1")

    here = Path(__file__).resolve().parent
    results: dict = {c: {t: [] for t in args.threads} for c in args.configs}
    for rep in range(args.repeats):
        order = args.threads if rep % 2 == 0 else list(reversed(args.threads))
        for c in args.configs:
            for t in order:
                spec = dict(CONFIGS[c], ny=args.ny, threads=t, warmup=args.warmup, steps=args.steps)
                p = subprocess.run(
                    [sys.executable, str(Path(__file__).resolve()), "--worker", json.dumps(spec)],
                    capture_output=True,
                    text=True,
                    cwd=here,
                )
                if p.returncode != 0:
                    raise SystemExit(f"{c}, {t} thread(s), repeat {rep + 1} failed:\n{p.stderr}")
                r = json.loads(p.stdout.strip().splitlines()[-1])
                results[c][t].append(r)
                print(
                    f"{c:9s} threads {t:2d} repeat {rep + 1}: {r['s_per_step'] * 1e3:8.2f} ms/step  digest {r['digest']}",
                    flush=True,
                )

    rows, failed = [], []
    for c in args.configs:
        digests = {r["digest"] for t in args.threads for r in results[c][t]}
        if len(digests) != 1:
            failed.append(f"{c}: the state after the timed steps differs between thread counts ({sorted(digests)})")
        base = statistics.median(r["s_per_step"] for r in results[c][args.threads[0]])
        base_stages = {
            k: statistics.median(r["stages_s"][k] for r in results[c][args.threads[0]])
            for k in results[c][args.threads[0]][0]["stages_s"]
        }
        for t in args.threads:
            med = statistics.median(r["s_per_step"] for r in results[c][t])
            stages = {k: statistics.median(r["stages_s"][k] for r in results[c][t]) for k in base_stages}
            rows.append(
                {
                    "config": c,
                    **CONFIGS[c],
                    "ny": args.ny,
                    "threads": t,
                    "s_per_step": med,
                    "s_per_step_repeats": [r["s_per_step"] for r in results[c][t]],
                    "speedup": base / med * args.threads[0],
                    "efficiency": base / med * args.threads[0] / t,
                    "stages_s": stages,
                    "stage_speedup": {
                        k: (base_stages[k] / v * args.threads[0] if v > 0 else None) for k, v in stages.items()
                    },
                    "iterations_median": results[c][t][0]["iterations_median"],
                    "time": results[c][t][0]["time"],
                    "digest": results[c][t][0]["digest"],
                }
            )

    print(
        f"\n{cpu_model()}, {os.cpu_count()} logical CPUs; ny = {args.ny}, steps {args.warmup + 1}-{args.warmup + args.steps}, "
        f"medians of {args.repeats}"
    )
    print("| configuration | threads | ms per step | speed-up | efficiency |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['config']} | {r['threads']} | {r['s_per_step'] * 1e3:.2f} | {r['speedup']:.2f} | {r['efficiency']:.2f} |"
        )
    stages = list(rows[0]["stages_s"])
    for c in args.configs:
        print(f"\n{c}: ms per step by stage (speed-up against {args.threads[0]} thread(s))")
        print("| stage | " + " | ".join(f"{t} thr" for t in args.threads) + " |")
        print("|---|" + "---|" * len(args.threads))
        for k in stages:
            cells = []
            for r in rows:
                if r["config"] == c:
                    s = r["stage_speedup"][k]
                    cells.append(f"{r['stages_s'][k] * 1e3:.2f}" + (f" ({s:.1f})" if s is not None else ""))
            print(f"| {k} | " + " | ".join(cells) + " |")
    if args.out:
        Path(args.out).write_text(
            json.dumps(
                {
                    "machine": {"cpu": cpu_model(), "cpu_count": os.cpu_count(), "platform": platform.platform()},
                    "args": {k: v for k, v in vars(args).items() if k != "worker"},
                    "rows": rows,
                },
                indent=2,
            )
            + "\n"
        )
    if failed:
        raise SystemExit("\n".join(failed))


if __name__ == "__main__":
    main()
