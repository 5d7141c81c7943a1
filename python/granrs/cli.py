"""Command line: ``granrs run CASE|FILE.toml``, ``granrs sweep FILE.toml``, ``granrs validate NAME``,
``granrs keys``, ``granrs animate DIR``, ``granrs info``."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import signal
import sys
import threading
from pathlib import Path
from typing import Optional

from ._granrs import ParameterError, SimulationError, SolverError, __version__, build_info
from .cases.cavity import run_cavity_case
from .cases.column import run_column
from .cases.column.run import check_case
from .config import apply_sets, column_case, describe, key as config_key, load_config, resolve, set_value, toml_value
from .io.animation import make_animation
from .io.outputs import (
    atomic_write,
    check_path_length,
    check_path_text,
    commit_output_dir,
    lock_output_dir,
    plan_output_dir,
    read_columns,
    record,
    release_output_dir,
)
from .io.provenance import command_line
from .runner import run_config
from .simulation import Terminated, raise_terminated
from .sweep import MAX_MEMBERS, run_sweep
from .validation import CASES, run_case


def _number(flag: str, kind: str, lo: float, hi: float, lo_open: bool = False, hi_open: bool = False):
    """An argparse type: an int or a finite float in [lo, hi] (an end excluded with ``lo_open``,
    ``hi_open``); the error names the flag and its range."""
    what = "an integer" if kind == "int" else "a number"
    rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"

    def parse(text: str):
        try:
            v = int(text) if kind == "int" else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"invalid parameter `{flag}` = {text!r}: allowed {what} in {rng}"
            ) from None
        if (
            kind == "float"
            and not math.isfinite(v)
            or (v <= lo if lo_open else v < lo)
            or (v >= hi if hi_open else v > hi)
        ):
            raise argparse.ArgumentTypeError(f"invalid parameter `{flag}` = {text!r}: allowed {what} in {rng}")
        return v

    return parse


def _key_type(flag: str, dotted: str):
    """The argparse type of a flag that sets a run-file key: that key's range (``granrs keys``)."""
    k = config_key(dotted)
    lo, hi = -math.inf if k.lo is None else k.lo, math.inf if k.hi is None else k.hi
    return _number(flag, k.kind, lo, hi, k.lo_open, k.hi_open)


def _key_help(text: str, dotted: str) -> str:
    """The help of a flag of ``granrs run column`` that sets the run-file key ``dotted``: ``text``,
    then the key, its allowed values with their unit and its default (``granrs keys``; a key whose
    default is None: ``text`` says what its absence means)."""
    k = config_key(dotted)
    default = "" if k.default is None else f"; default {toml_value(k.default)}"
    return f"{text} ({dotted}: {k.allowed()}{default})".replace("%", "%%")


def _key_flag(parser, flag: str, dotted: str, text: str, **kwargs) -> None:
    """Adds to ``parser`` the flag ``flag`` that sets the run-file key ``dotted``: its type is the
    key's range (:func:`_key_type`), its help ``text`` with the key (:func:`_key_help`)."""
    parser.add_argument(flag, type=_key_type(flag, dotted), help=_key_help(text, dotted), **kwargs)


def _choices(dotted: str) -> tuple:
    """The allowed values of a choice key of the run files."""
    return config_key(dotted).choices


def _out_plan(out, overwrite: bool, append: bool = False):
    return plan_output_dir(out, overwrite=overwrite, append=append, name="--out")


def _interrupted(out, progress: bool = False, err: Optional[BaseException] = None) -> int:
    """One line on stderr (after the progress bar's); exit status 128 + the signal: 130 for a
    Ctrl-C (SIGINT), 143 for SIGTERM, 129 for SIGHUP."""
    where = f"; the outputs written so far are in {out} (summary.json says where it stopped)" if out else ""
    what = str(err) if isinstance(err, Terminated) else "interrupted (Ctrl-C)"
    print(f"{chr(10) if progress else ''}granrs: {what}{where}", file=sys.stderr)
    return 128 + (err.signum if isinstance(err, Terminated) else signal.SIGINT)


