"""The paper's experiment: collapse of a (fluidised) column of glass beads in a channel.

Aravena, Chupin, Dubois & Roche, §4 (docs/reference-data.md, "The paper"): a column L_c = 0.20 m wide and
H_c = 0.40 m high (aspect ratio a = H_c/L_c = 2) of glass beads (φ = 0.58, ρ_s = 2500 kg m⁻³,
d_s = 75 µm) with internal friction angle α = 27° and wall friction α_b = 15° on the base and the
back wall, released at t = 0 from a reservoir whose gate is at x = L_c. Fluidised: the pore
pressure starts at p_f = β φ ρ_s g (H_c − y) (β = 0.9) and air is supplied through the reservoir
base, ∂p_f/∂y = −β φ ρ_s g for 0 < x < L_c; κ_f = 0.035 m² s⁻¹. D-P rheology with η_s = 0.1 Pa s.
The paper's run-out from the gate: 1.6874 m (simulation), 1.8443 m (experiment).

Numerics chosen for this case (measured reasons in docs/validation.md, "Column collapse"):
convection by upwind WENO5 (the centred form lets the air's shear layer over the flowing grains
oscillate at the grid scale, 5–9 m/s at ny = 32–64, until droplets of grains are flung down the
channel); a free-slip lid at the top of the domain (with an open top the inner viscous solves
stall near 1e-3 relative and floor the Picard increment above its tolerance).

Rest criterion (documented): the run stops when the largest velocity in the granular phase
(cells with Φ > 0; the air side of the smoothed interface band, Φ ≤ 0, where H_ε still gives a
cell some grains, is explicitly not looked at) stays below ``rest_speed`` (default 5e-3 m/s,
0.18 % of √(2 g H_c)) for ``rest_duration`` (default 0.05 s) after t > 0.1 s, or at ``t_end``.
summary.json says when (:func:`arrest_summary`): ``stop_reason`` is ``"rest"`` and
``arrest_time_s`` the start of that quiet window (None for a run that did not come to rest),
with the largest front, when it was reached and how far the front then moved back
(docs/validation.md, "Arrest of the deposit").

Models (``ColumnCase.model``, ``granrs run column --model``): ``two-phase`` (the paper's model,
the default), ``granular`` (the same 2D model with the air not resolved: the granular phase has a
free surface at p = 0, ``Model(air='free-surface')``), ``depth-averaged`` (Savage–Hutter shallow
layer with a depth-averaged pore pressure, ``granrs.depth_averaged``; seconds instead of minutes)
and ``auto``, which takes the depth-averaged model only where its measured run-out is within 5 %
of the two-phase one (docs/models.md, :func:`choose_model`). All models write the same outputs.

Observables (granrs.observables; docs/validation.md, "Observables"): every record (0.01 s) adds to
front.csv the fronts of the volume profile h = Σ_j f Δy at 1, 2, 5, 10 and 20 mm and at ½, 1 and
2 cells, the 50/90/95/99 % deposit quantiles, the centre of mass and the heights at the back wall
and the gate; summary.json["observables"] holds those of the final deposit with the centre of
mass's travel, and profiles.csv the final volume profile (``hvol_final``).
"""

from __future__ import annotations

import csv
import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from .. import __version__
from .. import observables as obs
from .._granrs import ParameterError, SimulationError, SolverError
from ..boundary import BoundaryConditions, Coulomb, FreeSlip
from ..grid import Grid
from ..materials import AIR, Material
from ..rheology import check_friction_angle
from ..model import (ACTIVE_REGION_SIDES, SIGMA_LOCATIONS, Model, Numerics, PorePressure, SideWalls, check_side_walls,
                     estimate_memory, memory_check)
from ..shapes import Rectangle
from ..simulation import Callback, Simulation
from ..io.outputs import OutputError, RunOutputs

G = 9.81
PAPER_RUNOUT_SIM = 1.6874
PAPER_RUNOUT_EXP = 1.8443
MODELS = ("auto", "two-phase", "granular", "depth-averaged")
#: run_column rewrites summary.json, front.csv and history.npz every this many records (0.1 s)
FLUSH_RECORDS = 10


