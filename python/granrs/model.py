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
from .boundary import BoundaryConditions, Coulomb
from .grid import Grid
from .materials import Material
from .rheology import RHEOLOGIES, Bingham, DruckerPrager, MuI, Newtonian

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
    supply under the reservoir, −β φ ρ_s g in the paper); None for no supply;
    time_scheme: 'implicit' (BDF2 with implicit diffusion, second order, no step limit from the
    diffusion; default) or 'explicit' (forward Euler, first order, stable only for
    δt ≤ h²/(4κ) = 1/(2κ(1/dx² + 1/dy²)); 'granular-only' only). An explicit run past its limit
    stops with a SimulationError naming the pore pressure, the cell and the limit.
    """

    diffusivity: float
    formulation: str = "granular-only"
    kappa_air: float = 1e16
    basal_gradient: Optional[float] = None
    basal_x_min: Optional[float] = None
    basal_x_max: Optional[float] = None
    time_scheme: str = "implicit"

    def __post_init__(self):
        if self.time_scheme not in ("implicit", "explicit"):
            raise ParameterError(f"invalid parameter `time_scheme` = {self.time_scheme!r}: allowed 'implicit' or 'explicit'")
        if self.time_scheme == "explicit" and self.formulation != "granular-only":
            raise ParameterError(f"invalid parameter `time_scheme` = 'explicit' with formulation {self.formulation!r}: "
                                 "allowed only with 'granular-only' (kappa_air in the air makes the explicit limit "
                                 "h²/(4κ) vanish)")
        if self.formulation not in ("granular-only", "kappa-infinity", "kappa-infinity-smoothed"):
            raise ParameterError(f"invalid parameter `formulation` = {self.formulation!r}: allowed 'granular-only', "
                                 "'kappa-infinity' or 'kappa-infinity-smoothed'")
        if not (isinstance(self.diffusivity, (int, float)) and math.isfinite(self.diffusivity) and self.diffusivity > 0):
            raise ParameterError(f"invalid parameter `diffusivity` = {self.diffusivity!r}: allowed a finite number > 0 (m²/s)")


@dataclass(frozen=True)
class SideWalls:
    """Friction of a channel's two vertical side walls on the 2D flow (not in the paper's model;
    Jop, Forterre & Pouliquen 2005, J. Fluid Mech. 541): the body force −(2/W) tan(α_w) p⁺ H_ε(Φ) s,
    s = u/|u| where the granular phase slides, |s| ≤ 1 where it sticks (a projection solved in
    the Picard loop with Σ; Rust walls/side.rs).

    width: the channel width W [m] (the paper's experiment: 0.10), in (0, 1000];
    friction_angle: α_w [degrees], in [0, 90).
    """

    width: float
    friction_angle: float

    def __post_init__(self):
        check_side_walls(self.width, self.friction_angle, "side_walls.width", "side_walls.friction_angle")


def check_side_walls(width, friction_angle, width_name: str, angle_name: str) -> None:
    """The ranges of a channel's side walls (Rust `SideWalls` checks the same): a width in
    (0, 1000] m and an angle in [0, 90) degrees; the errors name the caller's parameters."""
    def number(v) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    if not number(width) or not 0 < width <= 1000:
        raise ParameterError(f"invalid parameter `{width_name}` = {width!r}: allowed a channel width in (0, 1000] (m)")
    if not number(friction_angle) or not 0 <= friction_angle < 90:
        raise ParameterError(f"invalid parameter `{angle_name}` = {friction_angle!r}: allowed an angle in degrees in [0, 90)")


# ---- memory ------------------------------------------------------------------------------------
# Arrays of one float64 per cell (centre, face or node: all ~nx·ny) the core allocates, counted in
# rust/granrs-core/src: the two-phase state u, v, their previous values and convection terms, p,
# Φ (8) and the step's work arrays (13, models/two_phase.rs); the pressure projection (5,
# projection/mod.rs) and its shifted system (5, solvers/mod.rs), CG (5, solvers/cg.rs) and
# multigrid hierarchy (5 per level, 4/3 of the fine level, plus 2 × 1/3 of coarse vectors:
# solvers/level.rs, multigrid.rs); the momentum solver (10, time_stepping/momentum.rs); the level
# set's transport (2) and redistancing (11, levelset/); a yield stress or Coulomb wall adds the
# plastic stage (15, rheology/stage.rs) and tensor (17, rheology/plastic.rs); the pore pressure
# its fields (4) and a shifted system like the projection's (17.4); the granular-only model a
# second projection (18.4); side walls 6; step retries a copy of the state (8 + 1 + 3 + 2); the
# Simulation's copy of the last good state as many again.
_ARRAYS = {"base": 21.0, "projection": 22.4, "momentum": 10.0, "levelset": 13.0, "plastic": 32.0, "pore": 21.4,
           "free_surface": 18.4, "side_walls": 6.0, "state": 14.0}
#: the estimate is the counted arrays times this margin. Measured (2-core x86-64 VM, 2026-12-01,
#: the column case at 8544 x 96 cells, build and two steps, resident memory from /proc/self/statm):
#: 777 MB fluidised, 589 MB dry; peak 847 and 642 MB. The count gives 980 and 838 MB (1.16 and
#: 1.30 times the peak: some work arrays are smaller than a cell field), so no margin is added.
MEMORY_MARGIN = 1.0


def estimate_memory(grid: Grid, *, plastic: bool = True, pore_pressure: bool = False, air: str = "resolved",
                    side_walls: bool = False, step_retries: int = 3, pressure_solver: str = "multigrid-cg") -> int:
    """Bytes the core allocates for a model on ``grid`` with these options (see ``_ARRAYS``),
    times ``MEMORY_MARGIN``; the direct pressure solver adds its Cholesky factor (8 bytes ×
    cells × min(nx, ny), the band of a grid's natural ordering)."""
    count = _ARRAYS["base"] + _ARRAYS["projection"] + _ARRAYS["momentum"] + _ARRAYS["levelset"] + _ARRAYS["state"]
    count += _ARRAYS["plastic"] if plastic else 0.0
    count += _ARRAYS["pore"] if pore_pressure else 0.0
    count += _ARRAYS["free_surface"] if air == "free-surface" else 0.0
    count += _ARRAYS["side_walls"] if side_walls else 0.0
    count += _ARRAYS["state"] if step_retries else 0.0
    cells = (grid.nx + 1) * (grid.ny + 1)
    total = 8.0 * count * cells
    if pressure_solver == "direct":
        total += 8.0 * cells * min(grid.nx, grid.ny) * (2 if pore_pressure else 1)
    return int(MEMORY_MARGIN * total)


def available_memory() -> Optional[int]:
    """MemAvailable of /proc/meminfo in bytes (None where it cannot be read)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def memory_check(grid: Grid, estimate: int, what: str = "the model") -> None:
    """ParameterError naming the grid, the estimate and the memory available when ``estimate``
    exceeds it (nothing is checked where /proc/meminfo is missing)."""
    avail = available_memory()
    if avail is not None and estimate > avail:
        raise ParameterError(f"invalid parameter `grid` = {grid.nx} x {grid.ny} cells: {what} needs about "
                             f"{estimate / 2**30:.3g} GiB, more than the {avail / 2**30:.3g} GiB of memory available "
                             f"(MemAvailable); allowed a grid of at most about "
                             f"{int(grid.cells * avail / estimate):d} cells on this machine")


# the values of Numerics.active_region_sides (the Rust core parses the same names)
ACTIVE_REGION_SIDES = ("walls", "open-right", "open-right-top")
# where the plastic tensor lives (Numerics.sigma_location; Rust SigmaLocation)
SIGMA_LOCATIONS = ("staggered", "centres")


@dataclass(frozen=True)
class Numerics:
    """Numerical settings (defaults suit the paper's cases).

    cfl: CFL number of the adaptive step; dt: a fixed step instead (s); max_dt: cap on the step;
    max_growth: largest δt_n/δt_{n−1}; cfl_abort: the run stops with an error above this CFL
    number; step_retries: with the adaptive step, how many times a step whose Picard iteration
    does not converge is rejected and retaken with δt halved (default 3, 0: stop at once); the
    ceiling δt/2 then recovers by 1 % per accepted step (``time_stepping/clock.rs``); viscous: 'implicit' or 'explicit'; pressure_solver: 'multigrid-cg' or 'direct';
    pressure_rtol: relative residual of the pressure solve; interface_width: ε/h of the smoothed
    Heaviside; redistance_every: level-set redistancing frequency in steps (0: never);
    transport_interface: False freezes the interface; mass_correction: shift Φ by a constant after
    each interface update so that the dense-phase area keeps its initial value (off by default;
    docs/validation.md compares both).

    Yield stress and Coulomb walls (see ``granrs.rheology``): plastic: 'projection' (the
    bi-projection scheme, default), 'papanastasiou' or 'bi-viscous'; regularisation: the
    Papanastasiou exponent m [s] or the bi-viscous viscosity below yield [Pa s]; r, r_wall: the
    parameters of Σ = P(Σ + r D(u)) and s = P_b(s − r_b u_t) (None: the contraction bounds
    derived in ``rheology/plastic.rs`` and ``walls/mod.rs``); theta: pseudo-relaxation θ ∈ [0, 1)
    of the Picard iteration (geometric ratio about 1 − θ; 0 is plain Uzawa); picard_tol and
    picard_max_iterations: its stopping test on max |Σ^{k+1} − Σ^k| (dimensionless) and cap.
    convection: False drops ρ(u·∇)u (Stokes flow, or x-invariant layers where it vanishes);
    convection_scheme: 'centred' (second order, non-dissipative) or 'weno5' (upwind WENO5 per
    derivative: damps the grid-scale oscillations of an under-resolved light-phase shear layer);
    viscous_rtol: relative residual of the implicit viscous solve; viscous_max_iterations: its
    iteration cap (reaching it stops the run with a SimulationError, like pressure_max_iterations
    for the pressure solve and picard_max_iterations for the Picard iteration).
    pressure_gauge: how the pressure's constant is fixed when no side is an ``Outflow``: 'mean'
    (∫p = 0), 'top' (p = 0 on average over the top row of cells: a closed lid standing in for an
    open top, so that the air is at p ≈ 0 and tan(α) p⁺ and the Coulomb walls see the weight of
    the grains only), or 'auto' (default: 'top' when the yield stress or the wall friction depend
    on p, 'mean' otherwise).
    interface_yield: where the smoothed jump of the yield stress τ(Φ) and of the wall friction
    τ_b(Φ) sits across the interface band: 'paper' (default: τ = tan(α) p H_ε(Φ), the paper's
    §2.4), 'granular-side' (H_ε(Φ + ε), full strength wherever Φ > 0; with 'paper' the band,
    which the density already counts as granular, yields below the friction angle and runs
    ahead of a decelerating tongue; docs/validation.md, column collapse) or 'density-support'
    (H_ε(Φ + 2ε): full strength wherever the smoothed density carries grains, Φ > −ε; the only
    form that holds an inclined free surface at rest, docs/validation.md, fluidised layer).
    ambient_hydrostatic: p is the pressure in excess of the light phase's hydrostatic pressure
    ρ_f g·x and the body force is (ρ − ρ_f) g (off by default). For boxes where the air cannot
    balance its weight, as between the open sides of an x-invariant layer on a slope.
    proximal_restarts: per step, how many times the anchor Σ^n of the paper's eq. (12) may be
    reset to the relaxed fixed point before the iteration goes on (0, default: the paper's
    iteration). Eq. (12) converges to Σ = P(Σ + rD + θ(Σ^n − Σ)), whose rigid zones deform like
    an elastic body (wave speed ≈ 0.22 h/δt at θ = 0.8); the restarts approach eq. (11) itself,
    slowly (docs/validation.md, fluidised layer).
    r_neighbourhood: half-width w (cells) of the neighbourhood over which the default local r of
        the plastic projection takes the largest velocity response (0: the cell's own faces; at
        most 4; default 0). It sets how soft the relaxed fixed point of eq. (12) is within w cells
        of the air: a rigid zone there deforms at D = θ(Σ − Σ^n)/r, and r is set by the air's
        faces. w = 0 makes the column's run-out independent of δt (docs/validation.md, "The step size and the band under the surface").
    sigma_location: where the plastic tensor Σ lives on the MAC grid: 'staggered' (default: Σ_xx
        at cell centres, Σ_xy at nodes, each projected where its strain rate is exact) or
        'centres' (both at cell centres, as in the paper's Figure 3: D_xy averaged from the four
        corner nodes, the pair projected at the centre; not with anderson_depth > 0;
        docs/validation.md, column collapse).
    anderson_depth: depth m of the Anderson acceleration of the Picard iteration (0, default: the
        plain iteration; at most 20). Same fixed point, fewer predictor solves where the plain
        iteration crawls: Uzawa (θ = 0), fine grids, proximal restarts (docs/validation.md,
        Bingham cavity).
    picard_solve_max_iterations: iteration cap of each viscous solve inside the Picard loop
        (default 500; fine creeping grids need more from a cold start, e.g. the Bingham cavity at
        n = 128).
    pressure_update: 'standard' (default: p^{n+1} = p^n + δp) or 'rotational' (p^{n+1} = p^n + δp
        − η div ũ; Timmermans et al. 1996): the rotational form reaches Stokes-dominated steady
        states (ηδt/(ρh²) ≫ 1, e.g. the Bingham cavity) in tens of steps instead of thousands.
        Two-phase models only.
    wall_normal_stress: the normal stress −σ_n of the Coulomb walls' τ_b = tan(α_b)(−σ_n)⁺:
    'pressure' (default: −σ_n = p) or 'total' (the paper's total stress of the granular phase,
    −σ_n = p − T_nn with T = 2ηD(u) + τΣ, lagged by one step; a spreading layer presses harder
    on the base; docs/validation.md, column collapse).
    yield_pressure: the pressure of the yield stress τ = tan(α) p⁺ and of the walls' −σ_n = p:
        'absolute' (default, the paper's: p itself) or 'surface-air' (p − p_s, with p_s the mean
        pressure of the air on the granular surface, taken each step over the air cells just
        outside the smoothed band: the granular pressure starts from zero at the surface
        whatever the pressure gauge; two-phase models only; docs/models.md, active region).
    active_region: None (default: every step on the whole domain) or a band in cells: each step
    runs on a window anchored at the lower-left corner that holds the support of the dense phase
    (Φ > −3ε) and at least that many cells of light phase to its right and above; outside it the light phase is
    at rest (docs/models.md, active region). Needs a light phase, right and top sides that are
    walls and the 'top' pressure gauge. active_region_align: the window's sizes are multiples of
    this many cells (default 8, for the multigrid). active_region_sides: 'walls' (default: the window's
    right and top sides, where they lie inside the domain, have no normal flow) or 'open-right'
    (its right side is an outflow at the ambient air's hydrostatic pressure, so the air the front
    pushes leaves the window; the top stays a wall; docs/models.md, "An open right side") or
    'open-right-top' (its right and top sides both open, with backflow stabilisation: where air
    enters an open side its boundary pressure is lowered by ½ρ(u·n)²; docs/models.md, "An open
    top with backflow stabilisation").
    """

    cfl: float = 0.5
    dt: Optional[float] = None
    max_dt: float = math.inf
    max_growth: float = 1.2
    cfl_abort: float = 1.0
    step_retries: int = 3
    viscous: str = "implicit"
    pressure_solver: str = "multigrid-cg"
    pressure_rtol: float = 1e-8
    pressure_max_iterations: int = 200
    interface_width: float = 1.5
    redistance_every: int = 10
    transport_interface: bool = True
    mass_correction: bool = False
    plastic: str = "projection"
    regularisation: Optional[float] = None
    r: Optional[float] = None
    r_wall: Optional[float] = None
    theta: float = 0.5
    picard_tol: float = 1e-9
    picard_max_iterations: int = 1000
    convection: bool = True
    convection_scheme: str = "centred"
    viscous_rtol: float = 1e-10
    viscous_max_iterations: int = 2000
    pressure_gauge: str = "auto"
    interface_yield: str = "paper"
    ambient_hydrostatic: bool = False
    proximal_restarts: int = 0
    anderson_depth: int = 0
    r_neighbourhood: int = 0
    sigma_location: str = "staggered"
    picard_solve_max_iterations: int = 500
    pressure_update: str = "standard"
    wall_normal_stress: str = "pressure"
    yield_pressure: str = "absolute"
    active_region: Optional[int] = None
    active_region_align: int = 8
    active_region_sides: str = "walls"


class Model:
    """A two-phase (or single-phase) incompressible model on a MAC grid.

    ``dense`` is the material where Φ > 0 (the only one if ``light`` is None); ``light`` where
    Φ < 0. ``gravity`` is (g_x, g_y) in m s⁻². ``threads`` sets the size of the Rust thread pool.
    ``rheology`` is the law of the dense phase (``granrs.Bingham(...)``, ``granrs.DruckerPrager(...)``,
    ``granrs.MuI(...)``; default Newtonian), whose viscous part is ``dense.viscosity``.
    ``air``: ``"resolved"`` (default: the two-phase model, Navier–Stokes in both phases) or
    ``"free-surface"`` (the granular-only model: the light phase is not resolved, the dense phase
    has a free surface at p = 0 and its velocity is extended into the light phase to move Φ; p is
    then the whole pressure above the ambient one). ``light`` is still needed: it marks where the
    dense phase is not. ``side_walls``: None (default, the paper's 2D model) or a
    ``granrs.SideWalls(width, friction_angle)``: the friction of a channel's side walls on the flow.
    """

    def __init__(self, grid: Grid, dense: Material, light: Optional[Material] = None,
                 bc: Optional[BoundaryConditions] = None, gravity=(0.0, 0.0),
                 numerics: Optional[Numerics] = None, threads: int = 1, rheology=None,
                 pore_pressure: Optional[PorePressure] = None, air: str = "resolved",
                 side_walls: Optional[SideWalls] = None):
        if air not in ("resolved", "free-surface"):
            raise ParameterError(f"invalid parameter `air` = {air!r}: allowed 'resolved' (two-phase) or 'free-surface' (granular-only)")
        if air == "free-surface" and light is None:
            raise ParameterError("invalid parameter `air` = 'free-surface': allowed only with a light material (the surface is Φ = 0)")
        if not isinstance(grid, Grid):
            raise ParameterError(f"invalid parameter `grid` = {grid!r}: allowed a granrs.Grid")
        if not isinstance(dense, Material):
            raise ParameterError(f"invalid parameter `dense` = {dense!r}: allowed a granrs.Material")
        if light is not None and not isinstance(light, Material):
            raise ParameterError(f"invalid parameter `light` = {light!r}: allowed a granrs.Material or None")
        if not isinstance(threads, int) or isinstance(threads, bool) or not 1 <= threads <= 1024:
            raise ParameterError(f"invalid parameter `threads` = {threads!r}: allowed an integer in [1, 1024]")
        if rheology is None:
            rheology = Newtonian()
        if not isinstance(rheology, RHEOLOGIES):
            raise ParameterError(f"invalid parameter `rheology` = {rheology!r}: allowed granrs.Newtonian(), Bingham(...), "
                                 "DruckerPrager(...) or MuI(...)")
        if side_walls is not None and not isinstance(side_walls, SideWalls):
            raise ParameterError(f"invalid parameter `side_walls` = {side_walls!r}: allowed a granrs.SideWalls or None")
        self.side_walls = side_walls
        self.rheology = rheology
        self.grid = grid
        self.dense = dense
        self.light = light
        self.bc = bc if bc is not None else BoundaryConditions()
        if bc is not None and not isinstance(bc, BoundaryConditions):
            raise ParameterError(f"invalid parameter `bc` = {bc!r}: allowed a granrs.BoundaryConditions or None")
        if (isinstance(gravity, (str, bytes)) or not hasattr(gravity, "__len__") or len(gravity) != 2
                or not all(isinstance(g, (int, float, np.integer, np.floating)) and not isinstance(g, bool)
                           and math.isfinite(g) for g in gravity)):
            raise ParameterError(f"invalid parameter `gravity` = {gravity!r}: allowed a pair of finite numbers (g_x, g_y) "
                                 "in m/s², e.g. (0.0, -9.81)")
        self.gravity = (float(gravity[0]), float(gravity[1]))
        if numerics is not None and not isinstance(numerics, Numerics):
            raise ParameterError(f"invalid parameter `numerics` = {numerics!r}: allowed a granrs.Numerics or None")
        self.numerics = numerics if numerics is not None else Numerics()
        if pore_pressure is not None and not isinstance(pore_pressure, PorePressure):
            raise ParameterError(f"invalid parameter `pore_pressure` = {pore_pressure!r}: allowed a granrs.PorePressure or None")
        self.pore_pressure = pore_pressure
        n = self.numerics
        for name, lo, hi, val in (("active_region", 2, 100000, n.active_region), ("active_region_align", 1, 4096, n.active_region_align)):
            if val is not None and (not isinstance(val, int) or isinstance(val, bool) or not lo <= val <= hi):
                raise ParameterError(f"invalid parameter `{name}` = {val!r}: allowed None or an integer in [{lo}, {hi}] (cells)")
        self.memory_estimate = estimate_memory(
            grid, plastic=isinstance(rheology, (Bingham, DruckerPrager, MuI)) or any(
                isinstance(getattr(self.bc, s), Coulomb) for s in ("left", "right", "bottom", "top")),
            pore_pressure=pore_pressure is not None, air=air, side_walls=side_walls is not None,
            step_retries=n.step_retries if n.dt is None else 0, pressure_solver=n.pressure_solver)
        memory_check(grid, self.memory_estimate)
        self._rust = _granrs.RustModel(
            grid.nx, grid.ny, float(grid.lx), float(grid.ly), self.bc.spec(),
            (dense.density, dense.viscosity),
            None if light is None else (light.density, light.viscosity),
            self.gravity, n.interface_width, n.transport_interface, n.redistance_every, n.viscous,
            n.cfl, n.dt, n.max_dt, n.max_growth, n.cfl_abort, n.pressure_solver, n.pressure_rtol,
            n.pressure_max_iterations, threads, rheology.spec(), n.plastic, n.regularisation, n.r, n.r_wall,
            n.theta, n.picard_tol, n.picard_max_iterations, n.convection, n.viscous_rtol,
            None if pore_pressure is None else asdict(pore_pressure), n.mass_correction, n.convection_scheme,
            n.pressure_gauge, n.viscous_max_iterations, n.interface_yield, n.ambient_hydrostatic, n.proximal_restarts,
            n.wall_normal_stress, None if n.active_region is None else (n.active_region, n.active_region_align, n.active_region_sides),
            n.step_retries, air, n.anderson_depth, n.pressure_update, n.picard_solve_max_iterations, n.yield_pressure,
            n.r_neighbourhood, n.sigma_location,
            None if side_walls is None else (float(side_walls.width), float(side_walls.friction_angle)))
        self.air = air
        self.threads = threads
        names = ("u", "v", "p", "phi") + (("pf",) if pore_pressure is not None else ())
        self._views = {name: self._view(name) for name in names}
        self._has_plastic = isinstance(rheology, (Bingham, DruckerPrager, MuI)) or any(
            isinstance(getattr(self.bc, s), Coulomb) and getattr(self.bc, s).friction_angle is not None
            for s in ("left", "right", "bottom", "top"))
        if self._has_plastic:
            for name in ("sigma_xx", "sigma_xy", "trial_norm", "yield_stress"):
                self._views[name] = self._view(name)

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

    @property
    def viscosity(self) -> np.ndarray:
        """Viscosity at cell centres of the last step, shape (ny, nx) (a fresh read-only view)."""
        return self._view("viscosity")

    def _plastic(self, name: str) -> np.ndarray:
        if name not in self._views:
            raise ParameterError(f"invalid parameter `{name}`: the rheology {self.rheology} has no plastic tensor")
        return self._views[name]

    @property
    def sigma_xx(self) -> np.ndarray:
        """Σ_xx of the plastic tensor at cell centres (Σ_yy = −Σ_xx), shape (ny, nx), read-only live view."""
        return self._plastic("sigma_xx")

    @property
    def sigma_xy(self) -> np.ndarray:
        """Σ_xy of the plastic tensor at nodes, shape (ny + 1, nx + 1), read-only live view."""
        return self._plastic("sigma_xy")

    @property
    def trial_norm(self) -> np.ndarray:
        """|Σ + r D(u) + θ(Σⁿ − Σ)|, the argument of the plastic projection, at cell centres after
        the last step: ≤ 1 exactly where the material is rigid (unyielded), shape (ny, nx),
        read-only live view."""
        return self._plastic("trial_norm")

    @property
    def yield_stress(self) -> np.ndarray:
        """Yield stress τ(Φ) at cell centres of the last step [Pa], shape (ny, nx), read-only live view."""
        return self._plastic("yield_stress")

    @property
    def active_window(self):
        """(nx, ny) of the active window the last step ran on (``Numerics.active_region``), or
        None (the whole domain, or no step taken yet)."""
        w = self._rust.active_window()
        return None if w is None else tuple(w)

    def picard_history(self) -> np.ndarray:
        """Increments max |τ(Σ^{k+1} − Σ^k)|/τ_max of the Picard iterations of the last step."""
        return np.asarray(self._rust.picard_history())

    def wall_friction(self, side: str):
        """(s, τ_b) along a Coulomb side's tangential faces (arrays), or None without friction."""
        out = self._rust.wall_friction(side)
        return None if out is None else (np.asarray(out[0]), np.asarray(out[1]))

    def set_initial(self, u: Optional[ArrayOrFn] = None, v: Optional[ArrayOrFn] = None, p: Optional[ArrayOrFn] = None,
                    phi: Optional[ArrayOrFn] = None, pf: Optional[ArrayOrFn] = None,
                    balance_pressure: bool = True) -> None:
        """Sets initial fields from arrays, constants or functions f(x, y) evaluated at the
        field's points. With ``balance_pressure`` (and no explicit ``p``), p is set so that the
        body force is balanced (one pressure solve)."""
        points = {"u": self.grid.xfaces, "v": self.grid.yfaces, "p": self.grid.centres, "phi": self.grid.centres,
                  "pf": self.grid.centres}
        arrays = {}
        for name, value in (("phi", phi), ("pf", pf), ("u", u), ("v", v), ("p", p)):
            if value is None:
                continue
            if name == "pf" and self.pore_pressure is None:
                raise ParameterError("invalid parameter `pf`: allowed only for a model with pore_pressure")
            x, y = points[name]()
            what = "the value"
            if callable(value):
                try:
                    value = value(x, y)
                except Exception as err:  # noqa: BLE001 - the user's function
                    raise ParameterError(f"invalid parameter `{name}`: the function f(x, y) raised {type(err).__name__}: "
                                         f"{err}; allowed a function of NumPy arrays x, y of shape {x.shape}") from None
                what = "the function's result"
                if value is None or np.ndim(value) == 0:
                    raise ParameterError(f"invalid parameter `{name}`: {what} is {value!r}; allowed an array of shape "
                                         f"{x.shape} (write f(x, y) with NumPy, e.g. np.where(...) or 0 * x + c)")
            raw = np.asarray(value)
            if raw.dtype.kind not in "biuf":
                raise ParameterError(f"invalid parameter `{name}`: {what} has dtype {raw.dtype}; allowed real numbers "
                                     f"(float64), shape {x.shape}")
            arr = raw.astype(float)
            if arr.ndim == 0:
                arr = np.full(x.shape, float(arr))
            if arr.shape != x.shape:
                raise ParameterError(f"invalid parameter `{name}`: {what} has shape {arr.shape}; allowed shape {x.shape} "
                                     f"(ny, nx) = ({self.grid.ny}, {self.grid.nx}) for {name}")
            if not np.all(np.isfinite(arr)):
                bad = np.argwhere(~np.isfinite(arr))[0]
                raise ParameterError(f"invalid parameter `{name}`: {what} is not finite at (j, i) = ({bad[0]}, {bad[1]}); "
                                     "allowed finite numbers")
            arrays[name] = arr
        for name, arr in arrays.items():
            self._rust.set_field(name, np.ascontiguousarray(arr))
        if p is None and balance_pressure:
            self._rust.initialise_pressure()

    def balance_plastic_stress(self) -> dict:
        """Sets the plastic tensor Σ to the one that holds the current state at rest, column by
        column: Σ_xx = 0 and τΣ_xy = ∫_y^top f_x dy', with f_x the x-force at rest (weight along
        the slope and −∂x(p + p_f)). Call after the initial Φ, p_f and balanced pressure. Without
        it the Picard iteration (paper eq. 12) builds Σ up from 0 over many steps and a layer that
        should stay at rest moves meanwhile. Exact for states uniform along x (layers on a slope).

        Returns ``max_ratio`` (largest |τΣ_xy|/τ needed; ≤ 1 means the state can stay at rest),
        ``node`` (its (i, j)), ``clamped`` (nodes where Σ_xy was clamped to ±1, which will
        yield) and ``x_residual`` (the y-force left unbalanced where the state varies along x,
        relative to ρ g). Raises ParameterError for a law without a projected yield stress."""
        return self._rust.balance_plastic_stress()

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

    def energy_budget(self) -> dict:
        """The mechanical energy budget since the state was last set, J per metre of width
        (docs/architecture.md, "Energy budget"): ``kinetic``, ``potential`` (now and ``*_initial``),
        the works ``gravity_work``, ``plastic_work`` (with its ``plastic_negative_work``: stress
        given back to the flow, which eq. (11) of the paper forbids), ``viscous_work``,
        ``wall_work`` by side, ``side_wall_work`` (the channel's side walls, 0 without them), the
        ``residual`` E_k − E_k(0) − W_g + W_pl + W_visc + W_wall + W_side that
        the discretisation added (> 0) or removed (< 0), and the last ``rates`` in W/m."""
        return self._rust.energy_budget()

    # ---- stepping -----------------------------------------------------------------------
    def step(self) -> dict:
        """Takes one step (GIL released); returns its diagnostics."""
        return self._rust.step()

    def advance(self, t_end: Optional[float] = None, max_steps: Optional[int] = None) -> dict:
        """Steps until ``t_end`` (landing on it exactly) or ``max_steps``; returns per-step
        diagnostics as lists (time, dt, max_speed, cfl, divergence, pressure_iterations,
        viscous_iterations, picard_iterations, picard_increment)."""
        if t_end is None and max_steps is None:
            raise ParameterError("invalid parameter `t_end/max_steps`: allowed at least one of them")
        if t_end is not None and (isinstance(t_end, bool) or not isinstance(t_end, (int, float, np.floating))
                                  or not math.isfinite(t_end) or t_end < self.time):
            raise ParameterError(f"invalid parameter `t_end` = {t_end!r}: allowed a finite time >= the model time "
                                 f"{self.time!r} s")
        if max_steps is not None and (isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer))
                                      or max_steps < 0):
            raise ParameterError(f"invalid parameter `max_steps` = {max_steps!r}: allowed an integer >= 0")
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
            "pore_pressure": None if self.pore_pressure is None else asdict(self.pore_pressure), "rheology": self.rheology.spec(),
        }

    def __repr__(self) -> str:
        phases = f"dense {self.dense}" + ("" if self.light is None else f", light {self.light}")
        return (f"Model on {self.grid}\n  {phases}\n  {self.bc}\n  gravity {self.gravity}, threads {self.threads}\n"
                f"  t = {self.time:.6g} s after {self.step_count} steps")