def _json_path(text: str) -> Path:
    """The file of ``granrs validate --json``, checked before the case runs: no control
    character, not too long, not a folder, in a folder that exists or can be made and is writable."""
    check_path_text("--json", text)
    check_path_length("--json", text)
    path = Path(text)
    if path.is_dir():
        raise ParameterError(f"invalid parameter `--json` = {text!r}: it is a folder; allowed a file path")
    ancestor = Path(os.path.abspath(path)).parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir() or not os.access(ancestor, os.W_OK | os.X_OK):
        raise ParameterError(
            f"invalid parameter `--json` = {text!r}: {str(ancestor)!r} is not a writable folder; allowed a "
            "file in a writable folder"
        )
    return path


def _plot_backend() -> None:
    """The plots need matplotlib with its Agg back-end: checked before the work."""
    try:
        import matplotlib  # deferred: the plot back-end is checked only by the commands that plot

        matplotlib.use("Agg")
    except Exception as err:  # noqa: BLE001 - a missing or broken matplotlib: the same refusal
        raise ParameterError(
            f"invalid plot back-end: matplotlib with Agg cannot be loaded ({type(err).__name__}: {err}); "
            "allowed an installation of granrs with matplotlib"
        ) from None


def _validate(args) -> int:
    if args.name == "list":
        for name, (_, defaults, doc) in sorted(CASES.items()):
            print(f"{name:16s} {doc}  (defaults: {defaults})")
        return 0
    params = {}
    for key in (
        "n",
        "re",
        "steps",
        "period",
        "redistance_every",
        "cfl",
        "ny",
        "t_end",
        "tau_y",
        "bn",
        "geometry",
        "regularised",
        "slope",
        "dt",
        "theta",
        "air",
        "mass_correction",
    ):
        val = getattr(args, key)
        if val is not None:
            params[key] = val[0] if isinstance(val, list) and len(val) == 1 else val
    json_path = _json_path(args.json) if args.json else None
    record = run_case(args.name, threads=args.threads, **params)
    text = json.dumps(record, indent=2)
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(json_path, lambda f: f.write(text + "\n"))
    print(text)
    if record["passed"] is None:
        print(
            f"granrs: {args.name}: not judged (passed: null): the parameters are outside the range of its reference",
            file=sys.stderr,
        )
    return 1 if record["passed"] is False else 0


_COLUMN_OPTIONS = (
    "aspect_ratio",
    "width",
    "fluidised",
    "pore_pressure_ratio",
    "ny",
    "t_end",
    "rest_speed",
    "rest_duration",
    "rheology",
    "cfl",
    "cfl_light",
    "length",
    "compare_with",
    "threads",
    "re",
    "n",
    "model",
    "active_region",
    "active_region_sides",
    "channel_width",
    "friction_angle",
)
#: The run-file key each flag of `granrs run column` sets (its range, default and doc are the key's).
_COLUMN_KEYS = {
    "aspect_ratio": "geometry.aspect_ratio",
    "width": "geometry.width",
    "fluidised": "fluidisation.fluidised",
    "pore_pressure_ratio": "fluidisation.pore_pressure_ratio",
    "ny": "grid.ny",
    "t_end": "time.t_end",
    "rest_speed": "rest.speed",
    "rest_duration": "rest.duration",
    "cfl": "time.cfl",
    "cfl_light": "time.cfl_light",
    "rheology": "rheology.law",
    "friction_angle": "rheology.friction_angle",
    "threads": "numerics.threads",
    "active_region": "active_region.band",
    "active_region_sides": "active_region.sides",
    "channel_width": "side_walls.width",
}
_CAVITY_OPTIONS = ("re", "n")
#: The keys `granrs run column` takes from its own flags or none, which --set may not change.
_COLUMN_FLAG_KEYS = {
    **{dotted: "--" + name.replace("_", "-") for name, dotted in _COLUMN_KEYS.items()},
    "geometry.length": "--length",
    "case.model": "--model",
}


