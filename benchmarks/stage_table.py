"""The share of each stage in the column's step at ny = 64, 128 and 256, dry and fluidised, on one
and two threads, and each stage's time against the machine's memory bandwidth.

    .venv/bin/python benchmarks/stage_table.py [--ny 64 128 256] [--threads 1 2] [--at-time 1.5]
        [--steps 30] [--cache DIR] [--l3-gib-s 75.6] [--dram-gib-s 23.9] [--out FILE.json]

Each configuration is the reference case's (two-phase, the open active window with a band of
ny/16 cells, ``--active-region-sides open-right-top``), fluidised and dry, taken to
``--at-time`` seconds (the deposit spreading over the channel: the window's size and the
iteration counts of the later steps) and then profiled over ``--steps`` steps by
``stage_profile.py``, each thread count in its own process. The state at ``--at-time`` is kept
in ``--cache`` (default ``out/stage_table``) and reused by later calls.

Against the roofline: a stage's time is given as the number of passes over one f64 array of the
window's cells that the memory system could make in that time, at the bandwidth of the shared L3
cache and of DRAM measured on one thread by ``cargo bench -p granrs-core --bench kernels --
stream_triad`` (``--l3-gib-s``, ``--dram-gib-s``; docs/benchmarks.md). A stage that makes about
as many passes as its loops read and write arrays runs at that bandwidth; one that takes several
times more time than its passes is bound by its arithmetic, its dependencies or its
synchronisation instead (docs/benchmarks.md, "Where the step's time goes").
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from stage_profile import STAGES

HERE = Path(__file__).resolve().parent


def profile(ny: int, dry: bool, threads: int, args: argparse.Namespace) -> dict:
    out = Path(args.cache) / f"profile_{ny}_{'dry' if dry else 'fluidised'}_{threads}.json"
    cmd = [sys.executable, str(HERE / "stage_profile.py"), "--ny", str(ny), "--threads", str(threads)]
    cmd += ["--warmup", "3", "--steps", str(args.steps), "--active-region", str(max(ny // 16, 2))]
    cmd += ["--sides", "open-right-top", "--at-time", str(args.at_time), "--cache", args.cache, "--out", str(out)]
    if dry:
        cmd.append("--dry")
    r = subprocess.run(cmd, capture_output=True, text=True, check=False, env=dict(os.environ))
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{r.stderr}")
    return json.loads(out.read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ny", type=int, nargs="+", default=[64, 128, 256])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--at-time", type=float, default=1.5)
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--cache", default="out/stage_table")
    ap.add_argument("--l3-gib-s", type=float, default=75.6)
    ap.add_argument("--dram-gib-s", type=float, default=23.9)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    Path(args.cache).mkdir(parents=True, exist_ok=True)
    results = []
    for ny in args.ny:
        for dry in (False, True):
            # the most threads first: the first call of a case advances it to --at-time
            runs = {t: profile(ny, dry, t, args) for t in sorted(args.threads, reverse=True)}
            runs = {t: runs[t] for t in sorted(runs)}
            results.append({"ny": ny, "dry": dry, "runs": {str(t): r for t, r in runs.items()}})
            lo = min(runs)
            one = runs[lo]
            wx, wy = one["window"] or (None, None)
            cells = wx * wy if wx else one["cells"]
            pass_s = {"L3": cells * 8 / (args.l3_gib_s * 2**30), "DRAM": cells * 8 / (args.dram_gib_s * 2**30)}
            state = "dry" if dry else "fluidised"
            print(
                f"\n### ny = {ny}, {state}, t = {one['time_s']:.2f} s, window {wx} x {wy} ({cells} cells); "
                f"medians per step: " + ", ".join(f"{k} {v:g}" for k, v in one["iterations_median"].items())
            )
            head = " | ".join(f"{t} thread{'s' if t > 1 else ''} (ms)" for t in runs)
            print(f"| stage | {head} | share ({lo} thr.) | speed-up | passes at L3 / DRAM bandwidth ({lo} thr.) |")
            print("|---|" + "---|" * len(runs) + "---|---|---|")
            for k in (*STAGES, "binding"):
                v = [runs[t]["stages_s"][k] for t in runs]
                speed = f"{v[0] / v[-1]:.2f}" if v[-1] > 0 else "—"
                cols = " | ".join(f"{x * 1e3:.2f}" for x in v)
                share = 100 * v[0] / one["s_per_step"]
                print(
                    f"| {k} | {cols} | {share:.1f} % | {speed} | {v[0] / pass_s['L3']:.0f} / {v[0] / pass_s['DRAM']:.0f} |"
                )
            steps = [runs[t]["s_per_step"] for t in runs]
            cols = " | ".join(f"**{x * 1e3:.2f}**" for x in steps)
            print(
                f"| **step** | {cols} | 100 % | {steps[0] / steps[-1]:.2f} | {steps[0] / pass_s['L3']:.0f} / {steps[0] / pass_s['DRAM']:.0f} |"
            )
    if args.out:
        Path(args.out).write_text(json.dumps({"args": vars(args), "results": results}, indent=2) + "\n")


if __name__ == "__main__":
    main()
