"""One change at a time on the coarse column: what sets the late reach of the front.

    python examples/column_variants.py                 # the table in docs/validation.md (~10 min)
    python examples/column_variants.py --dt 0          # the same with adaptive steps

Each variant is the dry column at ny = 32 with a fixed step (default δt = 0.2 ms, 15 000 steps,
about 2.5 min per run on one core) and one parameter changed; outputs in ``out/variants/NAME``
and one JSON line per run on stdout (run-out, largest front, wall time).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import granrs.cases.column as column
import granrs.cases.column.build as build

VARIANTS = {
    "baseline": ({}, {}),
    "theta05": ({"theta": 0.5}, {}),
    "eta1": ({"granular_viscosity": 1.0}, {}),
    "eps1": ({}, {"interface_width": 1.0}),
    "wall27": ({"wall_friction_angle": 27.0}, {}),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dt", type=float, default=2e-4, help="fixed step in s (0: adaptive)")
    ap.add_argument("--only", nargs="*", help="variant names (default: all)")
    ap.add_argument("--out", default="out/variants")
    args = ap.parse_args()
    original = build.Numerics
    for name, (case_changes, numerics_changes) in VARIANTS.items():
        if args.only and name not in args.only:
            continue

        def numerics(**kw):
            if args.dt > 0:
                kw["dt"] = args.dt
            kw.update(numerics_changes)  # noqa: B023 (called within this iteration)
            return original(**kw)

        build.Numerics = numerics  # build_model reads the name from its module
        try:
            case = column.ColumnCase(ny=32, fluidised=False, **case_changes)
            s = column.run_column(case, Path(args.out) / name, progress=False)
        finally:
            build.Numerics = original
        print(
            json.dumps({"variant": name, **{k: s[k] for k in ("runout_m", "max_front_m", "wall_s", "steps")}}),
            flush=True,
        )


if __name__ == "__main__":
    main()
