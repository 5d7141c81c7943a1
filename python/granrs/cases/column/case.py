"""The column's scene: :class:`ColumnCase` (the paper's parameters as defaults), its validation, its
domain and grid, and the paper's run-outs.

A case states the scene in small objects of its own (the geometry :class:`ColumnGeometry`, the
grains :class:`Grains`, the fluidisation :class:`Fluidisation`, the rest criterion
:class:`RestCriterion`) and a few fields (channel, grid, run), and takes the package's physics
objects for the rest: the rheology with its bi-projection, the Coulomb base, the pore pressure,
the side walls, the interface, the active region, the clock and the numerics. Their ranges, units and docs are those of the Rust schema
(``granrs.options``); where the column's choice differs from the schema's default, it is stated
once below, in the column's default object, with the measurement behind it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Optional

from ... import options
from ..._granrs import ParameterError
from ...boundary import Coulomb, CoulombWall
from ...depth_averaged import DepthAveraged
from ...grid import Grid
from ...model import PorePressure, SideWalls, estimate_memory, memory_check
from ...options import ActiveRegion, BiProjection, Interface, Numerics, TimeStepping
from ...rheology import Bingham, DruckerPrager, MuI

G = 9.81
PAPER_RUNOUT_SIM = 1.6874
PAPER_RUNOUT_EXP = 1.8443
MODELS = ("two-phase", "granular", "depth-averaged")

#: The ranges of the scene's numbers outside its objects (the run-file keys and ``granrs keys``
#: read them here).
SCENE_RANGES = {"t_end": (1e-6, 1e4), "ny": (8, 4096)}
#: The scene's choices outside its objects: the back wall.
SCENE_CHOICES = {"back_wall": ("coulomb", "free-slip")}
#: The rheologies of the column (the law's name in the run files: the Rust schema's room).
RHEOLOGIES = {"drucker-prager": DruckerPrager, "mu-i": MuI, "bingham": Bingham}


def column_rheology() -> DruckerPrager:
    """The column's rheology: the paper's D-P law (α: the schema's 27°) with η_s = 0.1 Pa s (the
    paper's), and the column's bi-projection: pseudo-relaxation θ = 0.8 (geometric ratio of the
    Picard increment about 1 − θ) and the stress-weighted increment tolerance 1e-3 (max |τ ΔΣ|/τ_max:
    a stress change of ~3 Pa against stresses of 10²–10³ Pa; at ny = 32–64 the increment stalls
    transiently between 1e-4 and 5e-4, so 1e-4 stopped runs; docs/validation.md, "Column collapse")."""
    return DruckerPrager(viscosity=0.1, projection=BiProjection(theta=0.8, tolerance=1e-3))


def jop_mu_i(
    friction_angle: float,
    *,
    grain_diameter: float,
    grain_density: float,
    viscosity: float,
    projection: Optional[BiProjection] = None,
) -> MuI:
    """μ(I) for the column's glass beads: the paper gives no μ(I) constants, so μ_s = tan α with
    the Δμ = μ₂ − μ_s = 0.26 and I₀ = 0.279 of Jop, Forterre & Pouliquen (2006, Nature 441) for
    glass beads (an assumption); ``grain_diameter`` and ``grain_density`` are the case's
    ``grains.diameter`` and ``grains.density``."""
    mu_s = math.tan(math.radians(options.spec("friction_angle", "drucker-prager").check(friction_angle)))
    return MuI(
        mu_s=mu_s,
        mu_2=mu_s + 0.26,
        i0=0.279,
        grain_diameter=grain_diameter,
        grain_density=grain_density,
        viscosity=viscosity,
        projection=projection,
    )


def column_pore_pressure() -> PorePressure:
    """The column's pore pressure: κ_f = 0.035 m² s⁻¹ (the paper's) and, for the 'kappa-infinity'
    formulations, κ_∞ = 1e8 m² s⁻¹ instead of the paper's 1e16: it places the same boundary
    (κ_∞(1 − H_ε) exceeds κ_f wherever 1 − H_ε > 4e-10) and keeps the pore-pressure CG in double
    precision (with 1e16, κ_∞/κ_f = 3e17, it stalled at t = 2.23 s on the fluidised column at
    ny = 32). The basal supply is the scene's (``pore_pressure_ratio``, ``air_supply``)."""
    return PorePressure(diffusivity=0.035, kappa_air=1e8)


