"""summary.json's entries derived from the records: arrest, energy budget, fluidisation and the
observables (``granrs.observables``) of the records and of the final deposit."""

from __future__ import annotations

from typing import Optional

import numpy as np

from ... import observables as obs
from ...simulation import Terminated
from .case import RestCriterion

#: How summary.json's ``stop_reason`` begins for a run that did not end: written during the run
#: (killed, or still running), stopped by Ctrl-C, or stopped by a failure.
INCOMPLETE, INTERRUPTED, ERROR = "incomplete", "interrupted", "error"
#: The start of the ``stop_reason`` of a run stopped by SIGTERM or SIGHUP ("terminated by SIGTERM").
TERMINATED = "terminated by"
UNFINISHED_REASONS = (INCOMPLETE, INTERRUPTED, ERROR, TERMINATED)


def failure_stop_reason(failure: BaseException, message: str) -> str:
    """summary.json's ``stop_reason`` for a run that ``failure`` stopped: ``interrupted:
    KeyboardInterrupt`` for a Ctrl-C, ``terminated by SIGTERM`` (or SIGHUP) for a
    ``Terminated``, ``error: <message>`` otherwise."""
    if isinstance(failure, Terminated):
        return str(failure)  # "terminated by SIGTERM"
    if isinstance(failure, KeyboardInterrupt):
        return f"{INTERRUPTED}: {type(failure).__name__}"
    return f"{ERROR}: {message}"


class RestWatch:
    """A run's records against its :class:`RestCriterion` (the package's docstring): give it each
    record with :meth:`update`; ``since`` is the start of the current quiet window (None while the
    grains move faster)."""

    def __init__(self, criterion: RestCriterion):
        self.criterion = criterion
        self.since: Optional[float] = None

    def update(self, t: float, speed: float) -> bool:
        """Takes the record at time ``t``; True once the quiet window has lasted ``criterion.duration``."""
        c = self.criterion
        if t > c.after and speed < c.speed:
            if self.since is None:
                self.since = t
            return t - self.since >= c.duration
        self.since = None
        return False


def arrest_summary(t, front, speed, stop_reason: str, rest_since: Optional[float]) -> dict:
    """summary.json's arrest entries from the records (times ``t``, fronts ``front`` from the
    gate, largest granular speeds ``speed``): ``arrest_time_s`` (``rest_since``, the start of the
    window of rest that stopped the run, when ``stop_reason`` is ``"rest"``; else None), the time
    ``max_front_time_s`` of the largest front (``max_front_m``), ``front_retreat_m`` (the largest
    front minus the last one, ≥ 0) and ``final_granular_speed_m_s``."""
    front = np.asarray(front, dtype=float)
    if front.size == 0:
        return {
            "arrest_time_s": None,
            "max_front_time_s": None,
            "front_retreat_m": 0.0,
            "final_granular_speed_m_s": None,
        }
    k = int(np.argmax(front))
    return {
        "arrest_time_s": float(rest_since) if stop_reason == "rest" and rest_since is not None else None,
        "max_front_time_s": float(t[k]),
        "front_retreat_m": float(front[k] - front[-1]),
        "final_granular_speed_m_s": float(speed[-1]),
    }


ENERGY_COLUMNS = (
    "kinetic",
    "potential_drop",
    "gravity_work",
    "plastic_work",
    "plastic_negative_work",
    "viscous_work",
    "wall_work",
    "side_wall_work",
    "residual",
)


def _energy_row(b: dict) -> dict:
    """One row of energy.csv from ``Model.energy_budget()`` (J per metre of width)."""
    return {
        "kinetic": b["kinetic"],
        "potential_drop": b["potential_initial"] - b["potential"],
        "gravity_work": b["gravity_work"],
        "plastic_work": b["plastic_work"],
        "plastic_negative_work": b["plastic_negative_work"],
        "viscous_work": b["viscous_work"],
        "wall_work": sum(b["wall_work"].values()),
        "side_wall_work": b["side_wall_work"],
        "residual": b["residual"],
    }


def energy_summary(b: dict) -> dict:
    """Where gravity's work went by the end of the run, as fractions of it (they add up to 1):
    kinetic energy left, plastic, basal and back-wall friction, the channel's side walls (0 without
    them), viscous, and ``numerical`` (−
    the residual: what the discretisation dissipated); ``plastic_negative`` is the stress given
    back to the flow (≤ 0; zero for the paper's eq. 11, docs/validation.md)."""
    row = _energy_row(b)
    wg = row["gravity_work"]
    if not wg > 0:
        return {"gravity_work_J_per_m": wg}
    return {
        "gravity_work_J_per_m": wg,
        "potential_drop_J_per_m": row["potential_drop"],
        "kinetic": row["kinetic"] / wg,
        "plastic": row["plastic_work"] / wg,
        "wall": row["wall_work"] / wg,
        "side_walls": row["side_wall_work"] / wg,
        "viscous": row["viscous_work"] / wg,
        "numerical": -row["residual"] / wg,
        "plastic_negative": row["plastic_negative_work"] / wg,
    }


def fluidisation_summary(t: list, reservoir: list, channel: list, threshold: float = 0.1) -> dict:
    """summary.json["fluidisation"]: the basal pore-pressure ratio (``basal_pore_pressure_ratio``)
    under the reservoir and in the channel: its largest value in the channel, the last time the
    channel's ratio was at or above ``threshold`` (after which the material that left the
    reservoir slides as a dry material), and both ratios at the end."""
    ch = np.nan_to_num(np.asarray(channel, dtype=float), nan=0.0)
    above = np.nonzero(ch >= threshold)[0]
    return {
        "reservoir_max": float(np.nanmax(reservoir)),
        "reservoir_final": float(reservoir[-1]),
        "channel_max": float(ch.max()),
        "channel_final": float(ch[-1]),
        "threshold": threshold,
        "channel_fluidised_until_s": float(t[above[-1]]) if above.size else 0.0,
    }


def _record_observables(rec: dict, h: np.ndarray, dx: float, cell: float, x_gate: float) -> None:
    """Appends the observables of the profile h (granrs.observables, distances from the gate; fronts
    in cells of size ``cell``) to the record lists of ``rec`` (front.csv's columns)."""
    for k, v in obs.observe_profile(h, dx, cell, x_gate).items():
        rec.setdefault(k, []).append(v)


def _observables_summary(
    rec: dict, h_final: np.ndarray, dx: float, cell: float, x_gate: float, definition: str = obs.PROFILE_DEFINITION
) -> dict:
    """summary.json["observables"]: those of the final volume profile (profiles.csv's hvol_final),
    the centre of mass's travel since the first record, the fronts' largest values over the
    records, the thicknesses in cells in metres and the profile's definition."""
    final = obs.observe_profile(h_final, dx, cell, x_gate)
    keys = obs.observable_keys()
    initial = {k: rec[k][0] for k in keys} if rec.get(keys[0]) else final
    out = obs.summarise(final, initial, {k: rec[k] for k in keys if k in rec}, definition)
    out["cell_m"] = cell
    out["distances_from"] = "the gate, x = L_c"
    return out
