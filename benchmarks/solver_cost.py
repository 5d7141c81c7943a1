"""Whole column runs with each way of solving the bi-projection's step, in alternation on the same
machine: the Picard iteration of eq. (12) (the default), the exact step of eq. (11)
(``bi_projection.solver = "newton"``) and the deposit-at-rest recipe (the Picard iteration with the
five options of docs/howto/deposit-at-rest.md); on request the exact step with the light phase at
its own CFL number (``newton-cfl-light``: ``--cfl-light 0.9``). Gives each run's wall time, steps,
iterations per step, stop reason, observables and arrest record, and each solver's time inside the
run over the Picard run's of the same round.

    .venv/bin/python benchmarks/solver_cost.py [--ny 16 32] [--columns fluidised dry]
        [--t-end 0.1] [--rounds 3] [--solvers picard newton recipe [newton-cfl-light]] [--threads 1]
        [--out FILE.json]

Each run is ``granrs run column --ny N [--no-fluidised] --t-end T --threads K --quiet`` in a
process of its own, with the solver's ``--set`` items; a round runs every solver once, in the
order given (a solver's flags beside its ``--set`` items in ``FLAGS``). The wall time is the
process's (start-up included) and ``wall_s`` of its summary.json (the time inside the run). A run
that stops with an error is a row with its stop reason, not the end of the script. Ratios are
taken round by round and their median reported.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: The ``--set`` items of each solver.
SOLVERS = {
    "picard": [],
    "newton": ["bi_projection.solver='newton'"],
    "newton-cfl-light": ["bi_projection.solver='newton'"],
    "recipe": [
        "bi_projection.proximal_restarts=20",
        "bi_projection.anderson_depth=5",
        "interface.redistance_every=1",
        "interface.piece_removal_cells=4",
        "interface.redistance_tolerance=0.01",
    ],
}

#: Flags beside the ``--set`` items.
FLAGS = {"newton-cfl-light": ["--cfl-light", "0.9"]}

COLUMNS = {"fluidised": "--fluidised", "dry": "--no-fluidised"}


def run(ny: int, column: str, solver: str, args: argparse.Namespace, out: Path) -> dict:
    """One run in a process of its own: what its summary.json says, with the process's wall."""
    cmd = [sys.executable, "-c", "import sys; from granrs.cli import main; sys.exit(main())"]
    cmd += ["run", "column", "--ny", str(ny), COLUMNS[column], "--t-end", str(args.t_end)]
    cmd += ["--threads", str(args.threads), "--quiet", "--overwrite", "--out", str(out)]
    for item in SOLVERS[solver]:
        cmd += ["--set", item]
    cmd += FLAGS.get(solver, [])
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, check=False)
    row: dict = {"ny": ny, "column": column, "solver": solver, "process_wall_s": time.perf_counter() - t0}
    summary = out / "summary.json"
    if not summary.exists():
        lines = [x for x in r.stderr.strip().splitlines() if x.strip()]
        return row | {"stop_reason": "error: " + (lines[-1] if lines else f"exit status {r.returncode}")}
    s = json.loads(summary.read_text())
    return row | {
        "wall_s": s["wall_s"],
        "steps": s["steps"],
        "t_end_s": s["t_end_s"],
        "stop_reason": s["stop_reason"],
        "iterations": s.get("bi_projection_iterations"),
        "eq11_residual_max": s.get("eq11_residual_max"),
        "runout_m": s["runout_m"],
        "observables": s.get("observables"),
        "rest": {
            k: s.get(k) for k in ("arrest_time_s", "max_front_time_s", "front_retreat_m", "final_granular_speed_m_s")
        },
    }


def table(rows: list[dict], solvers: list[str]) -> list[str]:
    """Per grid and column: each solver's median time inside the run (summary.json's wall_s) and
    process wall (start-up included), its iterations per step (median of the rounds' medians /
    90 % / largest) and the median ratio of its time inside the run to the Picard run's of the
    same round."""
    lines = [
        "| ny | column | solver | run wall (median) | process wall (median) | iterations per step | over Picard (paired median) | stop |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for ny, column in dict.fromkeys((r["ny"], r["column"]) for r in rows):
        group = [r for r in rows if r["ny"] == ny and r["column"] == column]
        rounds = sorted({r["round"] for r in group})
        for solver in solvers:
            mine = [r for r in group if r["solver"] == solver]
            process = statistics.median(r["process_wall_s"] for r in mine)
            walls = [r["wall_s"] for r in mine if "wall_s" in r]
            wall = f"{statistics.median(walls):.2f} s" if walls else "—"
            its = [r["iterations"] for r in mine if r.get("iterations")]
            it = (
                "—"
                if not its
                else "{:g} / {:g} / {}".format(
                    statistics.median(i["median"] for i in its),
                    statistics.median(i["p90"] for i in its),
                    max(i["max"] for i in its),
                )
            )
            ratios = []
            for k in rounds:
                pair = {r["solver"]: r["wall_s"] for r in group if r["round"] == k and "wall_s" in r}
                if "picard" in pair and solver in pair:
                    ratios.append(pair[solver] / pair["picard"])
            ratio = f"{statistics.median(ratios):.2f}" if ratios else "—"
            stops = sorted({r["stop_reason"].split(":")[0] for r in mine})
            lines.append(
                f"| {ny} | {column} | {solver} | {wall} | {process:.2f} s | {it} | {ratio} | {', '.join(stops)} |"
            )
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ny", type=int, nargs="+", default=[16, 32])
    ap.add_argument("--columns", nargs="+", default=list(COLUMNS), choices=list(COLUMNS))
    ap.add_argument("--solvers", nargs="+", default=["picard", "newton", "recipe"], choices=list(SOLVERS))
    ap.add_argument("--t-end", type=float, default=0.1, help="simulated time of each run [s] (3: the whole collapse)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="JSON file for the rows")
    args = ap.parse_args()
    if args.rounds < 1 or args.t_end <= 0 or args.threads < 1:
        ap.error("--rounds and --threads must be at least 1 and --t-end positive")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for ny in args.ny:
            for column in args.columns:
                for k in range(args.rounds):
                    for solver in args.solvers:
                        row = run(ny, column, solver, args, Path(tmp) / "run")
                        rows.append(row | {"round": k})
                        print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    print("\n".join(table(rows, args.solvers)))
    if args.out:
        args.out.write_text(json.dumps({"t_end_s": args.t_end, "threads": args.threads, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
