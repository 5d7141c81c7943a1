"""Runs a resolved run-file configuration: the case, its field outputs, animation and checkpoints.

    cfg = granrs.config.load_config("examples/paper_fluidised.toml", sets=["numerics.t_end=0.1"])
    summary = run_config(cfg)          # what ``granrs run FILE.toml`` does

Everything that can be checked is checked before the first step (optional dependencies,
checkpoint support, the restart file). Outputs go to ``output.dir``: config.resolved.toml,
the case's summary.json / front.csv / profiles.csv / history.npz / plots, fields.pvd +
fields/*.vti and/or fields.nc, animation.gif, checkpoint.npz. A run that fails (SimulationError,
SolverError) or is interrupted (KeyboardInterrupt) keeps every file written so far and its
summary.json says why it stopped (``stop_reason``); the exception is then raised again.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from ._granrs import ParameterError, SimulationError, SolverError
from .cases.column import run_column
from .config import Config, column_case, dumps, resolve, write_config
from .io import checkpoint as ckpt
from .io.netcdf import available as netcdf_available
from .io.provenance import header_lines, provenance
from .simulation import Callback


def preflight(cfg: Config, restart: Optional[str] = None) -> None:
    """Checks that need more than the schema: optional dependencies, the restart file."""
    out = cfg["output"]
    if "netcdf" in out["formats"] and out["fields_every_s"] > 0 and not netcdf_available():
        raise ParameterError("invalid parameter `output.formats` item 'netcdf': needs the optional dependency netCDF4 "
                             "(pip install 'granrs[io]')")
    if restart is not None:
        meta = ckpt.load_checkpoint(restart).meta
        if meta["time"] >= cfg["numerics"]["t_end"]:
            raise ParameterError(f"invalid parameter `numerics.t_end` = {cfg['numerics']['t_end']!r}: allowed a time "
                                 f"after the checkpoint's t = {meta['time']!r} s")


def run_config(cfg: Config, *, command: Optional[str] = None, progress: bool = True, restart: Optional[str] = None,
               extra_callbacks: Optional[list] = None) -> dict:
    """Runs the configuration (validated again here) and returns the case's summary dict.

    ``command``: the command line recorded in the provenance (default: this process's);
    ``restart``: a checkpoint file to start from; ``extra_callbacks``: more ``Callback``s."""
    cfg = resolve(cfg)
    preflight(cfg, restart)
    case = column_case(cfg)
    case.validate()
    out_cfg = cfg["output"]
    out = Path(out_cfg["dir"])
    out.mkdir(parents=True, exist_ok=True)
    prov = provenance(dumps(cfg), command)
    write_config(cfg, out / "config.resolved.toml", header_lines(prov))

    callbacks = list(extra_callbacks or [])
    writer = None
    if out_cfg["fields_every_s"] > 0 and out_cfg["formats"]:
        from .io.writer import FieldWriter

        writer = FieldWriter(out, case.grid(), out_cfg["formats"], prov)
        callbacks.append(Callback(writer, every_time=out_cfg["fields_every_s"]))
    if out_cfg["checkpoint_every_s"] > 0:
        callbacks.append(Callback(lambda sim: ckpt.save_checkpoint(sim.model, out / "checkpoint.npz", prov),
                                  every_time=out_cfg["checkpoint_every_s"]))
    prepare = (lambda model: ckpt.restore_checkpoint(model, restart)) if restart is not None else None
    extra = {"provenance": {k: v for k, v in prov.items() if k != "configuration"}, "config": cfg,
             "restart_from": str(restart) if restart is not None else None,
             "fields": {"formats": list(out_cfg["formats"]) if writer else [], "every_s": out_cfg["fields_every_s"]}}
    try:
        summary = run_column(case, out, progress=progress, callbacks=callbacks, extra_summary=extra, prepare=prepare)
    except (SimulationError, SolverError):
        _animate(out_cfg, out, writer)  # the failure is data: animate what was saved
        raise
    _animate(out_cfg, out, writer)
    return summary


def _animate(out_cfg: dict, out: Path, writer) -> None:
    if out_cfg["animation"] and writer is not None and writer.frames > 0:
        from .io.animation import make_animation

        make_animation(out)