@dataclass
class ColumnCase:
    """Parameters of the column collapse (defaults: the paper's values)."""

    aspect_ratio: float = 2.0
    width: float = 0.20
    fluidised: bool = True
    pore_pressure_ratio: float = 0.9
    ny: int = 32
    t_end: float = 3.0
    rheology: str = "drucker-prager"
    cfl: float = 0.5
    threads: int = 1
    solid_fraction: float = 0.58
    grain_density: float = 2500.0
    grain_diameter: float = 75e-6
    friction_angle: float = 27.0
    wall_friction_angle: float = 15.0
    granular_viscosity: float = 0.1
    diffusivity: float = 0.035
    # the pore-pressure formulation of the two-phase model (granrs.PorePressure): 'granular-only'
    # (solve where Φ > 0 with p_f = 0 on the interface: the default, docs/validation.md) or the
    # paper's 'kappa-infinity' extension by zero through the air
    pore_formulation: str = "granular-only"
    # κ_∞ of the 'kappa-infinity' formulations [m² s⁻¹] (the paper: 1e16). 1e8 places the same
    # boundary (κ_∞(1 − H_ε) exceeds κ_f wherever 1 − H_ε > 4e-10) and keeps the pore-pressure
    # CG in double precision: with 1e16 (κ_∞/κ_f = 3e17) it stalled at ny = 32, t = 2.23 s
    # (measured on the fluidised column at ny = 32)
    kappa_air: float = 1e8
    # where the smoothed jump of the yield stress and of the basal friction sits across the
    # interface band (granrs.Numerics.interface_yield): the paper's 'paper' (default,
    # τ = tan(α) p H_ε(Φ)), 'granular-side' (full strength wherever Φ > 0) or 'density-support'
    # (full strength wherever the smoothed density carries grains, Φ > −ε); docs/validation.md
    interface_yield: str = "paper"
    # the normal stress of the Coulomb base and back wall (granrs.Numerics.wall_normal_stress):
    # 'pressure' (default, −σ_n = p) or 'total' (the paper's −σ_n = p − T_nn); docs/validation.md
    wall_normal_stress: str = "pressure"
    # the sign of the air supply through the reservoir's base: 'injection' (default: ∂p_f/∂y =
    # −β φρ_s g, the gas flows up into the column, as the text describes and the initial p_f
    # implies) or 'literal' (the printed ∂p_f/∂n = −β φρ_s g with n the base's outward normal,
    # ∂p_f/∂y = +β φρ_s g: an outflow); docs/validation.md, "Observables"
    air_supply: str = "injection"
    # the back wall (x = 0): 'coulomb' (default, the paper's: friction angle wall_friction_angle)
    # or 'free-slip' (the cross-code check against Basilisk, docs/validation.md)
    back_wall: str = "coulomb"
    # the pressure of the yield stress and the walls' normal stress (granrs.Numerics.yield_pressure):
    # 'absolute' (default, the paper's p) or 'surface-air' (p minus the mean air pressure on the
    # granular surface: independent of the pressure gauge; docs/models.md, active region)
    yield_pressure: str = "absolute"
    # active region (granrs.Numerics.active_region): None (whole domain) or the band of air
    # cells kept around the granular phase; each step then runs on that window (docs/models.md)
    active_region: Optional[int] = None
    # the window's sides (granrs.Numerics.active_region_sides): 'walls' (default), 'open-right' or
    # 'open-right-top' (its right side, or its right and top sides, outflows at the air's hydrostatic
    # pressure, the latter with backflow stabilisation; docs/models.md, "An open right side")
    active_region_sides: str = "walls"
    length: Optional[float] = None
    height: Optional[float] = None
    # Picard iteration of the plastic projection: stress-weighted increment tolerance and
    # pseudo-relaxation (geometric ratio about 1 − θ). The increment is max |τ ΔΣ|/τ_max, so
    # 1e-3 is a stress change of ~3 Pa against stresses of 10²–10³ Pa; at ny = 32–64 the increment
    # stalls transiently between 1e-4 and 5e-4 (see docs/validation.md), so 1e-4 stopped runs.
    picard_tol: float = 1e-3
    theta: float = 0.8
    # proximal restarts of the anchor Σⁿ of eq. (12) per step (granrs.Numerics.proximal_restarts):
    # 0 (default) the paper's iteration; 5 brings the relaxed fixed point towards eq. (11), whose
    # rigid zones do not ring (docs/validation.md, "Arrest of the deposit")
    proximal_restarts: int = 0
    # half-width of the neighbourhood of the plastic projection's local r (granrs.Numerics.r_neighbourhood):
    # within this many cells of the air the relaxed fixed point of eq. (12) is as soft as the air's
    # faces make it; 0 keeps the run-out independent of δt (docs/validation.md)
    r_neighbourhood: int = 0
    # the friction of the channel's side walls (granrs.SideWalls; not in the paper's 2D model): None
    # (default, the paper) or the channel width W in m (the experiment's: 0.10), with the friction
    # angle side_wall_friction_angle (None: the base's wall_friction_angle); docs/validation.md
    channel_width: Optional[float] = None
    side_wall_friction_angle: Optional[float] = None
    # where the plastic tensor lives (granrs.Numerics.sigma_location): 'staggered' (default) or
    # 'centres' (the paper's Figure 3: Σ_xx and Σ_xy at cell centres); docs/validation.md
    sigma_location: str = "staggered"
    # rejections of a step whose Picard iteration does not converge (retaken with δt halved;
    # granrs.Numerics.step_retries): the paper's grid, ny = 256, needs them at t ≈ 6 ms
    step_retries: int = 3
    # global mass correction of the level set (Φ shifted by a constant after each transport,
    # found by the secant method; see docs/validation.md, dam break): without it the dense area
    # grows by 6 % at ny = 32 by t = 3 s (thin films); switchable for comparison
    mass_correction: bool = True
    rest_speed: float = 5e-3
    rest_duration: float = 0.05
    profile_times: list = field(default_factory=lambda: [0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0])
    # which model: "two-phase" (default), "granular" (the air not resolved: a free surface at p = 0),
    # "depth-averaged", "auto" (see choose_model)
    model: str = "two-phase"
    # depth-averaged model only: earth-pressure coefficient k ("savage-hutter": the active
    # coefficient from friction_angle and wall_friction_angle, reduced by the pore pressure; or a
    # number; docs/models.md) and cells across min(L_c, H_c)
    earth_pressure: object = "savage-hutter"
    da_resolution: int = 64

    def validate(self) -> None:
        checks = [("aspect_ratio", self.aspect_ratio, 0.1, 20.0), ("width", self.width, 1e-3, 10.0),
                  ("pore_pressure_ratio", self.pore_pressure_ratio, 0.0, 1.0), ("t_end", self.t_end, 1e-6, 1e4),
                  ("cfl", self.cfl, 1e-3, 1.0), ("wall_friction_angle", self.wall_friction_angle, 0.0, 89.0),
                  ("granular_viscosity", self.granular_viscosity, 1e-8, 1e6), ("diffusivity", self.diffusivity, 1e-12, 1e6),
                  ("solid_fraction", self.solid_fraction, 0.01, 0.74), ("kappa_air", self.kappa_air, 1.0, 1e16)]
        for name, v, lo, hi in checks:
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or not lo <= v <= hi:
                raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed a number in [{lo}, {hi}]")
        check_friction_angle(self.friction_angle)
        if isinstance(self.ny, bool) or not isinstance(self.ny, int) or not 8 <= self.ny <= 4096:
            raise ParameterError(f"invalid parameter `ny` = {self.ny!r}: allowed an integer in [8, 4096]")
        for name, v, lo, what in (("length", self.length, self.width, "the gate at x = width"),
                                  ("height", self.height, self.column_height, "the column height aspect_ratio × width")):
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                                  or not lo < v <= 1000.0):
                raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed None (the default) or a number of metres "
                                     f"in ({lo:g}, 1000] (beyond {what} = {lo:g} m)")
        for name, v, lo, hi in (("threads", self.threads, 1, 1024), ("step_retries", self.step_retries, 0, 20),
                                ("r_neighbourhood", self.r_neighbourhood, 0, 4)):
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed an integer in [{lo}, {hi}]")
        if self.active_region is not None and (isinstance(self.active_region, bool)
                                               or not isinstance(self.active_region, int)
                                               or not 2 <= self.active_region <= 100000):
            raise ParameterError(f"invalid parameter `active_region` = {self.active_region!r}: allowed None or an integer "
                                 "in [2, 100000] (cells of air)")
        if self.pore_formulation not in ("granular-only", "kappa-infinity", "kappa-infinity-smoothed"):
            raise ParameterError(f"invalid parameter `pore_formulation` = {self.pore_formulation!r}: allowed "
                                 "'granular-only', 'kappa-infinity' or 'kappa-infinity-smoothed'")
        if self.interface_yield not in ("granular-side", "paper", "density-support"):
            raise ParameterError(f"invalid parameter `interface_yield` = {self.interface_yield!r}: allowed "
                                 "'granular-side', 'paper' or 'density-support'")
        if self.wall_normal_stress not in ("pressure", "total"):
            raise ParameterError(f"invalid parameter `wall_normal_stress` = {self.wall_normal_stress!r}: allowed "
                                 "'pressure' or 'total'")
        if self.channel_width is not None:
            angle = self.wall_friction_angle if self.side_wall_friction_angle is None else self.side_wall_friction_angle
            check_side_walls(self.channel_width, angle, "channel_width", "side_wall_friction_angle")
        elif self.side_wall_friction_angle is not None:
            raise ParameterError(f"invalid parameter `side_wall_friction_angle` = {self.side_wall_friction_angle!r}: "
                                 "allowed only with a channel_width")
        if self.air_supply not in ("injection", "literal"):
            raise ParameterError(f"invalid parameter `air_supply` = {self.air_supply!r}: allowed 'injection' or 'literal'")
        if self.back_wall not in ("coulomb", "free-slip"):
            raise ParameterError(f"invalid parameter `back_wall` = {self.back_wall!r}: allowed 'coulomb' or 'free-slip'")
        if self.sigma_location not in SIGMA_LOCATIONS:
            raise ParameterError(f"invalid parameter `sigma_location` = {self.sigma_location!r}: allowed "
                                 + " or ".join(repr(n) for n in SIGMA_LOCATIONS))
        if self.yield_pressure not in ("absolute", "surface-air"):
            raise ParameterError(f"invalid parameter `yield_pressure` = {self.yield_pressure!r}: allowed "
                                 "'absolute' or 'surface-air'")
        if self.active_region_sides not in ACTIVE_REGION_SIDES:
            names = [repr(n) for n in ACTIVE_REGION_SIDES]
            raise ParameterError(f"invalid parameter `active_region_sides` = {self.active_region_sides!r}: allowed "
                                 f"{', '.join(names[:-1])} or {names[-1]}")
        if self.model not in MODELS:
            raise ParameterError(f"invalid parameter `model` = {self.model!r}: allowed 'auto', 'two-phase', 'granular' or "
                                 "'depth-averaged'")
        if self.earth_pressure != "savage-hutter" and (not isinstance(self.earth_pressure, (int, float))
                                                        or isinstance(self.earth_pressure, bool)
                                                        or not 0.01 <= self.earth_pressure <= 100.0):
            raise ParameterError(f"invalid parameter `earth_pressure` = {self.earth_pressure!r}: allowed 'savage-hutter' "
                                 "or a number in [0.01, 100]")
        if not isinstance(self.proximal_restarts, int) or isinstance(self.proximal_restarts, bool) or not 0 <= self.proximal_restarts <= 1000:
            raise ParameterError(f"invalid parameter `proximal_restarts` = {self.proximal_restarts!r}: allowed an integer in [0, 1000]")
        if not isinstance(self.da_resolution, int) or not 4 <= self.da_resolution <= 4096:
            raise ParameterError(f"invalid parameter `da_resolution` = {self.da_resolution!r}: allowed an integer in [4, 4096]")
        if self.rheology not in ("drucker-prager", "mu-i"):
            raise ParameterError(f"invalid parameter `rheology` = {self.rheology!r}: allowed 'drucker-prager' or 'mu-i'")
        if self.model != "depth-averaged":  # memory before any work (granrs.model.estimate_memory)
            grid = self.grid()
            memory_check(grid, estimate_memory(grid, pore_pressure=bool(self.fluidised and self.pore_pressure_ratio > 0),
                                               air="free-surface" if self.model == "granular" else "resolved",
                                               side_walls=self.channel_width is not None, step_retries=self.step_retries),
                         f"the column's {self.model} model")

    @property
    def column_height(self) -> float:
        return self.aspect_ratio * self.width

    @property
    def mixture_density(self) -> float:
        return self.solid_fraction * self.grain_density

    def domain(self) -> tuple[float, float]:
        """(length, height): height 1.125 H_c (the paper's 0.45 m), length L_c + 8.25 H_c (3.5 m
        for the paper's column; the grid rounds it up by at most 3 %, to 3.6 m at ny = 2^k). The paper's channel needs only 2.05 m for its 1.6874 m run-out,
        but coarse grids run further (1.98 m at ny = 32, docs/validation.md), and reaching the
        far end stops the run with an error."""
        hc = self.column_height
        return (self.length or self.width + 8.25 * hc, self.height or 1.125 * hc)

    def grid(self) -> Grid:
        lx, ly = self.domain()
        h = ly / self.ny
        # nx rounded up to a multiple of the largest power of two m dividing ny (m ≤ ny/2): the
        # multigrid then coarsens both directions down to ny/m ≥ 2 rows. The plain rounding gave
        # nx = 498, 996, 1992 = 249·2^k at ny = 64, 128, 256, a 249 × 32 coarsest level whose
        # Cholesky refactorisation (every step: the density moves) cost 5–9 % of a step.
        # The domain grows by at most 3 % (else m is halved, down to 2): a user's length is kept.
        m = 1
        while self.ny % (2 * m) == 0 and 2 * m <= self.ny // 2:
            m *= 2
        m = max(m, 2)
        while m > 2 and math.ceil(lx / h / m - 1e-9) * m * h > 1.03 * lx:
            m //= 2
        nx = int(math.ceil(lx / h / m - 1e-9)) * m
        return Grid(nx, self.ny, nx * h, ly)


