"""Command line: ``granrs run CASE``, ``granrs validate NAME``, ``granrs info``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from . import __version__, build_info
from ._granrs import ParameterError, SimulationError, SolverError


def _validate(args) -> int:
    from .validation import CASES, run_case

    if args.name == "list":
        for name, (_, defaults, doc) in sorted(CASES.items()):
            print(f"{name:16s} {doc}  (defaults: {defaults})")
        return 0
    params = {}
    for key in ("n", "re", "steps", "period", "redistance_every", "cfl", "ny", "t_end"):
        val = getattr(args, key)
        if val is not None:
            params[key] = val if key != "n" or len(val) > 1 else val[0]
    record = run_case(args.name, threads=args.threads, **params)
    text = json.dumps(record, indent=2)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(text + "\n")
    print(text)
    return 0 if record["passed"] else 1


def _run(args) -> int:
    if args.case == "cavity":
        from .cases.cavity import run_cavity_case

        run_cavity_case(re=args.re, n=args.n, out=Path(args.out), threads=args.threads)
        return 0
    raise ParameterError(f"invalid parameter `case` = {args.case!r}: allowed 'cavity'")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="granrs", description=f"granrs {__version__}: fluidised dense granular flows")
    sub = parser.add_subparsers(dest="command", required=True)

    v = sub.add_parser("validate", help="run a named validation case and write its JSON record")
    v.add_argument("name", help="case name, or 'list'")
    v.add_argument("--n", type=int, action="append", help="grid size (repeat for a convergence study)")
    v.add_argument("--re", type=float, help="Reynolds number (cavity)")
    v.add_argument("--steps", type=int, help="number of steps (hydrostatic)")
    v.add_argument("--period", type=float, help="period T (single-vortex)")
    v.add_argument("--redistance-every", dest="redistance_every", type=int, help="redistancing frequency (level-set cases)")
    v.add_argument("--cfl", type=float, help="CFL number (level-set cases)")
    v.add_argument("--ny", type=int, help="cells across the height (column-type cases)")
    v.add_argument("--t-end", dest="t_end", type=float, help="end time (s)")
    v.add_argument("--threads", type=int, default=1)
    v.add_argument("--json", help="write the JSON record to this file")

    r = sub.add_parser("run", help="run a case and write its outputs and plots")
    r.add_argument("case", choices=["cavity"])
    r.add_argument("--re", type=float, default=100.0)
    r.add_argument("--n", type=int, default=64)
    r.add_argument("--threads", type=int, default=1)
    r.add_argument("--out", required=True)

    sub.add_parser("info", help="version and build profile")
    args = parser.parse_args(argv)
    try:
        if args.command == "validate":
            return _validate(args)
        if args.command == "run":
            return _run(args)
        print(json.dumps(build_info() | {"python_package": __version__}))
        return 0
    except (ParameterError, SimulationError, SolverError) as err:
        print(f"granrs: {type(err).__name__}: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