def column_numerics() -> Numerics:
    """The column's numerics: convection by upwind WENO5 (the centred form lets the air's shear
    layer over the flowing grains oscillate at the grid scale, 5–9 m/s at ny = 32–64, until
    droplets of grains are flung down the channel)."""
    return Numerics(convection_scheme="weno5")


def column_interface() -> Interface:
    """The column's interface: the level set's global mass correction (without it the dense area
    grows by 6 % at ny = 32 by t = 3 s: thin films; docs/validation.md, dam break)."""
    return Interface(mass_correction=True)


def _number(name: str, v, lo: float, hi: float, integer: bool = False) -> None:
    if integer:
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed an integer in [{lo}, {hi}]")
    elif isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
        raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed a number in [{lo:g}, {hi:g}]")


def _instance(name: str, v, kinds: tuple, words: str, optional: bool = False) -> None:
    if not (isinstance(v, kinds) or optional and v is None):
        raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed {words}" + (" or None" if optional else ""))


def _check_fields(obj, prefix: str) -> None:
    """ParameterError naming ``prefix.field`` and its range for the first number of ``obj`` (a
    scene object with ``RANGES``) out of its range."""
    for name, (lo, hi) in obj.RANGES.items():
        _number(f"{prefix}.{name}", getattr(obj, name), lo, hi)


@dataclass(frozen=True)
class ColumnGeometry:
    """The column and its channel: ``aspect_ratio`` a = H_c/L_c, ``width`` L_c [m] (the gate at
    x = L_c), the domain's ``length`` and ``height`` [m] (None: L_c + 8.25 H_c and 1.125 H_c, see
    :meth:`ColumnCase.domain`). ParameterError naming the field (``geometry.width``, ...) and its
    range when it is made."""

    aspect_ratio: float = 2.0
    width: float = 0.20
    length: Optional[float] = None
    height: Optional[float] = None

    #: the range of each number (the run-file keys ``geometry.*`` and ``granrs keys`` read them here)
    RANGES = {"aspect_ratio": (0.1, 20.0), "width": (1e-3, 10.0)}

    def __post_init__(self):
        _check_fields(self, "geometry")
        for name, v, lo, what in (
            ("length", self.length, self.width, "the gate at x = width"),
            ("height", self.height, self.column_height, "the column height aspect_ratio × width"),
        ):
            if v is not None and (
                isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo < v <= 1000.0
            ):
                raise ParameterError(
                    f"invalid parameter `geometry.{name}` = {v!r}: allowed None (the default) or a number of "
                    f"metres in ({lo:g}, 1000] (beyond {what} = {lo:g} m)"
                )

    @property
    def column_height(self) -> float:
        """H_c = a L_c [m]."""
        return self.aspect_ratio * self.width


@dataclass(frozen=True)
class Grains:
    """The granular material: ``solid_fraction`` φ of the column, the grains' ``density`` ρ_s
    [kg m⁻³] and ``diameter`` d_s [m] (read by μ(I)). ParameterError naming the field
    (``grains.density``, ...) and its range when it is made."""

    solid_fraction: float = 0.58
    density: float = 2500.0
    diameter: float = 75e-6

    #: the range of each field (the run-file keys ``grains.*`` and ``granrs keys`` read them here)
    RANGES = {"solid_fraction": (0.01, 0.74), "density": (1.0, 25000.0), "diameter": (1e-7, 0.1)}

    def __post_init__(self):
        _check_fields(self, "grains")