def side_walls(case: ColumnCase) -> Optional[SideWalls]:
    """The channel's side walls of ``case`` (None without a channel_width)."""
    if case.channel_width is None:
        return None
    angle = case.wall_friction_angle if case.side_wall_friction_angle is None else case.side_wall_friction_angle
    return SideWalls(case.channel_width, angle)


def build_model(case: ColumnCase) -> Model:
    """The two-phase model of the column case (or, with ``model='granular'``, the granular-only
    model: the same 2D model with the air not resolved), with its initial condition."""
    case.validate()
    grid = case.grid()
    hc, lc = case.column_height, case.width
    rho = case.mixture_density
    pore = None
    if case.fluidised and case.pore_pressure_ratio > 0:
        sign = 1.0 if case.air_supply == "literal" else -1.0
        pore = PorePressure(diffusivity=case.diffusivity, basal_gradient=sign * case.pore_pressure_ratio * rho * G,
                            formulation=case.pore_formulation, kappa_air=case.kappa_air,
                            basal_x_min=0.0, basal_x_max=lc)
    model = Model(grid, Material(rho, case.granular_viscosity), light=AIR, gravity=(0.0, -G),
                  bc=BoundaryConditions(left=FreeSlip() if case.back_wall == "free-slip" else Coulomb(case.wall_friction_angle),
                                        right=FreeSlip(),
                                        bottom=Coulomb(case.wall_friction_angle), top=FreeSlip()),
                  numerics=Numerics(cfl=case.cfl, picard_tol=case.picard_tol, theta=case.theta, r_neighbourhood=case.r_neighbourhood,
                                    sigma_location=case.sigma_location,
                                    picard_max_iterations=1000, convection_scheme="weno5", step_retries=case.step_retries,
                                    mass_correction=case.mass_correction, interface_yield=case.interface_yield,
                                    proximal_restarts=case.proximal_restarts,
                                    wall_normal_stress=case.wall_normal_stress, yield_pressure=case.yield_pressure,
                                    active_region=case.active_region, active_region_sides=case.active_region_sides),
                  threads=case.threads, pore_pressure=pore,
                  air="free-surface" if case.model == "granular" else "resolved",
                  side_walls=side_walls(case),
                  **_rheology_kwargs(case))
    model.set_shape(Rectangle(-1.0, lc, -1.0, hc), balance_pressure=False)
    if pore is not None:
        beta = case.pore_pressure_ratio
        model.set_initial(pf=lambda x, y: np.where((x < lc) & (y < hc), beta * rho * G * (hc - y), 0.0),
                          balance_pressure=False)
    model.set_initial(balance_pressure=True)
    return model


def _rheology_kwargs(case: ColumnCase) -> dict:
    """The granular rheology of the case: the paper's D-P model (constant η_s, yield stress
    tan α p⁺) or μ(I). The paper gives no μ(I) constants for its beads; we take μ_s = tan α and
    the Δμ = μ₂ − μ_s = 0.26, I₀ = 0.279 of Jop, Forterre & Pouliquen (2006, Nature 441) for glass
    beads (an assumption, stated in the summary)."""
    from ..rheology import DruckerPrager, MuI

    if case.rheology == "drucker-prager":
        return {"rheology": DruckerPrager(friction_angle=case.friction_angle)}
    mu_s = math.tan(math.radians(case.friction_angle))
    return {"rheology": MuI(mu_s=mu_s, mu_2=mu_s + 0.26, i0=0.279, grain_diameter=case.grain_diameter,
                            grain_density=case.grain_density)}


