"""One change at a time on the coarse column: what sets the late reach of the front.

    python examples/column_variants.py                 # the table in docs/validation.md (~10 min)
    python examples/column_variants.py --dt 0          # the same with adaptive steps

Each variant is the dry column at ny = 32 with a fixed step (default δt = 0.2 ms, 15 000 steps,
about 2.5 min per run on one core) and one parameter changed; outputs in ``out/variants/NAME``
and one JSON line per run on stdout (run-out, largest front, wall time).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import granrs.cases.column as column
from granrs import CoulombWall

VARIANTS = {
    "baseline": ({}, {}),
    "theta05": ({}, {"theta": 0.5}),
    "eta1": ({"rheology": dataclasses.replace(column.column_rheology(), viscosity=1.0)}, {}),
    "eps1": ({}, {"interface_width": 1.0}),
    "wall27": ({"base": CoulombWall(27.0)}, {}),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dt", type=float, default=2e-4, help="fixed step in s (0: adaptive)")
    ap.add_argument("--only", nargs="*", help="variant names (default: all)")
    ap.add_argument("--out", default="out/variants")
    args = ap.parse_args()
    for name, (case_changes, option_changes) in VARIANTS.items():
        if args.only and name not in args.only:
            continue
        fixed = {"dt": args.dt} if args.dt > 0 else {}
        case = column.ColumnCase(ny=32, fluidised=False, **case_changes).with_options(**fixed, **option_changes)
        s = column.run_column(case, Path(args.out) / name, progress=False)
        print(
            json.dumps({"variant": name, **{k: s[k] for k in ("runout_m", "max_front_m", "wall_s", "steps")}}),
            flush=True,
        )


if __name__ == "__main__":
    main()
