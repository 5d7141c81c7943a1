"""Cost of the column's step for two builds of granrs, measured in alternation: the ratio of their
costs per step on the same steps of the same run, and from it an estimate of a whole run.

    .venv/bin/python benchmarks/step_cost.py --base DIR [--ny 64 128 256] [--model two-phase granular]
        [--threads 1 2] [--warmup 10] [--steps 20] [--rounds 3] [--active-region 16 --sides open-right-top]
        [--restart CHECKPOINT] [--out benchmarks/step_cost.json]

``DIR`` holds the baseline build's ``granrs`` package (for example the tree of another commit,
built with ``maturin build --release`` and its wheel unpacked into DIR); the build under test is
the one ``import granrs`` finds (``make install``). Each measurement runs in its own process: the
column of ``granrs.cases.column`` is built, advanced ``--warmup`` steps (past the BDF1 start and
the growth of δt from a tenth of the stable step), then ``--steps`` steps are timed. The two
builds alternate (A B, then B A, ...) so that both see the same load on a shared machine; the
table reports the medians of the rounds and the ratio of the medians, of the wall time and of
the process's CPU time (all threads; with one thread the CPU time does not count the time the
process waits for a core, so its ratio is the steadier one on a shared machine). Both builds must reach
the same state: a digest of u, v, p, Φ (and p_f) after the timed steps is compared and a
mismatch is reported. The JSON of ``--out`` keeps, per case, the pairs of wall and CPU times
of each round and the 1-minute load average at the start and the end of its rounds.

``--steps-total N --wall-total W``: the estimate of a whole run of N steps that took W seconds
with the baseline (the reference case: 14 967 steps, 1 209 s): W × ratio, and N × (cost per
step of the build under test). The steps timed here are early steps of the collapse, so the
second figure is a lower bound when the window grows with the flow; the first assumes that the
ratio holds over the whole run.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from column_bench import state_digest, warm_column_model


def worker(args: argparse.Namespace) -> None:
    import numpy as np

    import granrs

    m = warm_column_model(args)
    t0, c0 = time.perf_counter(), time.process_time()
    log = m.advance(max_steps=args.steps)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    out = {
        "s_per_step": wall / args.steps,
        "cpu_s_per_step": cpu / args.steps,
        "steps": args.steps,
        "time": m.time,
        "digest": state_digest(m),
        "granrs": os.path.dirname(granrs.__file__),
    }
    for key in ("picard_iterations", "pressure_iterations", "viscous_iterations"):
        if key in log and len(log[key]):
            out[key + "_median"] = float(statistics.median(log[key]))
    stages = {k: float(np.sum(v)) for k, v in log.items() if k.startswith("wall_") and len(v)}
    if stages:
        out["stage_s_per_step"] = {k: v / args.steps for k, v in stages.items()}
    print(json.dumps(out), flush=True)


def measure(build: str | None, case: dict, args: argparse.Namespace) -> dict:
    env = dict(os.environ)
    if build:
        env["PYTHONPATH"] = build + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    cmd = [
        sys.executable,
        os.path.abspath(__file__),
        "--worker",
        "--ny",
        str(case["ny"]),
        "--model",
        case["model"],
        "--threads",
        str(case["threads"]),
        "--warmup",
        str(args.warmup),
        "--steps",
        str(args.steps),
    ]
    if case["dry"]:
        cmd.append("--dry")
    if args.active_region is not None:
        cmd += ["--active-region", str(args.active_region), "--sides", args.sides]
    if args.restart:
        cmd += ["--restart", args.restart]
    if args.at_time is not None:
        cmd += ["--at-time", str(args.at_time)] + (["--cache", args.cache] if args.cache else [])
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if r.returncode != 0:
        raise SystemExit(f"worker failed ({' '.join(cmd)}):\n{r.stderr}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--base", help="directory holding the baseline build's granrs package")
    ap.add_argument("--ny", type=int, nargs="+", default=[64])
    ap.add_argument("--model", nargs="+", default=["two-phase"], choices=["two-phase", "granular"])
    ap.add_argument("--threads", type=int, nargs="+", default=[2])
    ap.add_argument("--dry", action="store_true", help="the non-fluidised column (default: fluidised)")
    ap.add_argument("--warmup", type=int, default=10)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--active-region", type=int, default=None)
    ap.add_argument("--sides", default="open-right-top")
    ap.add_argument("--restart", default=None, help="start from this checkpoint.npz of the same case")
    ap.add_argument("--at-time", type=float, default=None, help="start at this time of the run (s)")
    ap.add_argument("--cache", default=None, help="folder keeping the state at --at-time between calls")
    ap.add_argument("--steps-total", type=int, default=None)
    ap.add_argument("--wall-total", type=float, default=None)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if args.worker:
        args.ny, args.model, args.threads = args.ny[0], args.model[0], args.threads[0]
        worker(args)
        return
    if not args.base:
        raise SystemExit("--base DIR is required (the baseline build's granrs package)")
    if not (Path(args.base) / "granrs").is_dir():
        raise SystemExit(f"--base {args.base}: no granrs package in that directory")
    rows = []
    for model in args.model:
        for ny in args.ny:
            for threads in args.threads:
                case = {"model": model, "ny": ny, "threads": threads, "dry": args.dry}
                runs: dict[str, list] = {"base": [], "new": []}
                load_start = os.getloadavg()
                for k in range(args.rounds):
                    order = [("base", args.base), ("new", None)]
                    if k % 2:
                        order.reverse()
                    for label, build in order:
                        runs[label].append(measure(build, case, args))
                        print(json.dumps({**case, "build": label, **runs[label][-1]}), flush=True)
                tb = statistics.median(r["s_per_step"] for r in runs["base"])
                tn = statistics.median(r["s_per_step"] for r in runs["new"])
                digests = {r["digest"] for r in runs["base"] + runs["new"]}
                cb = statistics.median(r["cpu_s_per_step"] for r in runs["base"])
                cn = statistics.median(r["cpu_s_per_step"] for r in runs["new"])
                row = {
                    **case,
                    "s_per_step_base": tb,
                    "s_per_step_new": tn,
                    "ratio_new_over_base": tn / tb,
                    "cpu_s_per_step_base": cb,
                    "cpu_s_per_step_new": cn,
                    "cpu_ratio_new_over_base": cn / cb,
                    "pairs": [[b["s_per_step"], n["s_per_step"]] for b, n in zip(runs["base"], runs["new"])],
                    "cpu_pairs": [
                        [b["cpu_s_per_step"], n["cpu_s_per_step"]] for b, n in zip(runs["base"], runs["new"])
                    ],
                    "rounds": args.rounds,
                    "load_average_start_end": [load_start[0], os.getloadavg()[0]],
                    "same_state": len(digests) == 1,
                }
                if args.steps_total:
                    row["estimate_steps_x_cost_s"] = args.steps_total * tn
                    if args.wall_total:
                        row["estimate_wall_x_ratio_s"] = args.wall_total * tn / tb
                rows.append(row)
                print(json.dumps({"summary": row}), flush=True)
    print()
    print(
        "| model | ny | threads | base wall/step | new wall/step | new/base (wall) | new/base (CPU time) | same state |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['model']}{' dry' if r['dry'] else ''} | {r['ny']} | {r['threads']} | {r['s_per_step_base'] * 1e3:.1f} ms | "
            f"{r['s_per_step_new'] * 1e3:.1f} ms | {r['ratio_new_over_base']:.3f} | {r['cpu_ratio_new_over_base']:.3f} | {r['same_state']} |"
        )
    if args.out:
        Path(args.out).write_text(
            json.dumps(
                {
                    "cpu_count": os.cpu_count(),
                    "args": {k: v for k, v in vars(args).items() if k != "worker"},
                    "rows": rows,
                },
                indent=2,
            )
            + "\n"
        )


if __name__ == "__main__":
    main()