def front_position(phi: np.ndarray, dx: float, max_gap: int = 2) -> float:
    """Front of the granular mass on the lowest row of cells: walking from the back wall along the
    cells with Φ > 0, gaps of at most ``max_gap`` cells are bridged (a front broken by one under-
    resolved cell), larger ones end the mass (detached droplets ahead of it do not count; see
    :func:`farthest_material`). Located at the linear zero crossing of Φ after the last cell."""
    row = phi[0]
    inside = np.nonzero(row > 0)[0]
    if inside.size == 0:
        return 0.0
    breaks = np.nonzero(np.diff(inside) > max_gap + 1)[0]
    i = inside[breaks[0]] if breaks.size else inside[-1]
    x = (i + 0.5) * dx
    if i + 1 < row.size:
        x += dx * row[i] / (row[i] - row[i + 1])
    return float(x)


def farthest_material(phi: np.ndarray, dx: float) -> float:
    """Largest x of a cell with Φ > 0 anywhere (detached droplets included)."""
    cols = np.nonzero((phi > 0).any(axis=0))[0]
    return float((cols[-1] + 1) * dx) if cols.size else 0.0


#: Fraction of the deposit's area behind ``runout_q99_m`` (summary.json).
DEPOSIT_QUANTILE = 0.99


def deposit_quantile(h: np.ndarray, dx: float, x_gate: float, q: float = DEPOSIT_QUANTILE) -> float:
    """Distance from the gate behind which the fraction ``q`` of the deposit's area lies: the
    cumulative area of the profile h (cell i spans [i dx, (i + 1) dx]) reaches q of the total,
    located linearly inside the cell where it does. Unlike the front, it does not jump when a
    thin piece of the tongue drops below the front's threshold (docs/validation.md,
    "Predictability of the late run-out")."""
    if not 0.0 < q <= 1.0:
        raise ParameterError(f"invalid parameter `q` = {q!r}: allowed a fraction in (0, 1]")
    h = np.clip(np.asarray(h, dtype=float), 0.0, None)
    cum = np.cumsum(h) * dx
    if cum.size == 0 or cum[-1] <= 0.0:
        return 0.0
    target = q * cum[-1]
    i = int(np.searchsorted(cum, target))
    before = cum[i - 1] if i > 0 else 0.0
    frac = (target - before) / (h[i] * dx) if h[i] > 0 else 1.0
    return float((i + frac) * dx - x_gate)


def surface_profile(phi: np.ndarray, dy: float) -> np.ndarray:
    """Height h(x) of the granular surface in each column: the highest zero crossing of Φ."""
    ny, nx = phi.shape
    inside = phi > 0
    j = ny - 1 - np.argmax(inside[::-1], axis=0)  # highest granular cell of each column
    cols = np.arange(nx)
    h = (j + 0.5) * dy
    below = j + 1 < ny  # interpolate to the zero crossing with the cell above
    a, b = phi[j[below], cols[below]], phi[j[below] + 1, cols[below]]
    h[below] += dy * a / (a - b)
    h[~inside.any(axis=0)] = 0.0
    return h


def basal_pore_pressure_ratio(pf_base: np.ndarray, h: np.ndarray, weight: float, mask: np.ndarray) -> float:
    """Share of the granular weight carried by the gas at the base over the columns ``mask``:
    Σ p_f(first cell row) / Σ φρ_s g h(x), h the surface height (``surface_profile``) and
    ``weight`` = φρ_s g. β at the start under the reservoir (less the half cell between the base
    and the first row); 0 where the gas has escaped; above 1 where the pore pressure exceeds the
    weight (p_s < 0: no friction at all). NaN where ``mask`` holds no material."""
    sel = mask & (h > 0)
    w = weight * float(np.sum(h[sel]))
    return float(np.sum(pf_base[sel]) / w) if w > 0 else math.nan


def arrest_summary(t, front, speed, stop_reason: str, rest_since: Optional[float]) -> dict:
    """summary.json's arrest entries from the records (times ``t``, fronts ``front`` from the
    gate, largest granular speeds ``speed``): ``arrest_time_s`` (``rest_since``, the start of the
    window of rest that stopped the run, when ``stop_reason`` is ``"rest"``; else None), the time
    ``max_front_time_s`` of the largest front (``max_front_m``), ``front_retreat_m`` (the largest
    front minus the last one, ≥ 0) and ``final_granular_speed_m_s``."""
    front = np.asarray(front, dtype=float)
    if front.size == 0:
        return {"arrest_time_s": None, "max_front_time_s": None, "front_retreat_m": 0.0, "final_granular_speed_m_s": None}
    k = int(np.argmax(front))
    return {"arrest_time_s": float(rest_since) if stop_reason == "rest" and rest_since is not None else None,
            "max_front_time_s": float(t[k]), "front_retreat_m": float(front[k] - front[-1]),
            "final_granular_speed_m_s": float(speed[-1])}