@dataclass(frozen=True)
class Fluidisation:
    """The pore gas pressure of the column: ``fluidised`` (on or off), ``pore_pressure_ratio`` β
    (initial p_f = β φρ_s g (H_c − y) and the basal supply under the reservoir) and ``air_supply``:
    'injection' (∂p_f/∂y = −β φρ_s g, gas flowing up into the column, as the paper's text
    describes and its initial p_f implies) or 'literal' (the printed ∂p_f/∂n = −β φρ_s g with n
    the outward normal: an outflow; docs/validation.md, "Observables"). ParameterError naming
    the field (``fluidisation.pore_pressure_ratio``, ...) and what is allowed when it is made."""

    fluidised: bool = True
    pore_pressure_ratio: float = 0.9
    air_supply: str = "injection"

    #: the range of each number and the choices (the run-file keys ``fluidisation.*`` read them here)
    RANGES = {"pore_pressure_ratio": (0.0, 1.0)}
    CHOICES = {"air_supply": ("injection", "literal")}

    def __post_init__(self):
        if not isinstance(self.fluidised, bool):
            raise ParameterError(
                f"invalid parameter `fluidisation.fluidised` = {self.fluidised!r}: allowed True or False"
            )
        _check_fields(self, "fluidisation")
        if self.air_supply not in self.CHOICES["air_supply"]:
            raise ParameterError(
                f"invalid parameter `fluidisation.air_supply` = {self.air_supply!r}: allowed "
                + ", ".join(repr(c) for c in self.CHOICES["air_supply"])
            )

    @property
    def active(self) -> bool:
        """Whether a pore pressure is solved: fluidised with β > 0."""
        return bool(self.fluidised and self.pore_pressure_ratio > 0)


@dataclass(frozen=True)
class RestCriterion:
    """When the column is at rest and its run stops: after ``after`` [s] (the release), the
    largest speed of the granular phase stays below ``speed`` [m/s] for ``duration`` [s]. The
    defaults: 5 mm/s (0.18 % of √(2 g H_c) for the paper's column) for 0.05 s after 0.1 s.
    ParameterError naming the field (``rest.speed``, ...) and its range when it is made."""

    speed: float = 5e-3
    duration: float = 0.05
    after: float = 0.1

    #: the range of each field (the run-file keys ``rest.*`` and ``granrs keys`` read them here)
    RANGES = {"speed": (1e-9, 10.0), "duration": (0.0, 1e4), "after": (0.0, 1e4)}

    def __post_init__(self):
        _check_fields(self, "rest")


