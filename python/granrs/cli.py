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
    for key in ("n", "re", "steps", "period", "redistance_every", "cfl", "ny", "t_end",
                "tau_y", "bn", "geometry", "regularised", "slope", "dt", "theta"):
        val = getattr(args, key)
        if val is not None:
            params[key] = val[0] if isinstance(val, list) and len(val) == 1 else val
    record = run_case(args.name, threads=args.threads, **params)
    text = json.dumps(record, indent=2)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(text + "\n")
    print(text)
    return 0 if record["passed"] else 1


def _run(args) -> int:
    if args.case == "column":
        from .cases.column import ColumnCase, run_column

        case = ColumnCase(aspect_ratio=args.aspect_ratio, width=args.width, fluidised=args.fluidised,
                          pore_pressure_ratio=args.pore_pressure_ratio, ny=args.ny if args.ny is not None else 32,
                          t_end=args.t_end, rheology=args.rheology, cfl=args.cfl, threads=args.threads,
                          length=args.length)
        summary = run_column(case, Path(args.out), progress=not args.quiet,
                             compare_with=Path(args.compare_with) if args.compare_with else None)
        keys = ("runout_m", "t_end_s", "steps", "nx", "ny", "wall_s", "mass_rel_error", "fluidised", "stop_reason")
        print(json.dumps({k: summary[k] for k in keys}, indent=2))
        return 0
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
    v.add_argument("--tau-y", dest="tau_y", type=float, help="yield stress (poiseuille-bingham, cessation)")
    v.add_argument("--bn", type=float, action="append", help="Bingham number (cavity-bingham; repeat for several)")
    v.add_argument("--geometry", choices=["couette", "poiseuille"], help="cessation geometry")
    v.add_argument("--regularised", action="store_true", default=None, help="also run the regularised law (heap-at-rest)")
    v.add_argument("--slope", type=float, help="slope in degrees (sliding-block, heap-at-rest)")
    v.add_argument("--dt", type=float, action="append", help="time step (cessation; repeat for a convergence study)")
    v.add_argument("--theta", type=float, action="append", help="pseudo-relaxation (picard-ratio; repeat)")
    v.add_argument("--threads", type=int, default=1)
    v.add_argument("--json", help="write the JSON record to this file")

    r = sub.add_parser("run", help="run a case and write its outputs and plots")
    r.add_argument("case", choices=["column", "cavity"])
    r.add_argument("--re", type=float, default=100.0, help="Reynolds number (cavity)")
    r.add_argument("--n", type=int, default=64, help="cells per side (cavity)")
    r.add_argument("--aspect-ratio", dest="aspect_ratio", type=float, default=2.0, help="H_c / L_c (column)")
    r.add_argument("--width", type=float, default=0.20, help="column width L_c in m")
    fl = r.add_mutually_exclusive_group()
    fl.add_argument("--fluidised", dest="fluidised", action="store_true", default=True, help="pore pressure on (default)")
    fl.add_argument("--no-fluidised", dest="fluidised", action="store_false", help="no pore pressure")
    r.add_argument("--pore-pressure-ratio", dest="pore_pressure_ratio", type=float, default=0.9, help="β (0.9 in the paper)")
    r.add_argument("--ny", type=int, help="cells over the domain height (column; 256 is the paper's grid)")
    r.add_argument("--t-end", dest="t_end", type=float, default=3.0, help="end time in s (column)")
    r.add_argument("--rheology", choices=["drucker-prager", "mu-i"], default="drucker-prager")
    r.add_argument("--cfl", type=float, default=0.5)
    r.add_argument("--length", type=float, help="domain length in m (default L_c + 5.125 H_c)")
    r.add_argument("--compare-with", dest="compare_with", help="another column run's output folder to overlay on front.png")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
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