def run_column(case: ColumnCase, out: Path, progress: bool = True, compare_with: Optional[Path] = None,
               callbacks: Optional[list] = None, extra_summary: Optional[dict] = None, prepare=None,
               outputs: Optional[RunOutputs] = None) -> dict:
    """Runs the case, writes summary.json, front.csv, profiles.csv, front.png and profiles.png into ``out``.

    ``callbacks``: more ``Callback``s for the Simulation (field output, checkpoints);
    ``extra_summary``: entries added to summary.json; ``prepare(model)``: called once the model
    is built (a restart restores its state there); ``outputs``: the folder's ``RunOutputs`` (a
    restart's earlier rows and original dense area). summary.json, front.csv and history.npz are
    rewritten atomically every ``FLUSH_RECORDS`` records during the run (``stop_reason``
    'incomplete: ...'). A SimulationError, SolverError or KeyboardInterrupt still writes every
    output from the steps done, with the ``stop_reason``, then is raised again."""
    case.validate()
    model_name, model_reason = choose_model(case)
    if model_name == "depth-averaged":
        if callbacks or prepare is not None:
            raise ParameterError("invalid parameter `model` = 'depth-averaged' with field output, checkpoints or a "
                                 "restart: allowed only with the 2D models ('two-phase', 'granular')")
        if case.channel_width is not None:
            raise ParameterError("invalid parameter `channel_width` with the depth-averaged model: allowed only with the "
                                 "2D models ('two-phase', 'granular')")
        return run_column_depth_averaged(case, out, progress=progress, compare_with=compare_with,
                                         extra_summary=extra_summary, reason=model_reason)
    out.mkdir(parents=True, exist_ok=True)
    model = build_model(case)
    if prepare is not None:
        prepare(model)
    grid = model.grid
    lc = case.width
    outputs = outputs if outputs is not None else RunOutputs(out)
    area0 = outputs.start_area or model.dense_area()
    rec = {"t": [], "front": [], "area": [], "max_granular_speed": [], "energy": []}
    # fluidisation: the basal pore pressure over the weight, under the reservoir and in the channel
    fluid = model.pore_pressure is not None
    xs_c = (np.arange(grid.nx) + 0.5) * grid.dx
    under_reservoir = xs_c < lc
    if fluid:
        rec["pf_ratio_reservoir"], rec["pf_ratio_channel"] = [], []
    profiles = {}
    state = {"rest_since": None}
    pending_profiles = sorted(case.profile_times)

    def granular_speed() -> float:
        uc, vc = model.centre_velocity()
        inside = model.phi > 0
        return float(np.max(np.hypot(uc, vc)[inside])) if inside.any() else 0.0

    def observe(sim: Simulation) -> None:
        t = model.time
        xf = front_position(model.phi, grid.dx)
        xfar = farthest_material(model.phi, grid.dx)
        # "reached the far end": the front, or more than 1 % of the column's area within the last
        # three columns of cells (single-cell specks of thin films sliding ahead do not count)
        far_area = float(np.count_nonzero(model.phi[:, -3:] > 0)) * grid.dx * grid.dy
        if xf > grid.lx - 3 * grid.dx or far_area > 0.01 * area0:
            raise SimulationError(f"the granular material reached the far end of the domain (x = {xfar:.3f} m of "
                                  f"{grid.lx:.3f} m) at t = {t:.3f} s: increase --length (grid.length in a run file)")
        speed = granular_speed()
        rec["t"].append(t)
        rec["front"].append(xf - lc)
        rec["area"].append(model.dense_area())
        rec["max_granular_speed"].append(speed)
        rec["energy"].append(model.energy_budget())
        _record_observables(rec, obs.volume_profile(model.phi, grid.dy), grid.dx, grid.dy, lc)
        if fluid:
            h, pf0, weight = surface_profile(model.phi, grid.dy), model.pf[0], case.mixture_density * G
            rec["pf_ratio_reservoir"].append(basal_pore_pressure_ratio(pf0, h, weight, under_reservoir))
            rec["pf_ratio_channel"].append(basal_pore_pressure_ratio(pf0, h, weight, ~under_reservoir))
        while pending_profiles and t >= pending_profiles[0] - 1e-9:
            profiles[round(pending_profiles.pop(0), 6)] = surface_profile(model.phi, grid.dy)
        if t > 0.1 and speed < case.rest_speed:
            state["rest_since"] = state["rest_since"] if state["rest_since"] is not None else t
            if t - state["rest_since"] >= case.rest_duration:
                sim.stop, sim.stop_reason = True, "rest"
        else:
            state["rest_since"] = None
        if len(rec["t"]) % FLUSH_RECORDS == 0:
            front = rec["front"]
            _progress(outputs, {"runout_m": front[-1], "max_front_m": max(front), "t_end_s": t, "steps": model.step_count,
                                "nx": grid.nx, "ny": grid.ny, "model": model_name, "case": asdict(case)}
                      | (extra_summary or {}), rec, sim.history_arrays(), t, model.step_count)

    sim = Simulation(model, stop_time=case.t_end, callbacks=[Callback(observe, every_time=0.01)] + list(callbacks or []),
                     progress=progress)
    t0 = time.perf_counter()
    error = failure = None
    try:
        sim.run()
    except (SimulationError, SolverError, KeyboardInterrupt) as err:  # keep what was computed, then report
        failure = err
        error = str(err) if not isinstance(err, KeyboardInterrupt) else "KeyboardInterrupt"
    wall = time.perf_counter() - t0
    profiles["final"] = surface_profile(model.phi, grid.dy)
    profiles["hvol_final"] = obs.volume_profile(model.phi, grid.dy)
    hist = sim.history_arrays()
    front = np.array(rec["front"])
    area = np.array(rec["area"])
    summary = {
        "runout_m": float(front[-1]) if front.size else 0.0, "max_front_m": float(front.max()) if front.size else 0.0,
        "runout_q99_m": deposit_quantile(profiles["final"], grid.dx, lc),
        "farthest_material_m": farthest_material(model.phi, grid.dx) - lc, "t_end_s": model.time, "steps": model.step_count,
        "nx": grid.nx, "ny": grid.ny, "cells": grid.cells, "h_m": grid.dy, "wall_s": wall,
        "mass_rel_error": float(np.max(np.abs(area - area0)) / area0) if area.size else 0.0,
        "fluidised": bool(case.fluidised and case.pore_pressure_ratio > 0), "rheology": case.rheology,
        "interface_yield": case.interface_yield, "wall_normal_stress": case.wall_normal_stress,
        "yield_pressure": case.yield_pressure, "sigma_location": case.sigma_location,
        "channel_width_m": case.channel_width, "side_wall_friction_angle": (None if case.channel_width is None else
                                                                             side_walls(case).friction_angle),
        "r_neighbourhood": case.r_neighbourhood,
        "active_region": case.active_region,
        "active_region_sides": case.active_region_sides, "threads": case.threads, "version": __version__,
        "stop_reason": sim.stop_reason if error is None else ("interrupted: KeyboardInterrupt"
                                                              if isinstance(failure, KeyboardInterrupt) else f"error: {error}"),
        "pressure_iterations_median": float(np.median(hist["pressure_iterations"])) if "time" in hist else 0.0,
        "pressure_iterations_max": int(np.max(hist["pressure_iterations"])) if "time" in hist else 0,
        "viscous_iterations_median": float(np.median(hist["viscous_iterations"])) if "time" in hist else 0.0,
        "dt_median_s": float(np.median(hist["dt"])) if "time" in hist else 0.0,
        "paper_runout_simulation_m": PAPER_RUNOUT_SIM, "paper_runout_experiment_m": PAPER_RUNOUT_EXP,
        "model": model_name, "model_reason": model_reason,
        "case": asdict(case),
    }
    summary.update(arrest_summary(rec["t"], front, rec["max_granular_speed"], summary["stop_reason"], state["rest_since"]))
    for key in ("picard_iterations",):
        if key in hist:
            summary[key + "_median"] = float(np.median(hist[key]))
    if "picard_r_halvings" in hist:
        summary["picard_r_halvings_total"] = int(np.sum(hist["picard_r_halvings"]))
    if "step_retries" in hist:
        summary["step_retries_total"] = int(np.sum(hist["step_retries"]))
    if rec["energy"]:
        summary["energy"] = energy_summary(rec["energy"][-1])
    summary["observables"] = _observables_summary(rec, profiles["hvol_final"], grid.dx, grid.dy, lc)
    if fluid and rec["t"]:
        summary["fluidisation"] = fluidisation_summary(rec["t"], rec["pf_ratio_reservoir"], rec["pf_ratio_channel"])
    summary.update(extra_summary or {})
    try:
        write_outputs(out, summary, rec, profiles, xs_c - lc, outputs)
        outputs.write_history(hist)
        if rec["energy"]:
            write_energy(out, rec["t"], rec["energy"])
            plot_energy(out)
        if fluid and rec["t"]:
            plot_fluidisation(out)
        plot_front(out, compare_with)
        plot_profiles(out)
    except OSError as err:  # a full disk: the files written before stay complete
        raise OutputError(f"cannot write the outputs in {out} ({err.strerror or err}); the files written before are kept"
                          + (f"; the run had stopped with: {error}" if error else "")) from None
    if isinstance(failure, KeyboardInterrupt):
        raise failure
    if error is not None:
        kind = SolverError if isinstance(failure, SolverError) else SimulationError
        raise kind(error + f" (outputs written to {out})") from failure
    return summary


ENERGY_COLUMNS = ("kinetic", "potential_drop", "gravity_work", "plastic_work", "plastic_negative_work", "viscous_work",
                  "wall_work", "side_wall_work", "residual")