@dataclass
class ColumnCase:
    """The column collapse: the scene, with the paper's values as defaults, and its physics.

    Scene: the ``geometry`` (:class:`ColumnGeometry`: aspect ratio, width, the domain's length
    and height), the ``grains`` (:class:`Grains`: solid fraction, density, diameter), the
    ``fluidisation`` (:class:`Fluidisation`: on or off, pore-pressure ratio β, air supply), the
    ``back_wall`` at x = 0: 'coulomb' (the base's friction, the paper's) or 'free-slip' (the
    cross-code check against Basilisk), ``ny`` cells over the domain's height, ``t_end`` [s], the
    ``rest`` criterion that stops the run earlier (:class:`RestCriterion`), the ``profile_times``
    of profiles.csv [s], the ``model`` ('two-phase', 'granular' or 'depth-averaged';
    docs/howto/choosing-a-model.md) and, for the depth-averaged model, its own choices
    ``depth_averaged`` (``granrs.DepthAveraged``: the lateral-pressure closure, the resolution,
    the pore-pressure transport). A field that the case's model does not read is refused when it
    differs from the default (``DepthAveraged.refuse_unused``).

    Physics: ``rheology`` (``DruckerPrager``, ``MuI`` or ``Bingham`` with its
    ``BiProjection``; :func:`column_rheology`), ``base`` (the ``CoulombWall`` of the base and of a
    Coulomb back wall, the paper's α_b = 15°), ``pore_pressure`` (``PorePressure``, used when
    fluidised; :func:`column_pore_pressure`), ``side_walls`` (None, the paper's 2D model, or
    ``SideWalls(width, friction_angle)``), ``active_region`` (None, the whole domain, or an
    ``ActiveRegion``), ``time`` (``TimeStepping``), ``numerics`` (``Numerics``, the options of
    no other object; :func:`column_numerics`), ``interface`` (``Interface``;
    :func:`column_interface`) and ``threads``.
    """

    geometry: ColumnGeometry = field(default_factory=ColumnGeometry)
    grains: Grains = field(default_factory=Grains)
    fluidisation: Fluidisation = field(default_factory=Fluidisation)
    back_wall: str = "coulomb"
    ny: int = 32
    t_end: float = 3.0
    rest: RestCriterion = field(default_factory=RestCriterion)
    profile_times: list = field(default_factory=lambda: [0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0])
    model: str = "two-phase"
    depth_averaged: DepthAveraged = field(default_factory=DepthAveraged)
    rheology: Any = field(default_factory=column_rheology)
    base: Coulomb = field(default_factory=lambda: CoulombWall(15.0))
    pore_pressure: PorePressure = field(default_factory=column_pore_pressure)
    side_walls: Optional[SideWalls] = None
    active_region: Optional[ActiveRegion] = None
    time: Any = field(default_factory=TimeStepping)
    numerics: Any = field(default_factory=column_numerics)
    interface: Any = field(default_factory=column_interface)
    threads: int = options.spec("threads").default

    def validate(self) -> None:
        """ParameterError naming the first bad field (its allowed values) before any work; the
        memory the model needs is checked against the memory available."""
        for name, cls in (("geometry", ColumnGeometry), ("grains", Grains), ("fluidisation", Fluidisation)):
            _instance(name, getattr(self, name), (cls,), f"a granrs.cases.column.{cls.__name__}(...)")
        for name, (lo, hi) in SCENE_RANGES.items():
            _number(name, getattr(self, name), lo, hi, integer=name == "ny")
        _instance("rest", self.rest, (RestCriterion,), "a granrs.cases.column.RestCriterion(speed, duration)")
        for name, choices in SCENE_CHOICES.items():
            if getattr(self, name) not in choices:
                raise ParameterError(
                    f"invalid parameter `{name}` = {getattr(self, name)!r}: allowed "
                    + ", ".join(repr(c) for c in choices)
                )
        if not isinstance(self.profile_times, (list, tuple)) or not all(
            isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t) and t >= 0
            for t in self.profile_times
        ):
            raise ParameterError(
                f"invalid parameter `profile_times` = {self.profile_times!r}: allowed a list of times >= 0 (s)"
            )
        if self.model not in MODELS:
            raise ParameterError(
                f"invalid parameter `model` = {self.model!r}: allowed 'two-phase', 'granular' or "
                "'depth-averaged' (no automatic choice: docs/howto/choosing-a-model.md)"
            )
        _instance(
            "depth_averaged", self.depth_averaged, (DepthAveraged,), "a granrs.DepthAveraged(closure, resolution, ...)"
        )
        _instance(
            "rheology", self.rheology, tuple(RHEOLOGIES.values()), "granrs.DruckerPrager(...), MuI(...) or Bingham(...)"
        )
        if self.rheology.viscosity is None:
            raise ParameterError(
                f"invalid parameter `rheology.viscosity` = None: allowed the granular phase's viscosity η_s "
                f"(Pa s), e.g. {type(self.rheology).__name__}(..., viscosity=0.1)"
            )
        if isinstance(self.rheology, MuI):
            for name, own in (("grain_diameter", "diameter"), ("grain_density", "density")):
                if getattr(self.rheology, name) != getattr(self.grains, own):
                    raise ParameterError(
                        f"invalid parameter `rheology.{name}` = {getattr(self.rheology, name)!r}: allowed the "
                        f"case's grains.{own} = {getattr(self.grains, own)!r} (granrs.cases.column.jop_mu_i builds it)"
                    )
        _instance("base", self.base, (Coulomb,), "a granrs.CoulombWall(friction_angle)")
        _instance("pore_pressure", self.pore_pressure, (PorePressure,), "a granrs.PorePressure(diffusivity, ...)")
        for name in ("basal_gradient", "basal_x_min", "basal_x_max"):
            if getattr(self.pore_pressure, name) is not None:
                raise ParameterError(
                    f"invalid parameter `pore_pressure.{name}` = {getattr(self.pore_pressure, name)!r}: allowed "
                    "None (the column's air supply is the scene's: fluidisation.pore_pressure_ratio, "
                    "fluidisation.air_supply, geometry.width)"
                )
        _instance("side_walls", self.side_walls, (SideWalls,), "a granrs.SideWalls(width, friction_angle)", True)
        _instance("active_region", self.active_region, (ActiveRegion,), "a granrs.ActiveRegion(band, ...)", True)
        if self.active_region is not None and self.active_region.band is None:
            raise ParameterError(
                "invalid parameter `active_region.band` = None: allowed an integer number of cells of air "
                f"({options.spec('active_region').allowed}); active_region=None runs on the whole domain"
            )
        for name, cls in (("time", TimeStepping), ("numerics", Numerics), ("interface", Interface)):
            _instance(name, getattr(self, name), (cls,), f"a granrs.{cls.__name__}(...)")
        options.spec("threads").check(self.threads, "threads")
        options.merge(self.numerics, self.objects())  # an option set in two places is refused
        self.depth_averaged.refuse_unused(self, ColumnCase())  # what the case's model does not read
        if self.model != "depth-averaged":  # memory before any work (granrs.model.estimate_memory)
            grid = self.grid()
            memory_check(
                grid,
                estimate_memory(
                    grid,
                    pore_pressure=self.fluidisation.active,
                    air="free-surface" if self.model == "granular" else "resolved",
                    side_walls=self.side_walls is not None,
                    step_retries=self.time.step_retries,
                ),
                f"the column's {self.model} model",
            )

    def objects(self) -> dict:
        """The case's option objects by name, as ``options.merge`` takes them (the rheology's
        bi-projection, the clock, the interface, the active region)."""
        objs = {"time": self.time, "interface": self.interface}
        if self.rheology.projection is not None:
            objs["rheology.projection"] = self.rheology.projection
        if self.active_region is not None:
            objs["active_region"] = self.active_region
        return objs

    def with_options(self, **changes) -> ColumnCase:
        """A copy of the case with model options changed by their schema keys
        (``granrs.options.FLAT``: ``theta``, ``picard_tol``, ``dt``, ``proximal_restarts``, ...),
        each in the object of its room (``granrs.options.ROOM_OBJECTS``: the rheology's
        bi-projection, the clock, the interface, the active region) or else in the numerics
        (``threads``: the case's own). ParameterError for a key that is not an option, or an
        option of an active region the case does not have."""
        case = dataclasses.replace(self)
        for key, value in changes.items():
            s = options.spec(key)
            if key == "threads":
                case.threads = value
                continue
            holders = {
                "time": ("time", case.time),
                "bi_projection": ("rheology.projection", case.rheology.projection or BiProjection()),
                "interface": ("interface", case.interface),
                "active_region": ("active_region", case.active_region),
            }
            name, obj = holders.get(s.room) or ("numerics", case.numerics)
            if obj is None:
                raise ParameterError(
                    f"invalid parameter `{key}` = {value!r}: allowed only with an active_region=ActiveRegion(band)"
                )
            field_name = next(n for n, f in obj.FIELDS.items() if f.key == key)
            obj = dataclasses.replace(obj, **{field_name: value})
            if name == "rheology.projection":
                case.rheology = dataclasses.replace(case.rheology, projection=obj)
            else:
                setattr(case, name, obj)
        return case

    @property
    def column_height(self) -> float:
        """H_c = a L_c [m] (``geometry.column_height``)."""
        return self.geometry.column_height

    @property
    def mixture_density(self) -> float:
        """φ ρ_s [kg m⁻³] of the column."""
        return self.grains.solid_fraction * self.grains.density

    @property
    def internal_friction_angle(self) -> float:
        """α of the rheology in degrees (μ(I): atan μ_s); the depth-averaged model's φ."""
        if isinstance(self.rheology, DruckerPrager):
            return self.rheology.friction_angle
        if isinstance(self.rheology, MuI):
            return math.degrees(math.atan(self.rheology.mu_s))
        raise ParameterError(
            f"invalid parameter `rheology` = {self.rheology!r} with the depth-averaged model: allowed "
            "DruckerPrager(...) or MuI(...) (a friction angle)"
        )

    def summary(self) -> dict:
        """The case as plain data (summary.json's "case"): the scene's fields and each object's
        fields, the rheology with its law's name; a non-finite number as its string."""

        def plain(v):  # JSON has no infinity: an unbounded option (time.max_dt) reads "inf"
            if isinstance(v, dict):
                return {k: plain(x) for k, x in v.items()}
            return str(v) if isinstance(v, float) and not math.isfinite(v) else v

        d = dataclasses.asdict(self)
        d["rheology"] = {"law": self.rheology.spec()[0], **d["rheology"]}
        return plain(d)

    def domain(self) -> tuple[float, float]:
        """(length, height): height 1.125 H_c (the paper's 0.45 m), length L_c + 8.25 H_c (3.5 m
        for the paper's column; the grid rounds it up by at most 3 %, to 3.6 m at ny = 2^k). The paper's channel needs only 2.05 m for its 1.6874 m run-out,
        but coarse grids run further (1.98 m at ny = 32, docs/validation.md), and reaching the
        far end stops the run with an error."""
        g = self.geometry
        hc = g.column_height
        return (g.length or g.width + 8.25 * hc, g.height or 1.125 * hc)

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