def _column_set(item: str) -> str:
    """A ``--set KEY=VALUE`` of `granrs run column`, refused (``ParameterError``) where a flag of the
    column sets the key, or where the column does not read it (``case.name``, ``output.*``: the
    case is the column, the folder is --out)."""
    dotted = item.partition("=")[0].strip()
    if dotted in _COLUMN_FLAG_KEYS:
        raise ParameterError(
            f"invalid parameter `--set {item}` with `granrs run column`: allowed keys without a flag of "
            f"their own; use {_COLUMN_FLAG_KEYS[dotted]}"
        )
    if dotted == "case.name" or dotted.startswith("output."):
        raise ParameterError(
            f"invalid parameter `--set {item}` with `granrs run column`: not read there (the case is the "
            "column, its outputs go to --out); allowed the model's keys (granrs keys)"
        )
    return item


def _run_file(args, parser) -> int:
    given = [f"--{k.replace('_', '-')}" for k in _COLUMN_OPTIONS if getattr(args, k) != parser.get_default(k)]
    if given:
        raise ParameterError(
            f"invalid parameter `{given[0]}` with a run file: allowed --set section.key=value "
            "(e.g. --set grid.ny=64), --out, --restart, --allow-changes, --overwrite, --quiet"
        )
    if args.allow_changes and not args.restart:
        raise ParameterError("invalid parameter `--allow-changes`: allowed only with --restart CHECKPOINT")
    if args.out is not None and not args.out.strip():
        _out_plan(args.out, args.overwrite)  # names the empty --out
    sets = list(args.set or [])
    if args.out is not None:
        check_path_text("--out", args.out)
    cfg = load_config(args.case, sets + ([f"output.dir={json.dumps(args.out)}"] if args.out else []))
    _plot_backend()
    try:
        summary = run_config(
            cfg,
            command=command_line(),
            progress=not args.quiet,
            restart=args.restart,
            overwrite=args.overwrite,
            allow_changes=args.allow_changes,
            out_name="--out" if args.out else "output.dir",
            source=args.case,
        )
    except KeyboardInterrupt as err:
        return _interrupted(cfg["output"]["dir"], not args.quiet, err)
    keys = ("runout_m", "t_end_s", "steps", "nx", "ny", "wall_s", "mass_rel_error", "fluidised", "stop_reason")
    print(json.dumps({k: summary[k] for k in keys} | {"out": cfg["output"]["dir"]}, indent=2))
    return 0