def _energy_row(b: dict) -> dict:
    """One row of energy.csv from ``Model.energy_budget()`` (J per metre of width)."""
    return {"kinetic": b["kinetic"], "potential_drop": b["potential_initial"] - b["potential"],
            "gravity_work": b["gravity_work"], "plastic_work": b["plastic_work"],
            "plastic_negative_work": b["plastic_negative_work"], "viscous_work": b["viscous_work"],
            "wall_work": sum(b["wall_work"].values()), "side_wall_work": b["side_wall_work"], "residual": b["residual"]}


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
    return {"gravity_work_J_per_m": wg, "potential_drop_J_per_m": row["potential_drop"],
            "kinetic": row["kinetic"] / wg, "plastic": row["plastic_work"] / wg, "wall": row["wall_work"] / wg,
            "side_walls": row["side_wall_work"] / wg, "viscous": row["viscous_work"] / wg, "numerical": -row["residual"] / wg,
            "plastic_negative": row["plastic_negative_work"] / wg}


def write_energy(out: Path, times: list, budgets: list) -> None:
    """energy.csv: the energy budget at the recorded times (J per metre of width)."""
    with open(out / "energy.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s"] + [c + "_J_m" for c in ENERGY_COLUMNS])
        for t, b in zip(times, budgets):
            row = _energy_row(b)
            w.writerow([f"{t:.6g}"] + [f"{row[c]:.6g}" for c in ENERGY_COLUMNS])


def plot_energy(out: Path) -> None:
    """energy.png: where gravity's work goes against time (from energy.csv)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = np.genfromtxt(out / "energy.csv", delimiter=",", names=True)
    meta = json.loads((out / "summary.json").read_text())
    fig, ax = plt.subplots(figsize=(10, 4.2))
    t = d["t_s"]
    ax.plot(t, d["gravity_work_J_m"], "k", lw=2, label="work of gravity W_g")
    ax.plot(t, d["potential_drop_J_m"], "k:", lw=1, label="potential energy drop")
    ax.plot(t, d["plastic_work_J_m"], color="C0", label="plastic work ∫τΣ:D")
    ax.plot(t, -d["plastic_negative_work_J_m"], color="C0", ls="--", lw=1,
            label="its negative part (stress given back), sign flipped")
    ax.plot(t, d["wall_work_J_m"], color="C1", label="Coulomb friction, base and back wall")
    if np.any(d["side_wall_work_J_m"] != 0):
        ax.plot(t, d["side_wall_work_J_m"], color="C5", label="friction of the channel's side walls")
    ax.plot(t, d["kinetic_J_m"], color="C2", label="kinetic energy")
    ax.plot(t, d["viscous_work_J_m"], color="C4", lw=1, label="viscous work")
    ax.plot(t, -d["residual_J_m"], color="C3", label="numerical dissipation (− residual)")
    ax.set(xlabel="t (s)", ylabel="J per metre of width", title=_label(meta) + " column: energy budget")
    ax.title.set_fontsize(9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(out / "energy.png", dpi=120)
    plt.close(fig)


def fluidisation_summary(t: list, reservoir: list, channel: list, threshold: float = 0.1) -> dict:
    """summary.json["fluidisation"]: the basal pore-pressure ratio (``basal_pore_pressure_ratio``)
    under the reservoir and in the channel: its largest value in the channel, the last time the
    channel's ratio was at or above ``threshold`` (after which the material that left the
    reservoir slides as a dry material), and both ratios at the end."""
    ch = np.nan_to_num(np.asarray(channel, dtype=float), nan=0.0)
    above = np.nonzero(ch >= threshold)[0]
    return {"reservoir_max": float(np.nanmax(reservoir)), "reservoir_final": float(reservoir[-1]),
            "channel_max": float(ch.max()), "channel_final": float(ch[-1]), "threshold": threshold,
            "channel_fluidised_until_s": float(t[above[-1]]) if above.size else 0.0}


def plot_fluidisation(out: Path) -> None:
    """fluidisation.png: the basal pore pressure over the weight against time, under the
    reservoir and in the channel (from front.csv)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = np.genfromtxt(out / "front.csv", delimiter=",", names=True)
    meta = json.loads((out / "summary.json").read_text())
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    ax.plot(d["t_s"], d["pf_ratio_reservoir"], label="under the reservoir (x < L_c)")
    ax.plot(d["t_s"], d["pf_ratio_channel"], label="in the channel (x > L_c)")
    beta = meta["case"]["pore_pressure_ratio"]
    ax.axhline(beta, color="0.5", ls=":", lw=1, label=f"initial β = {beta:g}")
    ax.axhline(1.0, color="k", ls="--", lw=0.8, label="pore pressure = weight (p_s = 0)")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("basal p_f / (φ ρ_s g h)")
    ax.set_ylim(bottom=0.0)
    ax.set_title(f"{_label(meta)}: fluidisation of the base", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "fluidisation.png", dpi=120)
    plt.close(fig)


#: front.csv's name of a per-record series (with its unit); any other series of numbers the
#: records hold is written under its own name
FRONT_NAMES = {"t": "t_s", "front": "front_m", "area": "area_m2", "max_granular_speed": "max_granular_speed_m_s"}


def front_columns(rec: dict) -> dict:
    """front.csv's columns from the per-record series: every series of numbers in ``rec``."""
    cols = {FRONT_NAMES[k]: rec[k] for k in FRONT_NAMES if k in rec}
    n = len(rec.get("t", ()))
    for k, v in rec.items():
        if k not in FRONT_NAMES and len(v) == n and all(isinstance(x, (int, float)) for x in v):
            cols[k] = v
    return cols


def write_outputs(out: Path, summary: dict, rec: dict, profiles: dict, xs: np.ndarray, outputs=None) -> None:
    """summary.json, front.csv (t, front from the gate, area, largest speed; with pore pressure
    also the basal pore-pressure ratios under the reservoir and in the channel) and profiles.csv
    (surface height at the recorded times against x − L_c): the same files for every model. Each
    file is written atomically (``granrs.io.outputs``); ``outputs``: the run's ``RunOutputs``
    (a restart's earlier rows)."""
    outputs = outputs if outputs is not None else RunOutputs(out)
    outputs.write_json("summary.json", summary)
    outputs.write_columns("front.csv", front_columns(rec))
    keys = list(profiles)
    cols = {"x_from_gate_m": xs} | {(("h_final" if k == "final" else k) if isinstance(k, str) else f"h_{k}"): profiles[k]
                                    for k in keys}
    outputs.write_columns("profiles.csv", cols)


def _progress(outputs, summary: dict, rec: dict, hist: dict, t: float, steps: int) -> None:
    """The outputs written during the run: front.csv and history.npz so far, and a summary whose
    ``stop_reason`` says the run had not finished when it was written."""
    outputs.write_columns("front.csv", front_columns(rec))
    outputs.write_history(hist)
    outputs.write_json("summary.json", summary | {
        "stop_reason": f"incomplete: written during the run at t = {t:.6g} s (step {steps}); a run that ends writes "
                       "its final stop_reason here, so this one was killed or its disk filled"})


