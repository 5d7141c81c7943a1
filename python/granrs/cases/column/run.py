"""The run of the column (:func:`run_column`): the model built, the records taken every 0.01 s
with the rest criterion, the outputs flushed during the run and written at its end (the
package's docstring describes the criterion and the records)."""

from __future__ import annotations

import builtins
import json
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ... import observables as obs, options
from ..._granrs import ParameterError, SimulationError, SolverError, __version__
from ...io.outputs import OutputError, RunOutputs, record
from ...model import Model
from ...simulation import Callback, Simulation, deferred_interrupt
from .build import build_model, model_arguments
from .case import PAPER_RUNOUT_EXP, PAPER_RUNOUT_SIM, ColumnCase, G
from .depth_averaged import run_column_depth_averaged
from .measures import (
    basal_pore_pressure_ratio,
    deposit_quantile,
    farthest_material,
    front_position,
    granular_speed,
    surface_profile,
)
from .outputs import _progress, write_energy, write_outputs
from .plots import plot_energy, plot_fluidisation, plot_front, plot_profiles
from .summaries import (
    UNFINISHED_REASONS,
    RestWatch,
    _observables_summary,
    _record_observables,
    arrest_summary,
    energy_summary,
    failure_stop_reason,
    fluidisation_summary,
)

#: run_column rewrites summary.json, front.csv and history.npz every this many records (0.1 s)
FLUSH_RECORDS = 10


def whole_records(rec: dict[str, list]) -> None:
    """Cuts every record list of ``rec`` to the shortest one's length, in place. A Ctrl-C can land
    inside the observer, between the appends of one record; front.csv then holds whole records
    only (its columns are the lists of the records' length)."""
    n = min((len(v) for v in rec.values()), default=0)
    for v in rec.values():
        del v[n:]


def check_case(case: ColumnCase, field_output: bool = False, restart: bool = False) -> None:
    """Every check of the case before any work, without allocating its model: the case's fields
    (``ColumnCase.validate``: ranges, memory), the 2D model's options and every rule between them
    (``Model.check``, in Rust), and what the depth-averaged model cannot do (``field_output``:
    snapshots or checkpoints asked for; ``restart``: a restart asked for)."""
    case.validate()
    if case.model == "depth-averaged":
        if field_output or restart:
            raise ParameterError(
                "invalid parameter `model` = 'depth-averaged' with field output, checkpoints or a "
                "restart: allowed only with the 2D models ('two-phase', 'granular')"
            )
        for name, value in (("side_walls", case.side_walls), ("active_region", case.active_region)):
            if value is not None:
                raise ParameterError(
                    f"invalid parameter `{name}` with the depth-averaged model: allowed only with the "
                    "2D models ('two-phase', 'granular')"
                )
        return
    Model.check(**model_arguments(case))