def _sweep(args) -> int:
    if args.out is not None:
        check_path_text("--out", args.out)
    cfg = load_config(args.file, args.set or [])
    _plot_backend()
    out = args.out if args.out is not None else cfg["output"]["dir"]
    try:
        result = run_sweep(
            cfg,
            args.param,
            scheduler=args.scheduler,
            workers=args.workers,
            out=args.out,
            overwrite=args.overwrite,
            max_members=args.max_members,
            fixed=tuple(item.partition("=")[0].strip() for item in args.set or []),
            source=args.file,
        )
    except KeyboardInterrupt as err:
        where = f"; the members that ran are in {out}, sweep.csv says which were interrupted"
        print(f"granrs: {'interrupted (Ctrl-C)' if not isinstance(err, Terminated) else err}{where}", file=sys.stderr)
        return 128 + (err.signum if isinstance(err, Terminated) else signal.SIGINT)
    keys = [
        k for k in result.table[0] if k not in ("dir", "error", "member", "stop_reason", "wall_s", "mass_rel_error")
    ]
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
    if args.case not in ("column", "cavity") and (Path(args.case).exists() or "/" in args.case):
        raise ParameterError(
            f"invalid parameter `case` = {args.case!r}: not a readable run file; allowed 'column', "
            "'cavity' or a run file FILE.toml"
        )
    for flag in ("restart", "allow_changes") + (("set",) if args.case != "column" else ()):
        if getattr(args, flag):
            allowed = "a run file (granrs run FILE.toml)" + (" or `granrs run column`" if flag == "set" else "")
            raise ParameterError(f"invalid parameter `--{flag.replace('_', '-')}`: allowed only with {allowed}")
    if args.case not in ("column", "cavity"):
        raise ParameterError(
            f"invalid parameter `case` = {args.case!r}: allowed 'column', 'cavity' or a run file "
            "FILE.toml (an existing file)"
        )
    if args.out is None:
        raise ParameterError(f"invalid parameter `--out`: required for `granrs run {args.case}`")
    other = (
        _CAVITY_OPTIONS
        if args.case == "column"
        else tuple(k for k in _COLUMN_OPTIONS if k not in _CAVITY_OPTIONS and k != "threads")
    )
    given = [f"--{k.replace('_', '-')}" for k in other if getattr(args, k) != parser.get_default(k)]
    if given:
        allowed = "--re, --n" if args.case == "cavity" else "the column's flags (granrs run --help)"
        raise ParameterError(
            f"invalid parameter `{given[0]}` with `granrs run {args.case}`: not used by this case; "
            f"allowed {allowed}, --threads, --out, --overwrite, --quiet"
        )
    if args.case == "column":
        if args.active_region_sides is not None and args.active_region is None:
            raise ParameterError(
                f"invalid parameter `--active-region-sides` = {args.active_region_sides!r}: allowed only "
                "with --active-region BAND"
            )
        if args.model == "depth-averaged":
            for flag, v in (
                ("--active-region", args.active_region),
                ("--channel-width", args.channel_width),
                ("--rheology", args.rheology),
                ("--cfl", args.cfl),
                ("--cfl-light", args.cfl_light),
                ("--threads", args.threads),
            ):
                if v is not None and v != parser.get_default(flag[2:].replace("-", "_")):
                    raise ParameterError(
                        f"invalid parameter `{flag}` = {v!r} with --model depth-averaged: not used by "
                        "the depth-averaged model; allowed only with --model two-phase or granular"
                    )
        compare = None
        if args.compare_with is not None:
            compare = Path(args.compare_with)
            check_path_text("--compare-with", args.compare_with)
            missing = [n for n in ("summary.json", "front.csv") if not (compare / n).is_file()]
            if missing:
                raise ParameterError(
                    f"invalid parameter `--compare-with` = {args.compare_with!r}: "
                    f"{'no such folder' if not compare.is_dir() else 'no ' + ' or '.join(missing) + ' there'}"
                    "; allowed the output folder of a finished column run"
                )
            for name, read in (("summary.json", lambda p: json.loads(p.read_text())), ("front.csv", read_columns)):
                try:
                    read(compare / name)
                except (OSError, ValueError, StopIteration) as err:
                    raise ParameterError(
                        f"invalid parameter `--compare-with` = {args.compare_with!r}: its {name} cannot be read "
                        f"({type(err).__name__}: {str(err)[:120]}); allowed the output folder of a finished column run"
                    ) from None
        raw: dict = {}
        for name, dotted in _COLUMN_KEYS.items():
            value = getattr(args, name)
            if value is not None:
                set_value(raw, dotted, value)
        raw = apply_sets(raw, [_column_set(item) for item in args.set or []])
        if args.model in _choices("case.model"):  # the keys the model does not read are refused with it
            set_value(raw, "case.model", args.model)
        case = column_case(resolve(raw))
        try:  # None: the column's own domain (ColumnCase.domain)
            case.geometry = dataclasses.replace(case.geometry, length=args.length)
        except ParameterError as err:  # the flag's own name: the length is beyond the gate
            raise ParameterError(str(err).replace("`geometry.length`", "`--length`", 1)) from None
        case.model = args.model  # checked by the case: its error says there is no automatic choice
        case.validate()
        check_case(case)
        _plot_backend()
        plan = _out_plan(args.out, args.overwrite)
        commit_output_dir(plan, command_line())
        for note in plan.notes:
            print(f"granrs: {note}", file=sys.stderr)
        try:
            summary = run_column(case, Path(args.out), progress=not args.quiet, compare_with=compare)
        except KeyboardInterrupt as err:
            return _interrupted(args.out, not args.quiet, err)
        finally:
            release_output_dir(args.out)
        keys = (
            "model",
            "model_reason",
            "runout_m",
            "t_end_s",
            "steps",
            "nx",
            "ny",
            "wall_s",
            "mass_rel_error",
            "fluidised",
            "stop_reason",
        )
        print(json.dumps({k: summary[k] for k in keys}, indent=2))
        return 0
    _plot_backend()
    plan = _out_plan(args.out, args.overwrite)
    commit_output_dir(plan, command_line())
    for note in plan.notes:
        print(f"granrs: {note}", file=sys.stderr)
    try:
        for name in ("cavity.png", "summary.json"):
            record(Path(args.out) / name)
        run_cavity_case(
            re=_given(args.re, 100.0), n=_given(args.n, 64), out=Path(args.out), threads=_given(args.threads, 1)
        )
    except KeyboardInterrupt as err:
        return _interrupted(args.out, False, err)
    finally:
        release_output_dir(args.out)
    return 0