def _record_observables(rec: dict, h: np.ndarray, dx: float, cell: float, x_gate: float) -> None:
    """Appends the observables of the profile h (granrs.observables, distances from the gate; fronts
    in cells of size ``cell``) to the record lists of ``rec`` (front.csv's columns)."""
    for k, v in obs.observe_profile(h, dx, cell, x_gate).items():
        rec.setdefault(k, []).append(v)


def _observables_summary(rec: dict, h_final: np.ndarray, dx: float, cell: float, x_gate: float) -> dict:
    """summary.json["observables"]: those of the final volume profile (profiles.csv's hvol_final),
    the centre of mass's travel since the first record, the fronts' largest values over the
    records, the thicknesses in cells in metres and the profile's definition."""
    final = obs.observe_profile(h_final, dx, cell, x_gate)
    keys = obs.observable_keys()
    initial = {k: rec[k][0] for k in keys} if rec.get(keys[0]) else final
    out = obs.summarise(final, initial, {k: rec[k] for k in keys if k in rec})
    out["cell_m"] = cell
    out["distances_from"] = "the gate, x = L_c"
    return out


# ---- model choice -----------------------------------------------------------------------------
# Largest aspect ratio a = H_c/L_c at which the depth-averaged run-out was measured within 5 % of
# the two-phase one at ny = 32 (examples/model_ladder.py → docs/img/model_ladder.csv,
# docs/models.md), per fluidisation state; None: at no measured aspect ratio. Measured points:
# a = 0.5, 1, 2, 4. auto takes the depth-averaged model only at or below the largest aspect
# ratio of an unbroken run of measured agreements starting from the smallest one.
# Measured (k: Savage–Hutter active) against the two-phase model with r_neighbourhood = 0
# fluidised −9.0, −15.3, −15.0, −7.3 %; non-fluidised −11.3, −9.7, +2.5, +16.8 % at
# a = 0.5, 1, 2, 4. No unbroken run of agreement starts at a = 0.5, so auto never takes the
# depth-averaged model. (With the option r_neighbourhood = 2 the non-fluidised a = 0.5 agrees to
# +0.1 %; docs/models.md.)
DEPTH_AVERAGED_MAX_ASPECT = {True: None, False: None}
RUNOUT_TOLERANCE = 0.05


def choose_model(case: ColumnCase) -> tuple[str, str]:
    """(model, reason): the requested model, or for ``auto`` the cheapest one whose documented
    criterion the scene meets (depth-averaged: a ≤ DEPTH_AVERAGED_MAX_ASPECT[fluidised]; otherwise
    the two-phase model)."""
    if case.model != "auto":
        return case.model, "requested"
    fluidised = bool(case.fluidised and case.pore_pressure_ratio > 0)
    state = "fluidised" if fluidised else "non-fluidised"
    a_max = DEPTH_AVERAGED_MAX_ASPECT[fluidised]
    if a_max is not None and case.aspect_ratio <= a_max + 1e-12:
        return "depth-averaged", (f"auto: {state} column with aspect ratio {case.aspect_ratio:g} <= {a_max:g}, where the "
                                  f"depth-averaged run-out was measured within {RUNOUT_TOLERANCE:.0%} of the two-phase "
                                  "model (docs/models.md)")
    limit = "at no measured aspect ratio" if a_max is None else f"only up to aspect ratio {a_max:g}"
    return "two-phase", (f"auto: {state} column with aspect ratio {case.aspect_ratio:g}: the depth-averaged run-out "
                         f"is within {RUNOUT_TOLERANCE:.0%} of the two-phase model {limit} (docs/models.md); "
                         "two-phase model used")


def depth_averaged_front_depth(case: ColumnCase) -> float:
    """Depth at which the depth-averaged front is read: half a cell of the two-phase grid of the
    same case (ny). The two-phase front is the zero of Φ on the lowest row of cells, which sees a
    layer only once it is thicker than dy/2; reading the depth-averaged front at the same depth
    compares like with like (the front at a vanishing depth is reported as runout_thin_m)."""
    return 0.5 * case.domain()[1] / case.ny


def build_depth_averaged(case: ColumnCase):
    """The depth-averaged model of the column (same channel length as the two-phase domain,
    Δx = min(L_c, H_c)/da_resolution, basal friction α_b, supply β_s under the reservoir when
    fluidised; k: Savage & Hutter's active coefficient from α and α_b reduced by the pore
    pressure, or the constant ``earth_pressure``) with its initial condition: h = H_c, β = β_s for
    x < L_c."""
    from ..depth_averaged import DepthAveragedModel, DepthAveragedPore

    case.validate()
    hc, lc = case.column_height, case.width
    length = case.domain()[0]
    cells = int(math.ceil(length / (min(lc, hc) / case.da_resolution)))
    fluidised = bool(case.fluidised and case.pore_pressure_ratio > 0)
    pore = DepthAveragedPore(case.diffusivity, case.pore_pressure_ratio, lc) if fluidised else None
    sh = case.earth_pressure == "savage-hutter"
    m = DepthAveragedModel(cells, length, gravity=G, earth_pressure=1.0 if sh else float(case.earth_pressure),
                           basal_friction_angle=case.wall_friction_angle, cfl=0.4, dry_depth=1e-6 * hc, pore=pore,
                           internal_friction_angle=case.friction_angle if sh else None)
    inside = m.x < lc
    m.set_state(h=np.where(inside, hc, 0.0), beta=np.where(inside, case.pore_pressure_ratio if fluidised else 0.0, 0.0))
    return m


def run_column_depth_averaged(case: ColumnCase, out: Path, progress: bool = True, compare_with: Optional[Path] = None,
                              extra_summary: Optional[dict] = None, reason: str = "requested") -> dict:
    """The column with the depth-averaged model: same records, rest criterion, outputs and plots
    as :func:`run_column` (front read at :func:`depth_averaged_front_depth`)."""
    out.mkdir(parents=True, exist_ok=True)
    m = build_depth_averaged(case)
    lc, hc = case.width, case.column_height
    threshold = depth_averaged_front_depth(case)
    mass0 = m.mass()
    rec = {"t": [], "front": [], "area": [], "max_granular_speed": []}
    profiles = {}
    pending = sorted(case.profile_times)
    rest_since = None
    stop_reason = "t_end"
    error = None
    t0 = time.perf_counter()
    try:
        k = 0
        while True:
            t = m.time
            xf = m.front(threshold)
            if xf > m.length - 3 * m.dx or float(np.sum(m.h[-3:])) * m.dx > 0.01 * mass0:
                raise SimulationError(f"the granular material reached the far end of the domain (x = {xf:.3f} m of "
                                      f"{m.length:.3f} m) at t = {t:.3f} s: increase --length (grid.length in a run file)")
            speed = m.max_speed()
            rec["t"].append(t)
            rec["front"].append(xf - lc)
            rec["area"].append(m.mass())
            rec["max_granular_speed"].append(speed)
            _record_observables(rec, m.h, m.dx, 2 * threshold, lc)
            while pending and t >= pending[0] - 1e-9:
                profiles[round(pending.pop(0), 6)] = m.h.copy()
            if t > 0.1 and speed < case.rest_speed:
                rest_since = rest_since if rest_since is not None else t
                if t - rest_since >= case.rest_duration:
                    stop_reason = "rest"
                    break
            else:
                rest_since = None
            if t >= case.t_end - 1e-12:
                break
            k += 1
            m.advance(min(case.t_end, 0.01 * k))
            if progress:
                print(f"\rdepth-averaged: t = {m.time:.2f} s, front {xf - lc:.3f} m", end="", flush=True)
    except (SimulationError, KeyboardInterrupt) as err:
        error = err
        stop_reason = "interrupted: KeyboardInterrupt" if isinstance(err, KeyboardInterrupt) else f"error: {err}"
    if progress:
        print()
    wall = time.perf_counter() - t0
    profiles["final"] = m.h.copy()
    front = np.array(rec["front"])
    area = np.array(rec["area"])
    summary = {
        "runout_m": float(front[-1]) if front.size else 0.0, "max_front_m": float(front.max()) if front.size else 0.0,
        "runout_thin_m": m.front(1e-3 * hc) - lc, "farthest_material_m": m.front(1e-6 * hc) - lc,
        "runout_q99_m": deposit_quantile(profiles["final"], m.dx, lc),
        "front_depth_m": threshold, "t_end_s": m.time, "steps": m.step_count,
        "nx": m.cells, "ny": case.ny, "cells": m.cells, "h_m": m.dx, "wall_s": wall,
        "mass_rel_error": float(np.max(np.abs(area - mass0)) / mass0) if area.size else 0.0,
        "fluidised": m.pore is not None, "rheology": "Coulomb basal friction (depth-averaged)",
        "threads": 1, "version": __version__, "stop_reason": stop_reason,
        "paper_runout_simulation_m": PAPER_RUNOUT_SIM, "paper_runout_experiment_m": PAPER_RUNOUT_EXP,
        "model": "depth-averaged", "model_reason": reason, "case": asdict(case),
    }
    summary.update(arrest_summary(rec["t"], front, rec["max_granular_speed"], stop_reason, rest_since))
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


