"""Whole runs of the paper's reference case and of the granular-only rung for two builds of
granrs, one after the other on the same machine: their wall times, step counts and run-outs,
and the ratio of the wall times.

    .venv/bin/python benchmarks/reference_runs.py [--base DIR] [--new DIR]
        [--cases reference granular granular-window reference-cfl-light] [--threads 2] [--ny 256] [--out FILE.json]

``DIR`` holds a build's ``granrs`` package (a wheel of another commit, built with ``maturin build
--release`` and unpacked into DIR); ``--new`` likewise, or the build ``import granrs`` finds
(``make install``). The cases (``granrs run column``, fluidised, to t = 3 s):

* ``reference``: the paper's grid, ny = 256 (2048 × 256 cells), the two-phase model on the open
  active window (``--active-region 16 --active-region-sides open-right-top``);
* ``granular``: the granular-only model at ny = 256 on the whole domain (``--model granular``);
* ``granular-window``: the granular-only model on the active window of walls with a band of 16
  cells (``--model granular --active-region 16``);
* ``reference-cfl-light``: the reference case with the air more than 6 cells from the grains
  held to a CFL number of 0.9 instead of 0.5 (``--cfl-light 0.9``, ``time.cfl_light``; the grains
  and the interface keep 0.5).

Each run is a process of its own, the base build first; the table gives ``wall_s`` of each run's
summary.json (the time inside the run, without the start-up and the plots) and the process's
wall time. With ``--base``, both builds must reach the same step count and run-out (the column's
answer bit for bit); a difference is reported. Without it each case runs once, with the new
build, and the table gives each case's wall time over the first case's. A run that stops with
an error is a row with its message (``error``), not the end of the script.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CASES = {
    "reference": ["--active-region", "16", "--active-region-sides", "open-right-top"],
    "granular": ["--model", "granular"],
    "granular-window": ["--model", "granular", "--active-region", "16"],
    "reference-cfl-light": ["--active-region", "16", "--active-region-sides", "open-right-top", "--cfl-light", "0.9"],
}

#: The observables of summary.json each row keeps (granrs.observables; docs/validation.md).
OBSERVABLES = (
    "front_h20mm_m",
    "front_h5mm_m",
    "q50_m",
    "q90_m",
    "q95_m",
    "centre_of_mass_travel_m",
    "h_back_wall_m",
    "h_gate_m",
)


def run(build: str | None, case: str, args: argparse.Namespace, out: Path) -> dict:
    return run_column(build, ["--ny", str(args.ny), "--threads", str(args.threads)] + CASES[case], out)


def run_column(build: str | None, options: list[str], out: Path) -> dict:
    """``granrs run column OPTIONS --quiet --out OUT`` in a process of its own, with the build in
    ``build`` (a directory holding a ``granrs`` package) or the one ``import granrs`` finds: its
    summary's wall time, steps, run-out and observables, or ``error``."""
    env = dict(os.environ)
    if build:
        env["PYTHONPATH"] = build + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    cmd = [sys.executable, "-m", "granrs.cli", "run", "column", *options, "--quiet", "--out", str(out)]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        lines = [x for x in r.stderr.strip().splitlines() if x.strip()]
        return {"error": lines[-1] if lines else f"exit status {r.returncode}", "process_wall_s": wall}
    s = json.loads((out / "summary.json").read_text())
    return {
        "wall_s": s["wall_s"],
        "process_wall_s": wall,
        "steps": s["steps"],
        "runout_m": s["runout_m"],
        "stop_reason": s["stop_reason"],
        "load_average": os.getloadavg()[0],
        "observables": {k: (s.get("observables") or {}).get(k) for k in OBSERVABLES},
    }


def fmt_wall(r: dict) -> str:
    return f"{r['wall_s']:.0f} s ({r['wall_s'] / 60:.1f} min)" if "wall_s" in r else f"failed: {r['error']}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", default=None, help="directory holding the baseline build's granrs package")
    ap.add_argument("--new", default=None, help="directory holding the build under test (default: import granrs)")
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ny", type=int, default=256)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    builds = ([("base", args.base)] if args.base else []) + [("new", args.new)]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            res = {}
            for name, build in builds:
                res[name] = run(build, case, args, Path(tmp) / f"{case}-{name}")
                print(json.dumps({"case": case, "build": name, **res[name]}), flush=True)
            row = {"case": case, **res}
            if args.base and "wall_s" in res["base"] and "wall_s" in res["new"]:
                b, n = res["base"], res["new"]
                row["ratio"] = n["wall_s"] / b["wall_s"]
                row["same_answer"] = (b["steps"], b["runout_m"]) == (n["steps"], n["runout_m"])
            rows.append(row)
    if not args.base:
        first = rows[0]["new"].get("wall_s")
        for r in rows:
            if first and "wall_s" in r["new"]:
                r["ratio_to_first"] = r["new"]["wall_s"] / first
    print(
        f"\n| case (ny = {args.ny}, {args.threads} threads) | steps | run-out (m) | "
        + ("base wall_s | new wall_s | new/base | same answer |" if args.base else f"wall_s | over {rows[0]['case']} |")
    )
    print("|---|---|---|" + ("---|---|---|---|" if args.base else "---|---|"))
    for r in rows:
        n = r["new"]
        steps = n.get("steps", "—")
        runout = f"{n['runout_m']:.4f}" if "runout_m" in n else "—"
        if args.base:
            ratio = f"{r['ratio']:.3f}" if "ratio" in r else "—"
            print(
                f"| {r['case']} | {steps} | {runout} | {fmt_wall(r['base'])} | {fmt_wall(n)} | {ratio} | {r.get('same_answer', '—')} |"
            )
        else:
            ratio = f"{r['ratio_to_first']:.3f}" if "ratio_to_first" in r else "—"
            print(f"| {r['case']} | {steps} | {runout} | {fmt_wall(n)} | {ratio} |")
    if args.out:
        Path(args.out).write_text(json.dumps({"args": vars(args), "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
