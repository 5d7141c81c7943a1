"""The column's scene: :class:`ColumnCase` (the paper's parameters as defaults), its validation, its
domain and grid, and the paper's run-outs."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Union

from ... import options
from ..._granrs import ParameterError
from ...grid import Grid
from ...model import check_side_walls, estimate_memory, memory_check

G = 9.81
PAPER_RUNOUT_SIM = 1.6874
PAPER_RUNOUT_EXP = 1.8443
MODELS = ("two-phase", "granular", "depth-averaged")

#: The ranges of the scene's numbers (the run-file keys and ``granrs keys`` read them here).
SCENE_RANGES = {
    "aspect_ratio": (0.1, 20.0),
    "width": (1e-3, 10.0),
    "pore_pressure_ratio": (0.0, 1.0),
    "t_end": (1e-6, 1e4),
    "granular_viscosity": (1e-8, 1e6),
    "solid_fraction": (0.01, 0.74),
    "ny": (8, 4096),
}
#: The scene's choices: the air supply through the reservoir's base and the back wall.
SCENE_CHOICES = {"air_supply": ("injection", "literal"), "back_wall": ("coulomb", "free-slip")}
#: The case's fields that are options of the Rust schema, as (key, room): their ranges, units and
#: choices are the schema's (checked in Rust); their defaults are the column's own (below).
OPTION_FIELDS = {
    "friction_angle": ("friction_angle", "drucker-prager"),
    "wall_friction_angle": ("friction_angle", "coulomb"),
    "diffusivity": ("diffusivity", "pore_pressure"),
    "pore_formulation": ("formulation", "pore_pressure"),
    "kappa_air": ("kappa_air", "pore_pressure"),
    "cfl": ("cfl", None),
    "threads": ("threads", None),
    "picard_tol": ("picard_tol", None),
    "theta": ("theta", None),
    "r_neighbourhood": ("r_neighbourhood", None),
    "sigma_location": ("sigma_location", None),
    "interface_yield": ("interface_yield", None),
    "wall_normal_stress": ("wall_normal_stress", None),
    "yield_pressure": ("yield_pressure", None),
    "proximal_restarts": ("proximal_restarts", None),
    "active_region": ("active_region", None),
    "active_region_sides": ("active_region_sides", None),
    "step_retries": ("step_retries", None),
    "mass_correction": ("mass_correction", None),
}
#: The schema keys of the flat options among OPTION_FIELDS, with their field names.
OPTION_FIELD_KEYS = {key: name for name, (key, room) in OPTION_FIELDS.items() if room is None}
#: The column's numerics where they differ from the schema's defaults (the measured reasons are
#: in the package's docstring): convection by upwind WENO5.
COLUMN_NUMERICS = {"convection_scheme": "weno5"}


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
    friction_angle: float = options.spec("friction_angle", "drucker-prager").default
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
    # any other option of the Rust schema by its key (granrs.Numerics, granrs.options), over the
    # column's numerics (COLUMN_NUMERICS and the fields above): e.g. {"pressure_rtol": 1e-10}
    numerics: dict = field(default_factory=dict)
    rest_speed: float = 5e-3
    rest_duration: float = 0.05
    profile_times: list = field(default_factory=lambda: [0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0])
    # which model: "two-phase" (default), "granular" (the air not resolved: a free surface at p = 0),
    # "depth-averaged" (docs/howto/choosing-a-model.md)
    model: str = "two-phase"
    # depth-averaged model only: earth-pressure coefficient k ("savage-hutter": the active
    # coefficient from friction_angle and wall_friction_angle, reduced by the pore pressure; or a
    # number; docs/models.md) and cells across min(L_c, H_c)
    earth_pressure: Union[str, float] = "savage-hutter"
    da_resolution: int = 64

    def validate(self) -> None:
        for name, (lo, hi) in SCENE_RANGES.items():
            v = getattr(self, name)
            if name == "ny":
                if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                    raise ParameterError(f"invalid parameter `ny` = {v!r}: allowed an integer in [{lo}, {hi}]")
            elif not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or not lo <= v <= hi:
                raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed a number in [{lo}, {hi}]")
        for name, (key, room) in OPTION_FIELDS.items():
            v = getattr(self, name)
            if not (name == "active_region" and v is None):
                options.spec(key, room).check(v, name)
        for name, v, lo, what in (
            ("length", self.length, self.width, "the gate at x = width"),
            ("height", self.height, self.column_height, "the column height aspect_ratio × width"),
        ):
            if v is not None and (
                isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo < v <= 1000.0
            ):
                raise ParameterError(
                    f"invalid parameter `{name}` = {v!r}: allowed None (the default) or a number of metres "
                    f"in ({lo:g}, 1000] (beyond {what} = {lo:g} m)"
                )
        if self.channel_width is not None:
            angle = self.wall_friction_angle if self.side_wall_friction_angle is None else self.side_wall_friction_angle
            check_side_walls(self.channel_width, angle, "channel_width", "side_wall_friction_angle")
        elif self.side_wall_friction_angle is not None:
            raise ParameterError(
                f"invalid parameter `side_wall_friction_angle` = {self.side_wall_friction_angle!r}: "
                "allowed only with a channel_width"
            )
        if not isinstance(self.numerics, dict):
            raise ParameterError(
                f"invalid parameter `numerics` = {self.numerics!r}: allowed a dict of option keys "
                "(granrs.options.FLAT) to values"
            )
        for key, v in self.numerics.items():
            if key in OPTION_FIELD_KEYS:
                raise ParameterError(
                    f"invalid parameter `numerics.{key}`: allowed as the case's field "
                    f"`{OPTION_FIELD_KEYS[key]}`, not in numerics"
                )
            options.spec(key).check(v, f"numerics.{key}")
        for name, choices in SCENE_CHOICES.items():
            if getattr(self, name) not in choices:
                raise ParameterError(
                    f"invalid parameter `{name}` = {getattr(self, name)!r}: allowed "
                    + ", ".join(repr(c) for c in choices)
                )
        if self.model not in MODELS:
            raise ParameterError(
                f"invalid parameter `model` = {self.model!r}: allowed 'two-phase', 'granular' or "
                "'depth-averaged' (no automatic choice: docs/howto/choosing-a-model.md)"
            )
        if self.earth_pressure != "savage-hutter" and (
            not isinstance(self.earth_pressure, (int, float))
            or isinstance(self.earth_pressure, bool)
            or not 0.01 <= self.earth_pressure <= 100.0
        ):
            raise ParameterError(
                f"invalid parameter `earth_pressure` = {self.earth_pressure!r}: allowed 'savage-hutter' "
                "or a number in [0.01, 100]"
            )
        if not isinstance(self.da_resolution, int) or not 4 <= self.da_resolution <= 4096:
            raise ParameterError(
                f"invalid parameter `da_resolution` = {self.da_resolution!r}: allowed an integer in [4, 4096]"
            )
        if self.rheology not in ("drucker-prager", "mu-i"):
            raise ParameterError(
                f"invalid parameter `rheology` = {self.rheology!r}: allowed 'drucker-prager' or 'mu-i'"
            )
        if self.model != "depth-averaged":  # memory before any work (granrs.model.estimate_memory)
            grid = self.grid()
            memory_check(
                grid,
                estimate_memory(
                    grid,
                    pore_pressure=bool(self.fluidised and self.pore_pressure_ratio > 0),
                    air="free-surface" if self.model == "granular" else "resolved",
                    side_walls=self.channel_width is not None,
                    step_retries=self.step_retries,
                ),
                f"the column's {self.model} model",
            )

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
