"""Every step of a whole column run: its wall time, iteration counts, active window and stage
times, and a summary by interval of simulated time.

    .venv/bin/python benchmarks/step_log.py --ny 256 [--dry] [--model two-phase|granular]
        [--threads 2] [--active-region 16 --sides open-right-top] [--t-end 3] [--out FILE.json]
    .venv/bin/python benchmarks/step_log.py --summary FILE.json [--interval 0.25]

The column of ``granrs.cases.column`` is built and stepped one step at a time to ``--t-end``
(``Model.step()``: no observation, no output; ``granrs run column`` adds them every 0.01 s).
The JSON holds the steps summed over intervals of 0.05 s of simulated time (the steps that
halved r listed one by one); the summary gives, per interval of simulated time, the steps,
their wall time, the mean wall time per step, the mean Picard / viscous / pressure iterations,
the active window's cells and each stage's share, then the steps whose Picard loop halved r
(the stall safeguard of ``rheology/stage.rs``) and their share of the wall time.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from column_bench import warm_column_model
from stage_profile import STAGES

#: Simulated seconds per interval of the JSON (the summary regroups them).
RECORD_INTERVAL = 0.05


def record(args: argparse.Namespace) -> list:
    """One dict per step of the run of ``args`` to ``args.t_end``."""
    args.warmup = 0
    m = warm_column_model(args)
    rows = []
    while True:
        t0 = time.perf_counter()
        d = m.step()
        wall = time.perf_counter() - t0
        rows.append(
            {
                "t": d["time"],
                "dt": d["dt"],
                "wall": wall,
                "max_speed": d["max_speed"],
                "picard": d["picard"]["iterations"],
                "r_halvings": d["picard"]["r_halvings"],
                "viscous": d["viscous"]["iterations"],
                "pressure": d["pressure"]["iterations"],
                "pore": d["pore"]["iterations"] if d.get("pore") else 0,
                "window": m.active_window,
                "stages": d["stage_seconds"],
            }
        )
        if d["time"] >= args.t_end * (1 - 1e-12):
            return rows


def aggregate(rows: list, interval: float) -> list:
    """The steps of ``rows`` summed over intervals (a, b] of ``interval`` simulated seconds."""
    groups: dict = {}
    for r in rows:
        k = max(0, math.ceil(r["t"] / interval - 1e-9) - 1)
        g = groups.setdefault(
            k,
            {
                "t_start": round(k * interval, 6),
                "t_end": round((k + 1) * interval, 6),
                "steps": 0,
                "wall": 0.0,
                "picard": 0,
                "viscous": 0,
                "pressure": 0,
                "r_halvings": 0,
                "halved_steps": [],
                "window_cells_max": 0,
                "stages": dict.fromkeys(STAGES, 0.0),
            },
        )
        g["steps"] += 1
        g["wall"] += r["wall"]
        for key in ("picard", "viscous", "pressure", "r_halvings"):
            g[key] += r[key]
        if r["r_halvings"]:
            g["halved_steps"].append([r["t"], r["picard"], r["wall"]])
        if r["window"]:
            g["window_cells_max"] = max(g["window_cells_max"], r["window"][0] * r["window"][1])
        for key in STAGES:
            g["stages"][key] += r["stages"][key]
    return [groups[k] for k in sorted(groups)]


def summary(intervals: list, interval: float, t_end: float) -> str:
    """The table of the module docstring, as text, from intervals of [`aggregate`] regrouped into
    intervals of ``interval`` simulated seconds (the last step, which ends at or just past
    ``t_end``, counted in the last interval)."""
    groups: dict = {}
    last = max(0, math.ceil(t_end / interval - 1e-9) - 1)
    for g in intervals:
        groups.setdefault(min(last, max(0, math.ceil(g["t_end"] / interval - 1e-9) - 1)), []).append(g)
    steps = sum(g["steps"] for g in intervals)
    total = sum(g["wall"] for g in intervals)
    lines = [
        f"{steps} steps, {total:.1f} s of steps ({1e3 * total / steps:.1f} ms per step)",
        "| t (s) | steps | wall (s) | ms/step | Picard | viscous | pressure | window cells (largest) | "
        + " | ".join(STAGES)
        + " | rest |",
        "|---" * (9 + len(STAGES)) + "|",
    ]
    for k in sorted(groups):
        gs = groups[k]
        n, w = sum(g["steps"] for g in gs), sum(g["wall"] for g in gs)
        cells = max(g["window_cells_max"] for g in gs)
        shares = [100 * sum(g["stages"][s] for g in gs) / w for s in STAGES]
        mean = {key: sum(g[key] for g in gs) / n for key in ("picard", "viscous", "pressure")}
        lines.append(
            f"| {k * interval:.2f}–{(k + 1) * interval:.2f} | {n} | {w:.1f} | {1e3 * w / n:.1f} | {mean['picard']:.1f} | "
            f"{mean['viscous']:.1f} | {mean['pressure']:.1f} | {cells or 'whole domain'} | "
            + " | ".join(f"{s:.0f} %" for s in shares)
            + f" | {100 - sum(shares):.0f} % |"
        )
    halved = [h for g in intervals for h in g["halved_steps"]]
    hw = sum(h[2] for h in halved)
    lines.append(
        f"steps that halved r: {len(halved)} ("
        + ", ".join(f"t = {h[0]:.4f} s: {h[1]} Picard iterations" for h in halved[:10])
        + f"{', ...' if len(halved) > 10 else ''}), {hw:.1f} s = {100 * hw / total:.1f} % of the steps' wall time"
    )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ny", type=int, default=64)
    ap.add_argument("--dry", action="store_true")
    ap.add_argument("--model", default="two-phase", choices=["two-phase", "granular"])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--active-region", type=int, default=None)
    ap.add_argument("--sides", default="open-right-top")
    ap.add_argument("--t-end", type=float, default=3.0)
    ap.add_argument("--interval", type=float, default=0.25, help="simulated seconds per row of the summary")
    ap.add_argument("--summary", default=None, help="print the summary of a JSON written before, run nothing")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if args.summary:
        data = json.loads(Path(args.summary).read_text())
        intervals, args.t_end = data["intervals"], data["config"]["t_end"]
    else:
        intervals = aggregate(record(args), RECORD_INTERVAL)
        if args.out:
            meta = {k: getattr(args, k) for k in ("ny", "dry", "model", "threads", "active_region", "sides", "t_end")}
            Path(args.out).write_text(
                json.dumps({"config": meta, "record_interval_s": RECORD_INTERVAL, "intervals": intervals}, indent=0)
            )
    print(summary(intervals, args.interval, args.t_end))


if __name__ == "__main__":
    main()
