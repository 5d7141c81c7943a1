"""Depth-averaged (shallow-layer, Savage–Hutter type) model of a granular layer along a channel.

Equations (Savage & Hutter 1989; pore pressure after Gueugneau, Kelfoun, Roche & Chupin 2017),
on a horizontal channel 0 < x < L with reflective walls at both ends::

    h_t + (h u)_x = 0
    (h u)_t + (h u² + ½ k g h²)_x = − k g h b_x − g h tan(α_b) (1 − β)⁺ sign(u)
    (h β)_t + (h β u)_x = − h β / t_d,   t_d = 4 h² / (π² κ),   β ≥ β_s under the air supply

β = p_b/(ρ g h) is the basal pore-pressure ratio. k is a constant (``earth_pressure``, 1 by
default) or, with ``internal_friction_angle`` = φ, Savage & Hutter's active coefficient
k_act = 2 sec²φ_e (1 − √(1 − cos²φ_e sec²δ_e)) − 1 per cell, tan φ_e = (1 − β) tan φ,
tan δ_e = (1 − β) tan α_b. Numerics (MUSCL–minmod, hydrostatic
reconstruction, HLL, SSP-RK2, friction as a projection that can stop a cell but never reverse it)
and the model's limits are in ``rust/granrs-core/src/models/depth_averaged.rs`` and
``docs/models.md``. The time loop runs in Rust with the GIL released.

    m = DepthAveragedModel(cells=400, length=2.0, basal_friction_angle=15.0)
    m.set_state(h=np.where(m.x < 0.2, 0.4, 0.0))
    m.advance(1.0)
    m.h, m.u, m.beta   # read-only live views, shape (cells,)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ._granrs import ParameterError, RustDepthAveraged

#: The defaults of the model's optional parameters: the Rust core's (``DepthAveragedConfig::new``).
_DEFAULTS = RustDepthAveraged.defaults()


@dataclass(frozen=True)
class DepthAveragedPore:
    """Pore pressure of the depth-averaged model: diffusivity κ (m² s⁻¹), supply ratio β_s and the
    extent 0 < x < ``supply_x_max`` of the basal air supply (the reservoir; 0: no supply)."""

    diffusivity: float
    supply_ratio: float
    supply_x_max: float = 0.0


class DepthAveragedModel:
    """The depth-averaged model (see the module docstring): ``cells`` over a channel of ``length``
    [m], ``gravity`` [m s⁻²], a constant ``earth_pressure`` coefficient k (or, with
    ``internal_friction_angle`` φ in degrees, Savage & Hutter's active one per cell), the
    ``basal_friction_angle`` α_b [degrees], the ``cfl`` number (≤ 0.5), the wet/dry threshold
    ``dry_depth`` [m] and the largest step ``max_dt`` [s]; defaults are the Rust core's.
    ``pore=None``: not fluidised, β ≡ 0 and no pore pressure is solved. ``config`` holds the
    configuration object given to the Rust model; every value is checked in Rust."""

    def __init__(
        self,
        cells: int,
        length: float,
        gravity: float = _DEFAULTS["gravity"],
        earth_pressure: float = _DEFAULTS["earth_pressure"],
        basal_friction_angle: float = _DEFAULTS["basal_friction_angle"],
        cfl: float = _DEFAULTS["cfl"],
        dry_depth: float = _DEFAULTS["dry_depth"],
        max_dt: float = _DEFAULTS["max_dt"],
        pore: Optional[DepthAveragedPore] = None,
        internal_friction_angle: Optional[float] = None,
    ) -> None:
        if pore is not None and not isinstance(pore, DepthAveragedPore):
            raise ParameterError(f"invalid parameter `pore` = {pore!r}: allowed a granrs.DepthAveragedPore or None")
        self.config = {
            "cells": cells,
            "length": length,
            "gravity": gravity,
            "earth_pressure": earth_pressure,
            "basal_friction_angle": basal_friction_angle,
            "cfl": cfl,
            "dry_depth": dry_depth,
            "max_dt": max_dt,
            "pore": None if pore is None else dataclasses.asdict(pore),
            "internal_friction_angle": internal_friction_angle,
        }
        self._rust = RustDepthAveraged(self.config)
        self.pore = pore
        n, _, dx, ghosts = self._rust.grid
        self.cells, self.length, self.dx = n, length, dx
        self.x = (np.arange(n) + 0.5) * dx
        self.x.flags.writeable = False
        self._views = {}
        for name in ("h", "u", "beta", "bed"):
            full = self._rust.field_storage(name)
            full.flags.writeable = False
            view = full[ghosts:-ghosts]
            view.flags.writeable = False
            self._views[name] = view

    @property
    def h(self) -> np.ndarray:
        """Depth h (m) at cell centres, read-only live view."""
        return self._views["h"]

    @property
    def u(self) -> np.ndarray:
        """Depth-averaged velocity u (m/s), read-only live view (0 where h < dry_depth)."""
        return self._views["u"]

    @property
    def beta(self) -> np.ndarray:
        """Basal pore-pressure ratio β = p_b/(ρ g h), read-only live view (0 when not fluidised)."""
        return self._views["beta"]

    @property
    def bed(self) -> np.ndarray:
        """Bed elevation b (m), read-only live view."""
        return self._views["bed"]

    def set_state(self, h, u=None, beta=None) -> None:
        """Sets h, u (default 0) and β (default 0): arrays of shape (cells,) or scalars."""
        n = self.cells

        def arr(v, default=0.0):
            return np.ascontiguousarray(np.broadcast_to(np.asarray(default if v is None else v, dtype=float), (n,)))

        self._rust.set_state(arr(h), arr(u), arr(beta))

    def set_bed(self, bed) -> None:
        """Sets the bed elevation b (shape (cells,))."""
        self._rust.set_bed(np.ascontiguousarray(np.broadcast_to(np.asarray(bed, dtype=float), (self.cells,))))

    def step(self) -> float:
        """One step; returns Δt."""
        return self._rust.step()

    def advance(self, t_end: float, max_steps: Optional[int] = None) -> int:
        """Steps until ``t_end`` (landing on it) or ``max_steps``; returns the steps taken."""
        return self._rust.advance(t_end, max_steps)

    def mass(self) -> float:
        """Σ h Δx (m², per unit width)."""
        return self._rust.mass()

    def earth_pressure(self) -> np.ndarray:
        """Earth-pressure coefficient k of each cell (a copy)."""
        return self._rust.earth_pressure()

    def max_speed(self) -> float:
        return self._rust.max_speed()

    def front(self, threshold: float) -> float:
        """x (m) where h first falls to ``threshold``, walking from the wall at x = 0."""
        return self._rust.front(threshold)

    @property
    def time(self) -> float:
        return self._rust.time

    @property
    def step_count(self) -> int:
        return self._rust.step_count