def run_column(
    case: ColumnCase,
    out: str | Path,
    progress: bool = True,
    compare_with: Optional[str | Path] = None,
    callbacks: Optional[list] = None,
    extra_summary: Optional[dict] = None,
    prepare=None,
    outputs: Optional[RunOutputs] = None,
) -> dict:
    """Runs the case, writes summary.json, front.csv, profiles.csv, front.png and profiles.png into ``out``.

    ``callbacks``: more ``Callback``s for the Simulation (field output, checkpoints);
    ``extra_summary``: entries added to summary.json; ``prepare(model)``: called once the model
    is built (a restart restores its state there); ``outputs``: the folder's ``RunOutputs`` (a
    restart's earlier rows and original dense area). summary.json, front.csv and history.npz are
    rewritten atomically every ``FLUSH_RECORDS`` records during the run (``stop_reason``
    'incomplete: ...') and before every callback that ``saves_state``. A SimulationError,
    SolverError or KeyboardInterrupt still writes every output from the steps done, with the
    ``stop_reason``, then is raised again."""
    check_case(case, field_output=bool(callbacks), restart=prepare is not None)
    out = Path(out)
    compare_with = None if compare_with is None else Path(compare_with)
    model_name, model_reason = case.model, "requested"
    if model_name == "depth-averaged":
        for name in ("front.png", "profiles.png"):  # its other files are recorded as they are written
            record(out / name)
        return run_column_depth_averaged(
            case, out, progress=progress, compare_with=compare_with, extra_summary=extra_summary, reason=model_reason
        )
    out.mkdir(parents=True, exist_ok=True)
    model = build_model(case)
    if prepare is not None:
        prepare(model)
    grid = model.grid
    lc = case.geometry.width
    outputs = outputs if outputs is not None else RunOutputs(out)
    area0 = outputs.start_area or model.dense_area()
    # the conserved volume Σ F dx dy (interface_transport = "clsvof"): its largest relative change
    volume0 = model.dense_volume()
    volume_change = [0.0]
    rec: dict[str, list] = {"t": [], "front": [], "area": [], "max_granular_speed": [], "energy": []}
    # fluidisation: the basal pore pressure over the weight, under the reservoir and in the channel
    fluid = model.pore_pressure is not None
    xs_c = (np.arange(grid.nx) + 0.5) * grid.dx
    under_reservoir = xs_c < lc
    if fluid:
        rec["pf_ratio_reservoir"], rec["pf_ratio_channel"] = [], []
    profiles: dict = {}
    rest = RestWatch(case.rest)
    last_flush = (0, -1)  # (records, steps) written by the last flush
    pending_profiles = sorted(case.profile_times)

    def observe(sim: Simulation) -> None:
        t = model.time
        xf = front_position(model.phi, grid.dx)
        xfar = farthest_material(model.phi, grid.dx)
        # "reached the far end": the front, or more than 1 % of the column's area within the last
        # three columns of cells (single-cell specks of thin films sliding ahead do not count)
        far_area = float(np.count_nonzero(model.phi[:, -3:] > 0)) * grid.dx * grid.dy
        if xf > grid.lx - 3 * grid.dx or far_area > 0.01 * area0:
            raise SimulationError(
                f"the granular material reached the far end of the domain (x = {xfar:.3f} m of "
                f"{grid.lx:.3f} m) at t = {t:.3f} s: increase --length (geometry.length in a run file)"
            )
        speed = granular_speed(model)
        rec["t"].append(t)
        rec["front"].append(xf - lc)
        rec["area"].append(model.dense_area())
        volume = model.dense_volume()
        if volume0 and volume is not None:
            volume_change[0] = max(volume_change[0], abs(volume / volume0 - 1.0))
        rec["max_granular_speed"].append(speed)
        rec["energy"].append(model.energy_budget())
        _record_observables(rec, obs.model_volume_profile(model), grid.dx, grid.dy, lc)
        if fluid:
            h, pf0, weight = surface_profile(model.phi, grid.dy), model.pf[0], case.mixture_density * G
            rec["pf_ratio_reservoir"].append(basal_pore_pressure_ratio(pf0, h, weight, under_reservoir))
            rec["pf_ratio_channel"].append(basal_pore_pressure_ratio(pf0, h, weight, ~under_reservoir))
        while pending_profiles and t >= pending_profiles[0] - 1e-9:
            profiles[round(pending_profiles.pop(0), 6)] = surface_profile(model.phi, grid.dy)
        if rest.update(t, speed):
            sim.stop, sim.stop_reason = True, "rest"
        if len(rec["t"]) % FLUSH_RECORDS == 0:
            flush(sim)

    def flush(sim: Simulation) -> None:
        nonlocal last_flush
        front, done = rec["front"], (len(rec["t"]), model.step_count)
        if not front or last_flush == done:  # nothing new since the last flush
            return
        last_flush = done
        _progress(
            outputs,
            {
                "runout_m": front[-1],
                "max_front_m": max(front),
                "t_end_s": model.time,
                "steps": model.step_count,
                "nx": grid.nx,
                "ny": grid.ny,
                "model": model_name,
                "case": case.summary(),
            }
            | (extra_summary or {}),
            rec,
            sim.history_arrays(),
            model.time,
            model.step_count,
        )

    sim = Simulation(
        model,
        stop_time=case.t_end,
        callbacks=[Callback(observe, every_time=0.01)] + list(callbacks or []),
        progress=progress,
    )
    sim.flush_outputs = flush  # a checkpoint never runs ahead of front.csv and history.npz
    t0 = time.perf_counter()
    error = failure = None
    try:
        sim.run()
    except (SimulationError, SolverError, KeyboardInterrupt) as err:  # keep what was computed, then report
        failure = err
        error = str(err) if not isinstance(err, KeyboardInterrupt) else "KeyboardInterrupt"
    wall = time.perf_counter() - t0
    whole_records(rec)
    profiles["final"] = surface_profile(model.phi, grid.dy)
    profiles["hvol_final"] = obs.model_volume_profile(model)
    history = sim.history_arrays()
    # the statistics below: a run that failed at its first step has the history's keys, no values
    hist = {k: v for k, v in history.items() if v.size}
    front = np.array(rec["front"])
    area = np.array(rec["area"])
    walls, region = case.side_walls, case.active_region
    opts = options.merge(case.numerics, case.objects())  # the options in force, each from its object
    summary: dict[str, Any] = {
        "runout_m": float(front[-1]) if front.size else 0.0,
        "max_front_m": float(front.max()) if front.size else 0.0,
        "runout_q99_m": deposit_quantile(profiles["final"], grid.dx, lc),
        "farthest_material_m": farthest_material(model.phi, grid.dx) - lc,
        "t_end_s": model.time,
        "steps": model.step_count,
        "nx": grid.nx,
        "ny": grid.ny,
        "cells": grid.cells,
        "h_m": grid.dy,
        "wall_s": wall,
        "mass_rel_error": float(np.max(np.abs(area - area0)) / area0) if area.size else 0.0,
        **({"volume_rel_error": volume_change[0]} if volume0 else {}),
        "fluidised": case.fluidisation.active,
        "rheology": case.rheology.spec()[0],
        "interface_yield": opts["interface_yield"],
        "wall_normal_stress": opts["wall_normal_stress"],
        "yield_pressure": opts["yield_pressure"],
        "sigma_location": opts["sigma_location"],
        "channel_width_m": None if walls is None else walls.width,
        "side_wall_friction_angle": None if walls is None else walls.friction_angle,
        "r_neighbourhood": opts["r_neighbourhood"],
        "active_region": None if region is None else region.band,
        "active_region_sides": None if region is None else region.sides,
        "threads": case.threads,
        "version": __version__,
        "stop_reason": sim.stop_reason if failure is None else failure_stop_reason(failure, str(error)),
        "pressure_iterations_median": float(np.median(hist["pressure_iterations"])) if "time" in hist else 0.0,
        "pressure_iterations_max": int(np.max(hist["pressure_iterations"])) if "time" in hist else 0,
        "viscous_iterations_median": float(np.median(hist["viscous_iterations"])) if "time" in hist else 0.0,
        "dt_median_s": float(np.median(hist["dt"])) if "time" in hist else 0.0,
        "paper_runout_simulation_m": PAPER_RUNOUT_SIM,
        "paper_runout_experiment_m": PAPER_RUNOUT_EXP,
        "model": model_name,
        "model_reason": model_reason,
        "case": case.summary(),
    }
    summary.update(arrest_summary(rec["t"], front, rec["max_granular_speed"], summary["stop_reason"], rest.since))
    if "solver" in opts and "picard_iterations" in hist:
        # the bi-projection's solver and its iterations per accepted step (Picard iterations, or
        # the exact step's sparse factorisations); with the exact step, the largest residual of
        # eq. (11) it accepted (each below bi_projection.newton_tol)
        its = hist["picard_iterations"]
        summary["bi_projection_solver"] = opts["solver"]
        summary["bi_projection_iterations"] = {
            "median": float(np.median(its)),
            "p90": float(np.percentile(its, 90)),
            "max": int(np.max(its)),
        }
        if opts["solver"] == "newton":
            summary["eq11_residual_max"] = float(np.max(hist["picard_increment"]))
    if "picard_r_halvings" in hist:
        summary["picard_r_halvings_total"] = int(np.sum(hist["picard_r_halvings"]))
    cap = opts["proximal_restarts"]
    if "picard_restarts" in hist and cap > 0:
        # steps whose Picard loop used every proximal restart it was allowed: they end on the
        # relaxed fixed point of their last anchor, not on eq. (11)'s
        summary["picard_restarts_capped_steps"] = int(np.sum(hist["picard_restarts"] >= cap))
    if "step_retries" in hist:
        summary["step_retries_total"] = int(np.sum(hist["step_retries"]))
    if "pieces_removed" in hist:
        summary["pieces_removed_total"] = int(np.sum(hist["pieces_removed"]))
    if rec["energy"]:
        summary["energy"] = energy_summary(rec["energy"][-1])
    summary["observables"] = _observables_summary(
        rec, profiles["hvol_final"], grid.dx, grid.dy, lc, obs.model_profile_definition(model)
    )
    if fluid and rec["t"]:
        summary["fluidisation"] = fluidisation_summary(rec["t"], rec["pf_ratio_reservoir"], rec["pf_ratio_channel"])
    summary.update(extra_summary or {})
    names = ("front.png", "profiles.png") + (("energy.csv", "energy.png") if rec["energy"] else ())
    for name in names + (("fluidisation.png",) if fluid and rec["t"] else ()):
        record(out / name)  # the plots and energy.csv, written without granrs.io.outputs
    try:
        write_outputs(out, summary, rec, profiles, xs_c - lc, outputs)
        outputs.write_history(history)
        if rec["energy"]:
            write_energy(out, rec["t"], rec["energy"])
            plot_energy(out)
        if fluid and rec["t"]:
            plot_fluidisation(out)
        plot_front(out, compare_with)
        plot_profiles(out)
    except OSError as err:  # a full disk: the files written before stay complete
        raise OutputError(
            f"cannot write the outputs in {out} ({err.strerror or err}); the files written before are kept"
            + (f"; the run had stopped with: {error}" if error else "")
        ) from None
    if isinstance(failure, KeyboardInterrupt):
        for cb in callbacks or []:  # a checkpoint of the state reached, where checkpoints are on
            if cb.saves_state:
                with deferred_interrupt():
                    cb.func(sim)
        raise failure
    if error is not None:
        kind = type(failure) if isinstance(failure, (SolverError, OutputError)) else SimulationError
        raise kind(error + f" (outputs written to {out})") from failure
    return summary


