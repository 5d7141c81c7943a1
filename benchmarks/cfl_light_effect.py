"""The light phase's own CFL number (``--cfl-light 0.9``) with the exact step, against the grid:
for each column and observable of the deposit, the change the option makes at the fine grid
beside the change from the coarse grid to the fine one, both from rows of ``solver_cost.py``
(solvers ``newton`` and ``newton-cfl-light``, whole runs).

    .venv/bin/python benchmarks/cfl_light_effect.py ROWS.json [ROWS.json ...] [--coarse 64] [--fine 128]

The grid's change |x_fine − x_coarse| stands for the fine grid's error: it is that error where the
observable converges at first order (Richardson, e_fine = |x_fine − x_coarse|/(2^p − 1) with
p = 1), and larger than it where the order is higher. The option passes where its change is below
the grid's for every observable; the script prints the table and the verdict.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

#: The deposit's observables compared (summary.json "observables", metres from the gate), and
#: the lowest-row run-out.
OBSERVABLES = [
    "front_h1mm_m",
    "front_h2mm_m",
    "front_h5mm_m",
    "front_h20mm_m",
    "q50_m",
    "q90_m",
    "q95_m",
    "q99_m",
    "centre_of_mass_travel_m",
    "h_back_wall_m",
    "h_gate_m",
    "runout_m",
]


def value(row: dict, name: str) -> float:
    return row["runout_m"] if name == "runout_m" else row["observables"][name]


def compare(rows: list[dict], coarse: int, fine: int) -> tuple[list[str], bool]:
    """The table's lines and whether the option's change is below the grid's everywhere."""
    pick = {(r["ny"], r["column"], r["solver"]): r for r in rows if "observables" in r and r["observables"]}
    lines = [
        f"| column | observable | ny = {coarse} | ny = {fine} | ny = {fine}, cfl_light 0.9 | grid change | option's change | ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    passed = True
    for column in sorted({c for (_, c, _) in pick}):
        keys = [(coarse, column, "newton"), (fine, column, "newton"), (fine, column, "newton-cfl-light")]
        if not all(k in pick for k in keys):
            continue
        a, b, c = (pick[k] for k in keys)
        for name in OBSERVABLES:
            xa, xb, xc = value(a, name), value(b, name), value(c, name)
            grid, option = abs(xb - xa), abs(xc - xb)
            ratio = option / grid if grid > 0 else float("inf")
            passed &= option < grid
            lines.append(
                f"| {column} | {name.removesuffix('_m')} | {xa:.4f} | {xb:.4f} | {xc:.4f} | {grid:.4f} | {option:.4f} | {ratio:.2f} |"
            )
    return lines, passed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rows", type=Path, nargs="+", help="JSON files written by solver_cost.py --out")
    ap.add_argument("--coarse", type=int, default=64)
    ap.add_argument("--fine", type=int, default=128)
    args = ap.parse_args()
    rows = [r for f in args.rows for r in json.loads(f.read_text())["rows"]]
    lines, passed = compare(rows, args.coarse, args.fine)
    if len(lines) == 2:
        ap.error(
            f"no column has newton rows at ny = {args.coarse} and {args.fine} and a newton-cfl-light row at {args.fine}"
        )
    print("\n".join(lines))
    print(f"\nthe option's change is {'below' if passed else 'not below'} the grid's for every observable")


if __name__ == "__main__":
    main()
