"""Runs a resolved run-file configuration: the case, its field outputs, animation and checkpoints.

    cfg = granrs.config.load_config("examples/paper_fluidised.toml", sets=["time.t_end=0.1"])
    summary = run_config(cfg)          # what ``granrs run FILE.toml`` does

Everything is checked before anything is written (``preflight``): the configuration, the
optional dependencies, the memory the model needs, the restart file and its configuration, and
the output folder (``granrs.io.outputs``: a new or empty folder; an existing run's folder only
with ``overwrite``, or by a restart from that folder's own checkpoint, which appends to its run).
A refused run changes nothing on disk. Outputs go to ``output.dir``: config.resolved.toml (a
restart appending to its run adds config.restart-NNNNNN.toml, NNNNNN its first step), the case's
summary.json / front.csv / profiles.csv / history.npz / plots, fields.pvd + fields/*.vti and/or
fields.nc, animation.gif, checkpoint.npz. summary.json, front.csv and history.npz are rewritten
atomically during the run. A run that fails (SimulationError, SolverError, OutputError) or is
interrupted (KeyboardInterrupt) keeps every file written so far and its summary.json says why it
stopped (``stop_reason``); the exception is then raised again.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Optional

import numpy as np

from ._granrs import ParameterError, SimulationError, SolverError
from .cases.column import run_column
from .cases.column.build import build_model
from .cases.column.run import check_case
from .config import Config, column_case, dumps, full_key_message, resolve, tomllib, write_config
from .io import checkpoint as ckpt
from .io.animation import make_animation
from .io.netcdf import available as netcdf_available
from .io.outputs import (
    OutputError,
    RunOutputs,
    check_path_text,
    commit_output_dir,
    plan_output_dir,
    read_columns,
    record,
    release_output_dir,
    resume_outputs,
)
from .io.provenance import header_lines, provenance
from .io.vtk import read_pvd
from .io.writer import FieldWriter
from .simulation import Callback


def _named(err: ParameterError, source: Optional[str]) -> ParameterError:
    """The error of a configuration's key with its run-file key (`numerics.pressure_update`) and
    the run file (``source``) named."""
    text = full_key_message(str(err))
    if source is not None and not text.startswith(f"{source}: "):
        text = f"{source}: {text}"
    return ParameterError(text)


def preflight(cfg: Config, restart: Optional[str] = None, allow_changes: bool = False, source: Optional[str] = None):
    """Checks that need more than the schema: optional dependencies, the model's options and the
    rules between them (``check_case``, without allocating), the restart file (readable, finite,
    after t_end, same configuration unless ``allow_changes``, a state this configuration's model
    can take). Returns the loaded ``Checkpoint`` (None without a restart). ``source``: the run
    file, named with the keys in the errors."""
    out = cfg["output"]
    if "netcdf" in out["formats"] and out["fields_every_s"] > 0 and not netcdf_available():
        raise _named(
            ParameterError(
                "invalid parameter `output.formats` item 'netcdf': needs the optional dependency netCDF4 "
                "(pip install 'granrs[io]')"
            ),
            source,
        )
    try:
        case = column_case(cfg)
    except ParameterError as err:
        raise _named(err, source) from None
    # the depth-averaged model writes no fields: output.* away from their defaults are refused
    # with it (config.refuse_unused_keys), their defaults ignored
    saves = case.model != "depth-averaged" and (
        bool(out["fields_every_s"] > 0 and out["formats"]) or out["checkpoint_every_s"] > 0
    )
    try:
        check_case(case, field_output=saves, restart=restart is not None)
    except ParameterError as err:
        raise _named(err, source) from None
    if restart is None:
        return None
    check_path_text("--restart", restart)
    ck = ckpt.load_checkpoint(restart)
    meta = ck.meta
    if meta["time"] >= cfg["time"]["t_end"]:
        raise _named(
            ParameterError(
                f"invalid parameter `time.t_end` = {cfg['time']['t_end']!r}: allowed a time "
                f"after the checkpoint's t = {meta['time']!r} s"
            ),
            source,
        )
    grid = case.grid()
    want = meta["grid"]
    if (
        (grid.nx, grid.ny) != (want["nx"], want["ny"])
        or abs(grid.lx - want["lx"]) > 1e-12 * want["lx"]
        or abs(grid.ly - want["ly"]) > 1e-12 * want["ly"]
    ):
        raise ParameterError(
            f"invalid parameter `--restart` = {str(restart)!r}: the checkpoint's grid {want['nx']} x "
            f"{want['ny']} cells on {want['lx']:g} m x {want['ly']:g} m differs from this "
            f"configuration's {grid.nx} x {grid.ny} on {grid.lx:g} m x {grid.ly:g} m; allowed a "
            "checkpoint of the same grid"
        )
    changes = configuration_changes(ck, cfg)
    if changes and not allow_changes:
        raise ParameterError(
            f"invalid parameter `--restart` = {str(restart)!r}: the configuration differs from the "
            f"checkpoint's in {'; '.join(changes)}; allowed the same configuration (except "
            f"{', '.join(RESTART_FREE_KEYS)} and output.*), or --allow-changes to restart with "
            "these changes"
        )
    if changes:  # the state must fit this configuration's model: restored into it, in memory only
        try:
            ckpt.restore_checkpoint(build_model(case), ck)
        except ParameterError as err:
            raise ParameterError(
                f"invalid parameter `--allow-changes` with --restart {str(restart)!r}: the checkpoint's "
                f"state does not fit the changed configuration ({'; '.join(changes)}): "
                f"{str(err).removeprefix('invalid checkpoint `object`: ')}; allowed "
                "changes that keep the model's state (not fluidised <-> dry, not the active region <-> "
                "the whole domain, not the model)"
            ) from None
    return ck


def _read_front(path: Path) -> None:
    if "t_s" not in read_columns(path):
        raise ValueError("no column t_s")


def _read_history(path: Path) -> None:
    with np.load(path) as z:
        if "time" not in z.files:
            raise ValueError("no entry time")
        for k in z.files:  # every entry read: a truncated one fails here
            z[k]


def _read_fields_nc(path: Path) -> None:
    try:
        import netCDF4  # deferred: optional dependency (the io extra)
    except ImportError:
        return  # not readable here, not known to be damaged: FieldWriter refuses NetCDF without it
    with netCDF4.Dataset(path) as ds:
        ds["time"][:]


def check_run_files(out: Path, restart) -> None:
    """A restart that appends to the run in ``out`` reads its front.csv, history.npz, fields.pvd
    and fields.nc: each one there must be readable, or the restart is refused naming it."""
    for name, read in (
        ("front.csv", _read_front),
        ("history.npz", _read_history),
        ("fields.pvd", read_pvd),
        ("fields.nc", _read_fields_nc),
    ):
        if not (out / name).exists():
            continue
        try:
            read(out / name)
        except Exception as err:  # noqa: BLE001 - zipfile, zlib, EOF, XML, CSV, HDF5: all "cannot be read"
            raise ParameterError(
                f"invalid parameter `--restart` = {str(restart)!r}: the run's {out / name} cannot be read "
                f"({type(err).__name__}: {str(err)[:200]}), so the restart cannot append to it; nothing was "
                f"changed; allowed a run folder whose files are whole (move {name} away: the restart then "
                "writes it again from the restart time), or a restart into another --out"
            ) from None


#: Bytes per cell of one snapshot: a .vti holds phi, p, pf (8 bytes each), the velocity (3 x 8)
#: and the yielded mask (1), base64-encoded (4/3); fields.nc at most the 6 fields uncompressed.
_VTI_BYTES_PER_CELL = (3 * 8 + 3 * 8 + 1) * 4 / 3
_NC_BYTES_PER_CELL = 6 * 8


def output_volume(cfg: Config) -> tuple[int, int]:
    """(snapshots, bytes): the field snapshots a run writes up to t_end and their size."""
    out = cfg["output"]
    if not (out["fields_every_s"] > 0 and out["formats"]) or cfg["case"]["model"] == "depth-averaged":
        return 0, 0
    grid = column_case(cfg).grid()
    n = int(cfg["time"]["t_end"] / out["fields_every_s"]) + 1
    per = ("vtk" in out["formats"]) * _VTI_BYTES_PER_CELL + ("netcdf" in out["formats"]) * _NC_BYTES_PER_CELL
    return n, int(n * per * grid.cells)


def check_output_volume(cfg: Config, plan, source: Optional[str] = None, total: Optional[dict] = None) -> None:
    """Refuses a run whose snapshots (``output_volume``) need more than the free space of the
    file system of its folder, naming both. ``total``: a dict that sums the volumes of several
    runs into one folder (a sweep's members), each checked with those before it."""
    n, size = output_volume(cfg)
    if total is not None:
        total["snapshots"] = total.get("snapshots", 0) + n
        total["bytes"] = total.get("bytes", 0) + size
        n, size = total["snapshots"], total["bytes"]
    if not size:
        return
    ancestor = Path(os.path.abspath(plan.path))
    while not ancestor.exists():
        ancestor = ancestor.parent
    st = os.statvfs(ancestor)
    free = st.f_bavail * st.f_frsize
    if size > free:
        every = cfg["output"]["fields_every_s"]
        raise _named(
            ParameterError(
                f"invalid parameter `output.fields_every_s` = {every!r}: the run would write about "
                f"{size / 1e9:.3g} GB of field snapshots ({n} up to t_end = {cfg['time']['t_end']:g} s, about "
                f"{size / n / 1e6:.3g} MB each), more than the {free / 1e9:.3g} GB free on the file system of "
                f"{str(ancestor)!r}; allowed a larger output.fields_every_s (at least "
                f"{every * size / free:.3g} s), fewer output.formats or a folder on a larger disk"
            ),
            source,
        )


#: Keys that may differ between a checkpoint's configuration and its restart's without
#: ``allow_changes`` (they change neither the state nor the equations).
RESTART_FREE_KEYS = ("time.t_end", "numerics.threads")


def configuration_changes(ck: ckpt.Checkpoint, cfg: dict) -> list[str]:
    """The keys (``section.key: old -> new``) whose value in ``cfg`` differs from the configuration
    the checkpoint was written with (its provenance); output.* and RESTART_FREE_KEYS are not
    compared. Empty when the checkpoint holds no configuration."""
    text = (ck.meta.get("provenance") or {}).get("configuration") or ""
    if not text:
        return []
    try:
        old = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return ["(the checkpoint's configuration cannot be read)"]
    try:  # with its defaults: the sections of an object that is off are not written
        old = resolve(old)
    except ParameterError:
        pass  # compared as written
    changes = []
    for section, table in cfg.items():
        if section == "output" or not isinstance(table, dict):
            continue
        for key, value in table.items():
            name = f"{section}.{key}"
            before = old.get(section, {}).get(key)
            if name not in RESTART_FREE_KEYS and before != value:
                changes.append(f"{name}: {before!r} -> {value!r}")
    return changes


def _own_run(out: Path, restart) -> bool:
    """Whether ``restart`` is the checkpoint of the run in ``out`` (a restart appends to it)."""
    try:
        return Path(restart).resolve().parent == out.resolve() and (out / "summary.json").exists()
    except OSError:
        return False


def run_config(
    cfg: Config,
    *,
    command: Optional[str] = None,
    progress: bool = True,
    restart: Optional[str] = None,
    extra_callbacks: Optional[list] = None,
    overwrite: bool = False,
    allow_changes: bool = False,
    out_name: str = "output.dir",
    source: Optional[str] = None,
) -> dict:
    """Runs the configuration (validated again here) and returns the case's summary dict.

    ``command``: the command line recorded in the provenance (default: this process's);
    ``restart``: a checkpoint file to start from; ``extra_callbacks``: more ``Callback``s;
    ``overwrite``: replace the outputs of a run already in output.dir; ``allow_changes``: restart
    with a configuration that differs from the checkpoint's; ``out_name``: the parameter the
    output folder's errors name (``--out`` on the command line); ``source``: the run file the
    configuration came from, which the errors of its keys name."""
    cfg = resolve(cfg)
    ck = preflight(cfg, restart, allow_changes, source=source)
    case = column_case(cfg)
    out_cfg = cfg["output"]
    out = Path(out_cfg["dir"])
    append = restart is not None and _own_run(out, restart)
    plan = plan_output_dir(out, overwrite=overwrite, append=append, name=out_name)
    if append:
        check_run_files(out, restart)
    check_output_volume(cfg, plan, source)
    # ---- every check has passed: from here on the run writes
    commit_output_dir(plan, command)
    for note in plan.notes:
        print(f"granrs: {note}", file=sys.stderr)
    try:
        return _run(cfg, case, ck, plan, command, progress, restart, extra_callbacks)
    finally:
        release_output_dir(out)


def _run(cfg: Config, case, ck, plan, command, progress: bool, restart, extra_callbacks) -> dict:
    out_cfg = cfg["output"]
    out = plan.path
    prov = provenance(dumps(cfg), command)
    t_start = ck.meta["time"] if ck is not None else None
    name = f"config.restart-{ck.meta['step_count']:06d}.toml" if plan.mode == "append" else "config.resolved.toml"
    record(out / name)
    write_config(cfg, out / name, header_lines(prov))
    front_prefix = history_prefix = None
    if plan.mode == "append":
        assert t_start is not None  # an append continues the run of a checkpoint
        front_prefix, history_prefix = resume_outputs(out, t_start)
    outputs = RunOutputs(
        out,
        front_prefix,
        history_prefix,
        start_area=float(np.ravel(ck.state["reference_area"])[0])
        if ck is not None and "reference_area" in ck.state
        else None,
    )

    callbacks = list(extra_callbacks or [])
    writer = None
    if out_cfg["fields_every_s"] > 0 and out_cfg["formats"] and case.model != "depth-averaged":  # no 2D fields
        writer = FieldWriter(
            out, case.grid(), out_cfg["formats"], prov, append_after=t_start if plan.mode == "append" else None
        )
        callbacks.append(Callback(writer, every_time=out_cfg["fields_every_s"]))
    if out_cfg["checkpoint_every_s"] > 0:
        callbacks.append(
            Callback(
                lambda sim: ckpt.save_checkpoint(sim.model, out / "checkpoint.npz", prov),
                every_time=out_cfg["checkpoint_every_s"],
                saves_state=True,
            )
        )
    prepare = (lambda model: ckpt.restore_checkpoint(model, ck)) if ck is not None else None
    extra = {
        "provenance": {k: v for k, v in prov.items() if k != "configuration"},
        "config": cfg,
        "restart_from": str(restart) if restart is not None else None,
        "fields": {"formats": list(out_cfg["formats"]) if writer else [], "every_s": out_cfg["fields_every_s"]},
    }
    if ck is not None:
        whole = plan.mode == "append" and front_prefix is not None and history_prefix is not None
        extra["restart"] = {
            "checkpoint": str(restart),
            "t_start_s": t_start,
            "step_start": ck.meta["step_count"],
            "front_and_history_from": "the run's start (appended to this folder's run)"
            if whole
            else f"the restart at t = {t_start:g} s",
            "mass_rel_error_from": "the run's start (the checkpoint's reference area)",
            "energy_from": f"the restart at t = {t_start:g} s (the budget starts again from a restored state)",
            "configuration_changes": configuration_changes(ck, cfg),
        }
    try:
        summary = run_column(
            case, out, progress=progress, callbacks=callbacks, extra_summary=extra, prepare=prepare, outputs=outputs
        )
    except (SimulationError, SolverError):
        _animate(out_cfg, out, writer)  # the failure is data: animate what was saved
        raise
    _animate(out_cfg, out, writer)
    return summary


def _animate(out_cfg: dict, out: Path, writer) -> None:
    if out_cfg["animation"] and writer is not None and writer.frames > 0:
        try:
            make_animation(out)
        except OSError as err:
            raise OutputError(
                f"cannot write {out / 'animation.gif'} ({err.strerror or err}); the files written before "
                f"are kept in {out}"
            ) from None
