"""The column with the depth-averaged model (``granrs.depth_averaged``): the model built from a
:class:`ColumnCase` and its run, with the same records, rest criterion, outputs and plots as the
2D models, and the refusal of the run-file keys the model does not read
(:func:`refuse_unused_keys`; a case's fields: ``DepthAveraged.refuse_unused``): a case, a run
file or a command line that sets anything the depth-averaged model does not read is refused
before any work, naming the parameter and the models that read it."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ..._granrs import ParameterError, SimulationError, __version__
from ...depth_averaged import ANGLE_READERS, DepthAveragedModel, DepthAveragedPore, unused_error
from .case import PAPER_RUNOUT_EXP, PAPER_RUNOUT_SIM, ColumnCase, G
from .measures import basal_pore_pressure_ratio, deposit_quantile
from .outputs import write_outputs
from .plots import plot_front, plot_profiles
from .summaries import RestWatch, _observables_summary, _record_observables, arrest_summary, failure_stop_reason


def depth_averaged_front_depth(case: ColumnCase) -> float:
    """Depth at which the depth-averaged front is read: half a cell of the two-phase grid of the
    same case (ny). The two-phase front is the zero of Φ on the lowest row of cells, which sees a
    layer only once it is thicker than dy/2; reading the depth-averaged front at the same depth
    compares like with like (the front at a vanishing depth is reported as runout_thin_m)."""
    return 0.5 * case.domain()[1] / case.ny


#: The run-file keys the depth-averaged model reads (every other key given with
#: case.model = 'depth-averaged' is refused; ``depth_averaged.*`` with another model too).
USED_KEYS = frozenset(
    {
        "case.name",
        "case.model",
        "geometry.aspect_ratio",
        "geometry.width",
        "geometry.length",
        "fluidisation.fluidised",
        "fluidisation.pore_pressure_ratio",
        "grid.ny",
        "rheology.friction_angle",
        "base.friction_angle",
        "pore_pressure.diffusivity",
        "time.t_end",
        "rest.speed",
        "rest.duration",
        "rest.after",
        "depth_averaged.closure",
        "depth_averaged.resolution",
        "depth_averaged.pore_transport",
        "output.dir",
    }
)


def refuse_unused_keys(cfg: dict, given) -> None:
    """ParameterError for the first run-file key in ``given`` ((section, key) pairs the file or the
    command line set) that the case's model does not read: with case.model = 'depth-averaged'
    every key outside :data:`USED_KEYS` (and rheology.friction_angle with the closure
    'hydrostatic'), with the 2D models every ``depth_averaged.*`` key."""
    model = cfg["case"]["model"]
    for section, key in sorted(given):
        name, value = f"{section}.{key}", cfg.get(section, {}).get(key)
        if model == "depth-averaged" and name not in USED_KEYS:
            raise unused_error(name, value)
        if model == "depth-averaged" and name == "rheology.friction_angle":
            if cfg["depth_averaged"]["closure"] == "hydrostatic":
                raise unused_error(name, value, ANGLE_READERS)
        if model != "depth-averaged" and section == "depth_averaged":
            raise ParameterError(
                f"invalid parameter `{name}` = {value!r} with case.model = {model!r}: read only by the "
                "depth-averaged model; allowed only with case.model = 'depth-averaged'"
            )


def build_depth_averaged(case: ColumnCase):
    """The depth-averaged model of the column (same channel length as the two-phase domain,
    Δx = min(L_c, H_c)/``case.depth_averaged.resolution``, basal friction α_b of ``case.base``,
    the pore pressure of ``case.depth_averaged.pore_transport`` with the basal supply β_s under
    the reservoir when fluidised, the lateral-pressure closure ``case.depth_averaged.closure``)
    with its initial condition: h = H_c, β = β_s for x < L_c (p_f = β_s ρ g (H_c − z), the 2D
    model's)."""
    case.validate()
    da = case.depth_averaged
    hc, lc = case.column_height, case.geometry.width
    length = case.domain()[0]
    cells = int(math.ceil(length / (min(lc, hc) / da.resolution)))
    fluidised, beta = case.fluidisation.active, case.fluidisation.pore_pressure_ratio
    pore = (
        DepthAveragedPore(case.pore_pressure.diffusivity, beta, lc, transport=da.pore_transport) if fluidised else None
    )
    m = DepthAveragedModel(
        cells,
        length,
        gravity=G,
        basal_friction_angle=case.base.friction_angle or 0.0,
        cfl=0.4,
        dry_depth=1e-6 * hc,
        pore=pore,
        **da.earth_pressure(lambda: case.internal_friction_angle),
    )
    inside = m.x < lc
    m.set_state(h=np.where(inside, hc, 0.0), beta=np.where(inside, beta if fluidised else 0.0, 0.0))
    return m


def run_column_depth_averaged(
    case: ColumnCase,
    out: str | Path,
    progress: bool = True,
    compare_with: Optional[Path] = None,
    extra_summary: Optional[dict] = None,
    reason: str = "requested",
) -> dict:
    """The column with the depth-averaged model: same records, rest criterion, outputs and plots
    as :func:`run_column` (front read at :func:`depth_averaged_front_depth`)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    m = build_depth_averaged(case)
    lc, hc = case.geometry.width, case.column_height
    threshold = depth_averaged_front_depth(case)
    mass0 = m.mass()
    rec: dict[str, list] = {"t": [], "front": [], "area": [], "max_granular_speed": []}
    # fluidisation: the pore pressure over the weight, under the reservoir and in the channel,
    # Σ p_f / Σ ρ g h as the 2D runs record it (measures.basal_pore_pressure_ratio), with p_f read
    # where the 2D runs read it, on their lowest row of cells, half a cell (the front's depth)
    # above the base: p_b (1 − threshold/h)⁺ with the linear profile of the pore pressure
    fluid = m.pore is not None
    under_reservoir = m.x < lc
    if fluid:
        rec["pf_ratio_reservoir"], rec["pf_ratio_channel"] = [], []
    profiles: dict = {}
    pending = sorted(case.profile_times)
    rest = RestWatch(case.rest)
    stop_reason = "t_end"
    error = None
    t0 = time.perf_counter()
    try:
        k = 0
        while True:
            t = m.time
            xf = m.front(threshold)
            if xf > m.length - 3 * m.dx or float(np.sum(m.h[-3:])) * m.dx > 0.01 * mass0:
                raise SimulationError(
                    f"the granular material reached the far end of the domain (x = {xf:.3f} m of "
                    f"{m.length:.3f} m) at t = {t:.3f} s: increase --length (geometry.length in a run file)"
                )
            speed = m.max_speed()
            rec["t"].append(t)
            rec["front"].append(xf - lc)
            rec["area"].append(m.mass())
            rec["max_granular_speed"].append(speed)
            _record_observables(rec, m.h, m.dx, 2 * threshold, lc)
            if fluid:
                wet = np.where(m.h >= m.config["dry_depth"], m.h, 0.0)
                pb = m.beta * np.maximum(wet - threshold, 0.0)  # p_f / (ρ g) at the 2D lowest row
                rec["pf_ratio_reservoir"].append(basal_pore_pressure_ratio(pb, wet, 1.0, under_reservoir))
                rec["pf_ratio_channel"].append(basal_pore_pressure_ratio(pb, wet, 1.0, ~under_reservoir))
            while pending and t >= pending[0] - 1e-9:
                profiles[round(pending.pop(0), 6)] = m.h.copy()
            if rest.update(t, speed):
                stop_reason = "rest"
                break
            if t >= case.t_end - 1e-12:
                break
            k += 1
            m.advance(min(case.t_end, 0.01 * k))
            if progress:
                print(f"\rdepth-averaged: t = {m.time:.2f} s, front {xf - lc:.3f} m", end="", flush=True)
    except (SimulationError, KeyboardInterrupt) as err:
        error = err
        stop_reason = failure_stop_reason(err, str(err))
    if progress:
        print()
    wall = time.perf_counter() - t0
    profiles["final"] = m.h.copy()
    front = np.array(rec["front"])
    area = np.array(rec["area"])
    summary: dict[str, Any] = {
        "runout_m": float(front[-1]) if front.size else 0.0,
        "max_front_m": float(front.max()) if front.size else 0.0,
        "runout_thin_m": m.front(1e-3 * hc) - lc,
        "farthest_material_m": m.front(1e-6 * hc) - lc,
        "runout_q99_m": deposit_quantile(profiles["final"], m.dx, lc),
        "front_depth_m": threshold,
        "t_end_s": m.time,
        "steps": m.step_count,
        "nx": m.cells,
        "ny": case.ny,
        "cells": m.cells,
        "h_m": m.dx,
        "wall_s": wall,
        "mass_rel_error": float(np.max(np.abs(area - mass0)) / mass0) if area.size else 0.0,
        "fluidised": m.pore is not None,
        "rheology": "Coulomb basal friction (depth-averaged)",
        "threads": 1,
        "version": __version__,
        "stop_reason": stop_reason,
        "paper_runout_simulation_m": PAPER_RUNOUT_SIM,
        "paper_runout_experiment_m": PAPER_RUNOUT_EXP,
        "model": "depth-averaged",
        "model_reason": reason,
        "case": case.summary(),
    }
    summary.update(arrest_summary(rec["t"], front, rec["max_granular_speed"], stop_reason, rest.since))
    summary["observables"] = _observables_summary(rec, profiles["final"], m.dx, threshold * 2, lc)
    summary["observables"]["profile_definition"] = "h(x), the depth-averaged layer's thickness"
    profiles["hvol_final"] = profiles["final"]
    summary.update(extra_summary or {})
    write_outputs(out, summary, rec, profiles, m.x - lc)
    plot_front(out, compare_with)
    plot_profiles(out)
    if isinstance(error, KeyboardInterrupt):
        raise error
    if error is not None:
        raise SimulationError(f"{error} (outputs written to {out})") from error
    return summary
