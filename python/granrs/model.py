"""The model: materials, boundary conditions and numerics on a grid; it takes one step at a time.

Field arrays (``u``, ``v``, ``p``, ``phi``) are zero-copy, read-only NumPy views of the Rust
state, indexed ``[j, i]`` (rows along y). They stay live: after a step they show the new values.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Callable, Optional, Union

import numpy as np

from . import _granrs
from ._granrs import ParameterError
from .boundary import BoundaryConditions
from .grid import Grid
from .materials import Material

HALO = _granrs.build_info()["halo"]
ArrayOrFn = Union[np.ndarray, Callable[[np.ndarray, np.ndarray], np.ndarray], float]


@dataclass(frozen=True)
class PorePressure:
    """The pore gas pressure equation ∂_t p_f + div(u p_f) = div(κ ∇p_f) (paper eq. 10f).

    diffusivity: κ_f in the granular phase [m² s⁻¹] (the paper: 0.035);
    formulation: 'granular-only' (solve where Φ > 0, p_f = 0 on the interface; default),
    'kappa-infinity' (whole domain, κ = kappa_air in the air, sharp sub-cell interface) or
    'kappa-infinity-smoothed' (the paper's literal κ(Φ) = κ_f H_ε + κ_∞(1 − H_ε), whose p_f = 0
    boundary sits about ε inside the grains);
    basal_gradient: ∂p_f/∂y on the base [Pa/m] between basal_x_min and basal_x_max (the air
    supply under the reservoir, −β φ ρ_s g in the paper); None for no supply.
    """

    diffusivity: float
    formulation: str = "granular-only"
    kappa_air: float = 1e16
    basal_gradient: Optional[float] = None
    basal_x_min: Optional[float] = None
    basal_x_max: Optional[float] = None

    def __post_init__(self):
        if self.formulation not in ("granular-only", "kappa-infinity", "kappa-infinity-smoothed"):
            raise ParameterError(f"invalid parameter `formulation` = {self.formulation!r}: allowed 'granular-only', "
                                 "'kappa-infinity' or 'kappa-infinity-smoothed'")
        if not (isinstance(self.diffusivity, (int, float)) and math.isfinite(self.diffusivity) and self.diffusivity > 0):
            raise ParameterError(f"invalid parameter `diffusivity` = {self.diffusivity!r}: allowed a finite number > 0 (m²/s)")


@dataclass(frozen=True)
class Numerics:
    """Numerical settings (defaults suit the paper's cases).

    cfl: CFL number of the adaptive step; dt: a fixed step instead (s); max_dt: cap on the step;
    max_growth: largest δt_n/δt_{n−1}; cfl_abort: the run stops with an error above this CFL
    number; viscous: 'implicit' or 'explicit'; pressure_solver: 'multigrid-cg' or 'direct';
    pressure_rtol: relative residual of the pressure solve; interface_width: ε/h of the smoothed
    Heaviside; redistance_every: level-set redistancing frequency in steps (0: never);
    transport_interface: False freezes the interface; mass_correction: shift Φ by a constant after
    each interface update so that the dense-phase area keeps its initial value (off by default;
    docs/validation.md compares both).
    """

    cfl: float = 0.5
    dt: Optional[float] = None
    max_dt: float = math.inf
    max_growth: float = 1.2
    cfl_abort: float = 1.0
    viscous: str = "implicit"
    pressure_solver: str = "multigrid-cg"
    pressure_rtol: float = 1e-8
    pressure_max_iterations: int = 200
    interface_width: float = 1.5
    redistance_every: int = 10
    transport_interface: bool = True
    mass_correction: bool = False


class Model:
    """A two-phase (or single-phase) incompressible model on a MAC grid.

    ``dense`` is the material where Φ > 0 (the only one if ``light`` is None); ``light`` where
    Φ < 0. ``gravity`` is (g_x, g_y) in m s⁻². ``threads`` sets the size of the Rust thread pool.
    """

    def __init__(self, grid: Grid, dense: Material, light: Optional[Material] = None,
                 bc: Optional[BoundaryConditions] = None, gravity=(0.0, 0.0),
                 numerics: Optional[Numerics] = None, threads: int = 1,
                 pore_pressure: Optional[PorePressure] = None):
        if not isinstance(grid, Grid):
            raise ParameterError(f"invalid parameter `grid` = {grid!r}: allowed a granrs.Grid")
        if not isinstance(dense, Material):
            raise ParameterError(f"invalid parameter `dense` = {dense!r}: allowed a granrs.Material")
        if light is not None and not isinstance(light, Material):
            raise ParameterError(f"invalid parameter `light` = {light!r}: allowed a granrs.Material or None")
        if not isinstance(threads, int) or isinstance(threads, bool) or not 1 <= threads <= 1024:
            raise ParameterError(f"invalid parameter `threads` = {threads!r}: allowed an integer in [1, 1024]")
        self.grid = grid
        self.dense = dense
        self.light = light
        self.bc = bc if bc is not None else BoundaryConditions()
        self.gravity = tuple(float(g) for g in gravity)
        self.numerics = numerics if numerics is not None else Numerics()
        if pore_pressure is not None and not isinstance(pore_pressure, PorePressure):
            raise ParameterError(f"invalid parameter `pore_pressure` = {pore_pressure!r}: allowed a granrs.PorePressure or None")
        self.pore_pressure = pore_pressure
        n = self.numerics
        self._rust = _granrs.RustModel(
            grid.nx, grid.ny, float(grid.lx), float(grid.ly), self.bc.spec(),
            (dense.density, dense.viscosity),
            None if light is None else (light.density, light.viscosity),
            self.gravity, n.interface_width, n.transport_interface, n.redistance_every, n.viscous,
            n.cfl, n.dt, n.max_dt, n.max_growth, n.cfl_abort, n.pressure_solver, n.pressure_rtol,
            n.pressure_max_iterations, threads,
            None if pore_pressure is None else asdict(pore_pressure), n.mass_correction)
        self.threads = threads
        names = ("u", "v", "p", "phi") + (("pf",) if pore_pressure is not None else ())
        self._views = {name: self._view(name) for name in names}

    def _view(self, name: str) -> np.ndarray:
        full = self._rust.field_storage(name)
        full.flags.writeable = False
        view = full[HALO:-HALO, HALO:-HALO]
        view.flags.writeable = False
        return view

    # ---- fields -------------------------------------------------------------------------
    @property
    def u(self) -> np.ndarray:
        """x-velocity on vertical faces, shape (ny, nx + 1), read-only live view."""
        return self._views["u"]

    @property
    def v(self) -> np.ndarray:
        """y-velocity on horizontal faces, shape (ny + 1, nx), read-only live view."""
        return self._views["v"]

    @property
    def p(self) -> np.ndarray:
        """Pressure at cell centres, shape (ny, nx), read-only live view."""
        return self._views["p"]

    @property
    def phi(self) -> np.ndarray:
        """Level set at cell centres (> 0 in the dense phase), shape (ny, nx), read-only live view."""
        return self._views["phi"]

    @property
    def pf(self) -> np.ndarray:
        """Pore gas pressure at cell centres, shape (ny, nx), read-only live view (fluidised models only)."""
        if "pf" not in self._views:
            raise ParameterError("invalid parameter `pf`: allowed only for a model with pore_pressure (this one is not fluidised)")
        return self._views["pf"]

    def set_initial(self, u: ArrayOrFn = None, v: ArrayOrFn = None, p: ArrayOrFn = None,
                    phi: ArrayOrFn = None, pf: ArrayOrFn = None, balance_pressure: bool = True) -> None:
        """Sets initial fields from arrays, constants or functions f(x, y) evaluated at the
        field's points. With ``balance_pressure`` (and no explicit ``p``), p is set so that the
        body force is balanced (one pressure solve)."""
        points = {"u": self.grid.xfaces, "v": self.grid.yfaces, "p": self.grid.centres, "phi": self.grid.centres,
                  "pf": self.grid.centres}
        for name, value in (("phi", phi), ("pf", pf), ("u", u), ("v", v), ("p", p)):
            if value is None:
                continue
            x, y = points[name]()
            if callable(value):
                arr = np.asarray(value(x, y), dtype=float)
            else:
                arr = np.asarray(value, dtype=float)
                if arr.ndim == 0:
                    arr = np.full(x.shape, float(arr))
            self._rust.set_field(name, np.ascontiguousarray(arr))
        if p is None and balance_pressure:
            self._rust.initialise_pressure()

    def set_shape(self, shape, balance_pressure: bool = True) -> None:
        """Sets Φ to the exact signed distance of a :mod:`granrs.shapes` shape (Φ > 0 inside)."""
        from .shapes import Shape

        if not isinstance(shape, Shape):
            raise ParameterError(f"invalid parameter `shape` = {shape!r}: allowed a granrs.shapes shape")
        self._rust.set_shape(shape.spec())
        if balance_pressure:
            self._rust.initialise_pressure()

    def dense_area(self) -> float:
        """Area of the dense phase {Φ > 0} (sub-cell accurate), m²."""
        return self._rust.dense_area()

    # ---- stepping -----------------------------------------------------------------------
    def step(self) -> dict:
        """Takes one step (GIL released); returns its diagnostics."""
        return self._rust.step()

    def advance(self, t_end: Optional[float] = None, max_steps: Optional[int] = None) -> dict:
        """Steps until ``t_end`` (landing on it exactly) or ``max_steps``; returns per-step
        diagnostics as lists (time, dt, max_speed, cfl, divergence, pressure_iterations,
        viscous_iterations)."""
        return self._rust.advance(t_end, max_steps)

    @property
    def time(self) -> float:
        return self._rust.time

    @property
    def step_count(self) -> int:
        return self._rust.step_count

    def last_step(self) -> dict:
        return self._rust.last_step()

    # ---- derived quantities -------------------------------------------------------------
    def centre_velocity(self) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) averaged to cell centres, each (ny, nx)."""
        return 0.5 * (self.u[:, 1:] + self.u[:, :-1]), 0.5 * (self.v[1:, :] + self.v[:-1, :])

    def streamfunction(self) -> np.ndarray:
        """ψ at nodes, shape (ny + 1, nx + 1), with u = ∂ψ/∂y, ψ = 0 on the bottom wall:
        ψ(x_i, y_j) = Σ_{k<j} u(x_i, y_{k+½}) dy (exact for the discretely divergence-free field)."""
        psi = np.zeros((self.grid.ny + 1, self.grid.nx + 1))
        psi[1:, :] = np.cumsum(self.u, axis=0) * self.grid.dy
        return psi

    def summary(self) -> dict:
        return {
            "grid": {"nx": self.grid.nx, "ny": self.grid.ny, "lx": self.grid.lx, "ly": self.grid.ly},
            "dense": asdict(self.dense), "light": None if self.light is None else asdict(self.light),
            "bc": {k: v[0] for k, v in self.bc.spec().items()}, "gravity": list(self.gravity),
            "numerics": asdict(self.numerics), "threads": self.threads,
            "pore_pressure": None if self.pore_pressure is None else asdict(self.pore_pressure),
        }

    def __repr__(self) -> str:
        phases = f"dense {self.dense}" + ("" if self.light is None else f", light {self.light}")
        return (f"Model on {self.grid}\n  {phases}\n  {self.bc}\n  gravity {self.gravity}, threads {self.threads}\n"
                f"  t = {self.time:.6g} s after {self.step_count} steps")