def run_finished(out) -> bool:
    """Whether the folder ``out`` holds a column run that ended: its summary.json can be read and
    its ``stop_reason`` is not one of :data:`UNFINISHED_REASONS` (a run that reached ``t_end`` or
    came to rest). A folder without summary.json, with one that cannot be read, or with the
    summary of a run that was killed, interrupted or failed is not finished: a study that
    resumes runs it again."""
    try:
        summary = json.loads((Path(out) / "summary.json").read_text())
    except (OSError, ValueError):
        return False
    reason = summary.get("stop_reason") if isinstance(summary, dict) else None
    return isinstance(reason, str) and not reason.startswith(UNFINISHED_REASONS)


def run_columns(runs: list, jobs: int = 1, progress: bool = False) -> list[dict]:
    """Runs several cases, ``runs`` = [(ColumnCase, output folder), ...], with :func:`run_column`,
    and returns their summaries in the same order.

    ``jobs`` = 1 runs them one after the other in this process; ``jobs`` > 1 runs that many at a
    time, each in a process of its own (``spawn``), with the thread count of its case. A run's
    answer does not depend on the process that runs it, and on a machine with free cores several
    runs side by side finish sooner than one after the other on more threads each below the
    paper's grid (docs/howto/threads.md). Every case is validated before any run starts. When a run
    fails, the runs already started finish and keep their outputs, and the first failure is raised
    again, its message naming its folder; one after the other, the runs after it do not start.
    Side by side, the workers import the calling script again: a script that calls it needs
    ``if __name__ == "__main__":``. ``progress``: each run's progress line, one after the other
    only."""
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ParameterError(f"invalid parameter `jobs` = {jobs!r}: allowed an integer >= 1")
    runs = [(case, Path(out)) for case, out in runs]
    for case, _ in runs:
        case.validate()
    if jobs == 1 or len(runs) < 2:
        return [run_column(case, out, progress=progress) for case, out in runs]
    ctx = multiprocessing.get_context("spawn")
    summaries: list[dict] = []
    first_error: Optional[Exception] = None
    with ProcessPoolExecutor(max_workers=min(jobs, len(runs)), mp_context=ctx) as pool:
        futures = [pool.submit(_run_in_child, case, out) for case, out in runs]
        for (_, out), fut in zip(runs, futures):
            try:
                kind, value = fut.result()
            except BrokenProcessPool as e:
                raise SimulationError(
                    f"the process running the case writing into {out} died before it finished: killed "
                    "for its memory, or the script that calls run_columns with jobs > 1 cannot be "
                    'imported again by its workers (it needs `if __name__ == "__main__":`)'
                ) from e
            if kind == "summary":
                summaries.append(value)
                continue
            first_error = first_error or _rebuilt_error(value, out)
    if first_error is not None:
        raise first_error
    return summaries


def _run_in_child(case: ColumnCase, out: Path) -> tuple[str, Any]:
    """:func:`run_column` in a worker process of :func:`run_columns`: ("summary", the summary),
    or ("error", (class name, message)) for an exception (the extension's exception classes
    do not pickle across processes)."""
    try:
        return "summary", run_column(case, out, progress=False)
    except Exception as e:
        return "error", (type(e).__name__, str(e))


def _rebuilt_error(value: tuple[str, str], out: Path) -> Exception:
    """The exception a worker of :func:`run_columns` reported for the run writing into ``out``:
    granrs's own classes (SimulationError, SolverError, ParameterError, OutputError) and the
    built-in ones by name, RuntimeError for any other, with the worker's message, which names the
    folder."""
    name, message = value
    if str(out) not in message:  # run_column's own errors name the folder already
        message += f" (the run writing into {out})"
    own = {c.__name__: c for c in (SimulationError, SolverError, ParameterError, OutputError)}
    cls = own.get(name) or getattr(builtins, name, None)
    if not (isinstance(cls, type) and issubclass(cls, Exception)):
        return RuntimeError(f"{name}: {message}")
    return cls(message)