def _label(meta: dict) -> str:
    state = "fluidised" if meta["fluidised"] else "non-fluidised"
    if meta.get("model") == "depth-averaged":
        return f"{state}, depth-averaged ({meta['cells']} cells)"
    model = ", granular-only" if meta.get("model") == "granular" else ""
    window = f", active region {meta['active_region']}" if meta.get("active_region") else ""
    walls = f", side walls {100 * meta['channel_width_m']:g} cm apart" if meta.get("channel_width_m") else ""
    return f"{state}{model}{walls}{window}, ny = {meta['ny']}"


def _read_front(path: Path):
    meta = json.loads((path / "summary.json").read_text())
    if len((path / "front.csv").read_text().splitlines()) < 2:  # a run that failed before its first record
        return np.zeros(0), np.zeros(0), meta
    data = np.genfromtxt(path / "front.csv", delimiter=",", skip_header=1, ndmin=2)
    return data[:, 0], data[:, 1], meta


def _front_label(meta: dict) -> str:
    """Legend entry of a run on front.png: a run that came to rest has a run-out; one cut at
    t_end has only the front it reached then."""
    reason = str(meta.get("stop_reason", ""))
    if reason == "rest":
        return _label(meta) + f": run-out {meta['runout_m']:.3f} m (at rest)"
    why = "stopped by an error" if reason.startswith(("error", "interrupted")) else "not at rest"
    return _label(meta) + f": front {meta['runout_m']:.3f} m at t = {meta.get('t_end_s', 0.0):g} s ({why})"


def _front_band(path: Path) -> Optional[dict]:
    """The thickness fronts of front.csv in ``path`` by thickness in metres (None for a front.csv
    without them)."""
    d = np.genfromtxt(path / "front.csv", delimiter=",", names=True)
    keys = [k for k in obs.front_keys(cells=()) if k in (d.dtype.names or ())]
    if not keys or d.ndim == 0:
        return None
    return {"t": d["t_s"], "fronts": [(k, d[k]) for k in keys]}


def plot_front(out: Path, compare_with: Optional[Path] = None) -> None:
    """front.png: the lowest-row front (bold) and the band of the thickness fronts of the volume
    profile (from 1 to 20 mm, shaded; each thickness a thin line) against time, for this run and
    for ``compare_with``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    runs = [out] + ([compare_with] if compare_with is not None and (compare_with / "front.csv").exists() else [])
    for k, path in enumerate(runs):
        t, x, meta = _read_front(path)
        label = _front_label(meta)
        ax.plot(t, x, f"C{k}-", lw=2, label=label)
        band = _front_band(path) if t.size > 1 else None
        if band is not None:
            lo, hi = band["fronts"][-1][1], band["fronts"][0][1]  # the thickest and the thinnest
            ax.fill_between(band["t"], np.nan_to_num(lo), np.nan_to_num(hi), color=f"C{k}", alpha=0.15, lw=0,
                            label=f"fronts at h = {band['fronts'][0][0][7:-2]} to {band['fronts'][-1][0][7:-2]} "
                                  "(volume profile)")
            for name, xf in band["fronts"]:
                ax.plot(band["t"], xf, f"C{k}", lw=0.6, alpha=0.8)
                ax.annotate(name[7:-2], (band["t"][-1], xf[-1]), fontsize=6, color=f"C{k}",
                            xytext=(2, 0), textcoords="offset points", va="center")
    ax.axhline(PAPER_RUNOUT_SIM, color="k", ls="--", lw=1, label=f"paper, simulation: {PAPER_RUNOUT_SIM} m")
    ax.axhline(PAPER_RUNOUT_EXP, color="k", ls=":", lw=1.5, label=f"paper, experiment: {PAPER_RUNOUT_EXP} m")
    ax.set(xlabel="t (s)", ylabel="front position from the gate (m)",
           title="Column collapse: front (bold: lowest row of cells) and thickness fronts")
    ax.title.set_fontsize(10)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(out / "front.png", dpi=120)
    plt.close(fig)


def plot_profiles(out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    header = (out / "profiles.csv").read_text().splitlines()[0].split(",")
    data = np.genfromtxt(out / "profiles.csv", delimiter=",", skip_header=1)
    meta = json.loads((out / "summary.json").read_text())
    cols = [(k, name) for k, name in enumerate(header) if name.startswith("h_")]
    fig, ax = plt.subplots(figsize=(9, 3.8))
    cmap = plt.get_cmap("viridis")
    for n, (k, name) in enumerate(cols):
        label = "final deposit" if name == "h_final" else f"t = {float(name[2:]):g} s"
        style = dict(color="k", lw=2) if name == "h_final" else dict(color=cmap(n / max(1, len(cols) - 1)), lw=1)
        ax.plot(data[:, 0], data[:, k], label=label, **style)
    if "hvol_final" in header and meta.get("model") != "depth-averaged":
        ax.plot(data[:, 0], data[:, header.index("hvol_final")], color="C3", ls="--", lw=1.2,
                label="final, volume per column")
    ax.axvline(0.0, color="grey", lw=0.8)
    ax.axvline(PAPER_RUNOUT_SIM, color="k", ls="--", lw=1, label="paper run-out (simulation)")
    ax.axvline(PAPER_RUNOUT_EXP, color="k", ls=":", lw=1.5, label="paper run-out (experiment)")
    ax.set(xlabel="x − L_c (m), gate at 0", ylabel="h (m): surface height; dashed: volume per column",
           title=_label(meta) + " column: surface profiles\n"
                 "(paper: thickest near the gate, gentle decrease downstream)")
    ax.title.set_fontsize(9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(out / "profiles.png", dpi=120)
    plt.close(fig)
