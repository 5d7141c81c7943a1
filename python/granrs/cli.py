"""Command line: ``granrs run CASE|FILE.toml``, ``granrs sweep FILE.toml``, ``granrs validate NAME``,
``granrs keys``, ``granrs animate DIR``, ``granrs info``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from . import __version__, build_info
from ._granrs import ParameterError, SimulationError, SolverError
from .model import ACTIVE_REGION_SIDES


def _validate(args) -> int:
    from .validation import CASES, run_case

    if args.name == "list":
        for name, (_, defaults, doc) in sorted(CASES.items()):
            print(f"{name:16s} {doc}  (defaults: {defaults})")
        return 0
    params = {}
    for key in ("n", "re", "steps", "period", "redistance_every", "cfl", "ny", "t_end",
                "tau_y", "bn", "geometry", "regularised", "slope", "dt", "theta", "air"):
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


_COLUMN_OPTIONS = ("aspect_ratio", "width", "fluidised", "pore_pressure_ratio", "ny", "t_end", "rheology", "cfl",
                   "length", "compare_with", "threads", "re", "n", "model")


def _run_file(args, parser) -> int:
    from .config import load_config, set_value
    from .io.provenance import command_line
    from .runner import run_config

    given = [f"--{k.replace('_', '-')}" for k in _COLUMN_OPTIONS if getattr(args, k) != parser.get_default(k)]
    if given:
        raise ParameterError(f"invalid parameter `{given[0]}` with a run file: allowed --set section.key=value "
                             "(e.g. --set grid.ny=64), --out, --restart, --quiet")
    sets = list(args.set or [])
    cfg = load_config(args.case, sets + ([f"output.dir={json.dumps(args.out)}"] if args.out else []))
    try:
        summary = run_config(cfg, command=command_line(), progress=not args.quiet, restart=args.restart)
    except KeyboardInterrupt:
        print(f"granrs: interrupted; the outputs written so far are in {cfg['output']['dir']}", file=sys.stderr)
        return 130
    keys = ("runout_m", "t_end_s", "steps", "nx", "ny", "wall_s", "mass_rel_error", "fluidised", "stop_reason")
    print(json.dumps({k: summary[k] for k in keys} | {"out": cfg["output"]["dir"]}, indent=2))
    return 0


def _sweep(args) -> int:
    from .config import load_config
    from .sweep import run_sweep

    cfg = load_config(args.file, args.set or [])
    result = run_sweep(cfg, args.param, scheduler=args.scheduler, workers=args.workers, out=args.out)
    keys = [k for k in result.table[0] if k not in ("dir", "error", "member", "stop_reason", "wall_s", "mass_rel_error")]
    print(",".join(keys))
    for row in result.table:
        print(",".join(f"{row[k]:.6g}" if isinstance(row[k], float) else str(row[k]) for k in keys))
    failed = [r for r in result.table if r["status"] != "ok"]
    for r in failed:
        print(f"member {r['member']} failed: {r['error']}", file=sys.stderr)
    print(f"wrote {', '.join(str(p) for p in result.files.values())}", file=sys.stderr)
    return 0 if not failed else 1


def _run(args, parser) -> int:
    if args.case.endswith(".toml") or Path(args.case).is_file():
        return _run_file(args, parser)
    if args.set or args.restart:
        raise ParameterError("invalid parameter `--set/--restart`: allowed only with a run file (granrs run FILE.toml)")
    if args.out is None:
        raise ParameterError(f"invalid parameter `--out`: required for `granrs run {args.case}`")
    if args.case == "column":
        from .cases.column import ColumnCase, run_column

        case = ColumnCase(aspect_ratio=args.aspect_ratio, width=args.width, fluidised=args.fluidised,
                          pore_pressure_ratio=args.pore_pressure_ratio, ny=args.ny if args.ny is not None else 32,
                          t_end=args.t_end, rheology=args.rheology, cfl=args.cfl, threads=args.threads,
                          length=args.length, model=args.model, active_region=args.active_region,
                          active_region_sides=args.active_region_sides, channel_width=args.channel_width)
        summary = run_column(case, Path(args.out), progress=not args.quiet,
                             compare_with=Path(args.compare_with) if args.compare_with else None)
        keys = ("model", "model_reason", "runout_m", "t_end_s", "steps", "nx", "ny", "wall_s", "mass_rel_error",
                "fluidised", "stop_reason")
        print(json.dumps({k: summary[k] for k in keys}, indent=2))
        return 0
    if args.case == "cavity":
        from .cases.cavity import run_cavity_case

        run_cavity_case(re=args.re, n=args.n, out=Path(args.out), threads=args.threads)
        return 0
    raise ParameterError(f"invalid parameter `case` = {args.case!r}: allowed 'column', 'cavity' or a run file FILE.toml")


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
    v.add_argument("--air", choices=["resolved", "free-surface"],
                   help="dam-break: the two-phase model (resolved, default) or the granular-only model's free surface")
    v.add_argument("--threads", type=int, default=1)
    v.add_argument("--json", help="write the JSON record to this file")

    r = sub.add_parser("run", help="run a case or a run file (FILE.toml) and write its outputs and plots")
    r.add_argument("case", help="'column', 'cavity', or a run file FILE.toml (see `granrs keys`)")
    r.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="run file: override a key, e.g. --set numerics.cfl=0.3 (TOML value; repeat)")
    r.add_argument("--restart", metavar="CHECKPOINT", help="run file: start from a checkpoint.npz")
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
    r.add_argument("--model", default="two-phase", metavar="auto|two-phase|granular|depth-averaged",
                   help="column: the two-phase model (default), the granular-only 2D model (air not resolved: a free "
                        "surface at p = 0), the depth-averaged one, or auto: the depth-averaged model only where it was "
                        "measured within 5%% of the two-phase run-out (docs/models.md)")
    r.add_argument("--cfl", type=float, default=0.5)
    r.add_argument("--active-region", dest="active_region", type=int, metavar="BAND",
                   help="column: run each step on a window around the granular phase with BAND cells of air "
                        "(docs/models.md, active region; with --model granular take BAND >= 16: at ny = 64 BAND = 16 "
                        "is within 0.1 %% of the whole-domain run-out, BAND = 8 2.4 %% long); default: the whole domain")
    r.add_argument("--active-region-sides", dest="active_region_sides", choices=ACTIVE_REGION_SIDES, default="walls",
                   help="column, with --active-region: the window's right and top sides are walls (default), or its "
                        "right side is open (outflow at the air's hydrostatic pressure; docs/models.md, an open right side), or "
                        "its right and top sides are open with backflow stabilisation (open-right-top; with the two-phase "
                        "model and --active-region 4: 4.3x faster at ny = 64, docs/models.md)")
    r.add_argument("--channel-width", dest="channel_width", type=float, metavar="W",
                   help="column: the friction of a channel's side walls W metres apart (the paper's experiment: 0.10; "
                        "not in the paper's 2D model; friction angle that of the base; docs/validation.md)")
    r.add_argument("--length", type=float, help="domain length in m (default L_c + 8.25 H_c, rounded up to the grid)")
    r.add_argument("--compare-with", dest="compare_with", help="another column run's output folder to overlay on front.png")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--threads", type=int, default=1)
    r.add_argument("--out", help="output folder (a run file's output.dir by default)")

    s = sub.add_parser("sweep", help="run the cartesian product of swept keys of a run file on dask")
    s.add_argument("file", help="the base run file FILE.toml")
    s.add_argument("--param", action="append", required=True, metavar="KEY=SPEC",
                   help="swept key: KEY=a:b:n (n values from a to b) or KEY=v1,v2,... (repeat for a product)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a key of the base file (repeat)")
    s.add_argument("--scheduler", help="address of a running dask scheduler (default: a LocalCluster)")
    s.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes, one thread each (2)")
    s.add_argument("--out", help="sweep folder: member-NNN/, sweep.csv, sweep.nc, sweep_runout.png "
                                 "(default: the file's output.dir)")

    sub.add_parser("keys", help="the keys of a run file: type, range, unit, default")
    a = sub.add_parser("animate", help="(re)make animation.gif from the fields saved in an output folder")
    a.add_argument("dir")
    sub.add_parser("info", help="version and build profile")
    args = parser.parse_args(argv)
    try:
        if args.command == "validate":
            return _validate(args)
        if args.command == "run":
            return _run(args, r)
        if args.command == "sweep":
            return _sweep(args)
        if args.command == "keys":
            from .config import describe

            print(describe(), end="")
            return 0
        if args.command == "animate":
            from .io.animation import make_animation

            path = make_animation(Path(args.dir))
            if path is None:
                raise ParameterError(f"invalid parameter `dir` = {args.dir!r}: allowed a folder with fields.nc or fields.pvd")
            print(path)
            return 0
        print(json.dumps(build_info() | {"python_package": __version__}))
        return 0
    except (ParameterError, SimulationError, SolverError, NotImplementedError) as err:
        print(f"granrs: {type(err).__name__}: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