def _given(value, default):
    return default if value is None else value


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="granrs", description=f"granrs {__version__}: fluidised dense granular flows")
    sub = parser.add_subparsers(dest="command", required=True)

    v = sub.add_parser("validate", help="run a named validation case and write its JSON record")
    v.add_argument("name", help="case name, or 'list'")
    v.add_argument(
        "--n", type=_number("--n", "int", 2, 65536), action="append", help="grid size (repeat for a convergence study)"
    )
    v.add_argument("--re", type=_number("--re", "float", 0.0, 1e6, lo_open=True), help="Reynolds number (cavity)")
    v.add_argument("--steps", type=_number("--steps", "int", 1, 10**7), help="number of steps (hydrostatic)")
    v.add_argument(
        "--period", type=_number("--period", "float", 0.0, 1e4, lo_open=True), help="period T (single-vortex)"
    )
    v.add_argument(
        "--redistance-every",
        dest="redistance_every",
        type=_number("--redistance-every", "int", 0, 10**6),
        help="redistancing frequency (level-set cases)",
    )
    v.add_argument(
        "--cfl", type=_number("--cfl", "float", 0.0, 10.0, lo_open=True), help="CFL number (level-set cases)"
    )
    v.add_argument("--ny", type=_number("--ny", "int", 8, 4096), help="cells across the height (column-type cases)")
    v.add_argument(
        "--t-end", dest="t_end", type=_number("--t-end", "float", 0.0, 1e4, lo_open=True), help="end time (s)"
    )
    v.add_argument(
        "--tau-y",
        dest="tau_y",
        type=_number("--tau-y", "float", 0.0, 1e9),
        help="yield stress (poiseuille-bingham, cessation)",
    )
    v.add_argument(
        "--bn",
        type=_number("--bn", "float", 0.0, 1e6),
        action="append",
        help="Bingham number (cavity-bingham; repeat for several)",
    )
    v.add_argument("--geometry", choices=["couette", "poiseuille"], help="cessation geometry")
    v.add_argument(
        "--regularised", action="store_true", default=None, help="also run the regularised law (heap-at-rest)"
    )
    v.add_argument(
        "--slope", type=_number("--slope", "float", 0.0, 89.0), help="slope in degrees (sliding-block, heap-at-rest)"
    )
    v.add_argument(
        "--dt",
        type=_number("--dt", "float", 0.0, 1e3, lo_open=True),
        action="append",
        help="time step (cessation; repeat for a convergence study)",
    )
    v.add_argument(
        "--theta",
        type=_number("--theta", "float", 0.0, 1.0),
        action="append",
        help="pseudo-relaxation (picard-ratio; repeat)",
    )
    v.add_argument(
        "--air",
        choices=["resolved", "free-surface"],
        help="dam-break: the two-phase model (resolved, default) or the granular-only model's free surface",
    )
    v.add_argument(
        "--no-mass-correction",
        dest="mass_correction",
        action="store_false",
        default=None,
        help="dam-break: without the global mass correction (it is on by default)",
    )
    v.add_argument("--threads", type=_key_type("--threads", "numerics.threads"), default=1)
    v.add_argument("--json", help="write the JSON record to this file")

    r = sub.add_parser("run", help="run a case or a run file (FILE.toml) and write its outputs and plots")
    r.add_argument("case", help="'column', 'cavity', or a run file FILE.toml (see `granrs keys`)")
    r.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a key of a run file, or with `granrs run column` a key that none of its flags sets, "
        "e.g. --set bi_projection.proximal_restarts=20 (TOML value; repeat)",
    )
    r.add_argument(
        "--restart",
        metavar="CHECKPOINT",
        help="run file: start from a checkpoint.npz (into its own folder: the run is continued, appended to)",
    )
    r.add_argument(
        "--allow-changes",
        dest="allow_changes",
        action="store_true",
        help="with --restart: allow a configuration that differs from the checkpoint's",
    )
    r.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the run already in --out: remove exactly the files its granrs-manifest.txt lists, "
        "keep every other (docs/failures.md)",
    )
    r.add_argument("--re", type=_number("--re", "float", 0.0, 1e5, lo_open=True), help="Reynolds number (cavity; 100)")
    r.add_argument("--n", type=_number("--n", "int", 8, 1024), help="cells per side (cavity; 64)")
    _key_flag(r, "--aspect-ratio", "geometry.aspect_ratio", "column: H_c / L_c")
    _key_flag(r, "--width", "geometry.width", "column: width L_c of the reservoir, the gate at x = L_c")
    fl = r.add_mutually_exclusive_group()
    fl.add_argument(
        "--fluidised",
        dest="fluidised",
        action="store_true",
        default=True,
        help="column: pore pressure on (default; fluidisation.fluidised = true)",
    )
    fl.add_argument(
        "--no-fluidised",
        dest="fluidised",
        action="store_false",
        help="column: no pore pressure (fluidisation.fluidised = false)",
    )
    _key_flag(
        r,
        "--pore-pressure-ratio",
        "fluidisation.pore_pressure_ratio",
        "column: β, pore pressure over the lithostatic one",
    )
    _key_flag(r, "--ny", "grid.ny", "column: cells over the domain height (256 is the paper's grid)")
    _key_flag(r, "--t-end", "time.t_end", "column: end of the simulated time, earlier at rest")
    _key_flag(
        r, "--rest-speed", "rest.speed", "column: the run stops at rest: granular speed below this for --rest-duration"
    )
    _key_flag(
        r,
        "--rest-duration",
        "rest.duration",
        "column: how long the granular speed stays below --rest-speed before the run stops",
    )
    r.add_argument(
        "--rheology",
        choices=_choices("rheology.law"),
        help=_key_help("column: the granular rheology", "rheology.law"),
    )
    _key_flag(r, "--friction-angle", "rheology.friction_angle", "column: internal friction angle α")
    r.add_argument(
        "--model",
        default="two-phase",
        metavar="|".join(_choices("case.model")),
        help=_key_help(
            "column: the two-phase model, the granular-only 2D model (air not resolved: a free surface at p = 0) "
            "or the depth-averaged one (docs/howto/choosing-a-model.md)",
            "case.model",
        ),
    )
    _key_flag(r, "--cfl", "time.cfl", "column: CFL number")
    _key_flag(
        r,
        "--cfl-light",
        "time.cfl_light",
        "column: CFL number of the air more than 6 cells from the grains, which keep --cfl; without it --cfl "
        "everywhere",
    )
    _key_flag(
        r,
        "--active-region",
        "active_region.band",
        "column: run each step on a window around the granular phase with BAND cells of air "
        "(docs/models.md, active region; with --model granular take BAND >= 16: at ny = 64 BAND = 16 "
        "is within 0.1 % of the whole-domain run-out, BAND = 8 2.4 % long); without it, the whole domain",
        metavar="BAND",
    )
    r.add_argument(
        "--active-region-sides",
        dest="active_region_sides",
        choices=_choices("active_region.sides"),
        help=_key_help(
            "column, with --active-region: the window's right and top sides are walls, or its right side is open "
            "(outflow at the air's hydrostatic pressure; docs/models.md, an open right side), or its right and top "
            "sides are open with backflow stabilisation (open-right-top; with the two-phase model and "
            "--active-region 4: 4.3x faster at ny = 64, docs/models.md)",
            "active_region.sides",
        ),
    )
    _key_flag(
        r,
        "--channel-width",
        "side_walls.width",
        "column: the friction of a channel's side walls W metres apart (the paper's experiment: 0.10; "
        "not in the paper's 2D model; friction angle that of the base; docs/validation.md); without it, no side walls",
        metavar="W",
    )
    _key_flag(r, "--length", "geometry.length", "column: domain length, beyond --width; without it L_c + 8.25 H_c")
    r.add_argument(
        "--compare-with", dest="compare_with", help="another column run's output folder to overlay on front.png"
    )
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    _key_flag(r, "--threads", "numerics.threads", "Rust threads")
    r.add_argument("--out", help="output folder, new or empty unless --overwrite (a run file's output.dir by default)")

    s = sub.add_parser("sweep", help="run the cartesian product of swept keys of a run file on dask")
    s.add_argument("file", help="the base run file FILE.toml")
    s.add_argument(
        "--param",
        action="append",
        required=True,
        metavar="KEY=SPEC",
        help="swept key: KEY=a:b:n (n values from a to b) or KEY=v1,v2,... (repeat for a product)",
    )
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a key of the base file (repeat)")
    s.add_argument("--scheduler", help="address of a running dask scheduler (default: a LocalCluster)")
    s.add_argument(
        "--workers",
        type=_number("--workers", "int", 1, 256),
        default=2,
        help="LocalCluster worker processes, one thread each (2)",
    )
    s.add_argument(
        "--out",
        help="sweep folder: member-NNN/, sweep.csv, sweep.nc, sweep_runout.png "
        "(default: the file's output.dir; new or empty unless --overwrite)",
    )
    s.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the sweep already in --out: remove exactly the files its manifests list",
    )
    s.add_argument(
        "--max-members",
        dest="max_members",
        type=_number("--max-members", "int", 1, 10**9),
        default=MAX_MEMBERS,
        help=f"the most members the sweep may have ({MAX_MEMBERS}): a larger product is refused before any run",
    )

    sub.add_parser("keys", help="the keys of a run file: type, range, unit, default")
    a = sub.add_parser("animate", help="(re)make animation.gif from the fields saved in an output folder")
    a.add_argument("dir")
    sub.add_parser("info", help="version and build profile")
    args = parser.parse_args(argv)
    for signum in (signal.SIGTERM, signal.SIGHUP):  # a batch scheduler's stop, as a Ctrl-C
        if signal.getsignal(signum) is signal.SIG_DFL and threading.current_thread() is threading.main_thread():
            signal.signal(signum, raise_terminated)
    try:
        if args.command == "validate":
            return _validate(args)
        if args.command == "run":
            return _run(args, r)
        if args.command == "sweep":
            return _sweep(args)
        if args.command == "keys":
            print(describe(), end="")
            return 0
        if args.command == "animate":
            if not Path(args.dir).is_dir():
                raise ParameterError(f"invalid parameter `dir` = {args.dir!r}: no such folder; allowed a run's folder")
            _plot_backend()
            lock_output_dir(args.dir, "dir", command_line())
            try:
                path = make_animation(Path(args.dir))
            finally:
                release_output_dir(args.dir)
            if path is None:
                raise ParameterError(
                    f"invalid parameter `dir` = {args.dir!r}: allowed a folder with fields.nc or fields.pvd"
                )
            print(path)
            return 0
        print(json.dumps(build_info() | {"python_package": __version__}))
        return 0
    except (ParameterError, NotImplementedError) as err:
        print(f"granrs: {type(err).__name__}: {err}", file=sys.stderr)
        return 2
    except (SimulationError, SolverError) as err:
        newline = chr(10) if args.command == "run" and not args.quiet else ""
        print(f"{newline}granrs: {type(err).__name__}: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as err:
        return _interrupted(None, False, err)


if __name__ == "__main__":
    sys.exit(main())
