"""Depth-averaged (shallow-layer, Savage–Hutter type) model of a granular layer along a channel.

Equations (Savage & Hutter 1989; the pore pressure is the two-phase model's eq. (7d) integrated
over the depth; the lateral stress of Iverson & Denlinger 2001), on a horizontal channel
0 < x < L with reflective walls at both ends::

    h_t + (h u)_x = 0
    (h u)_t + (h u² + ½ K g h²)_x = − K g h b_x − g h tan(α_b) (1 − β)⁺ sign(u)
    m_t + (m u)_x = − 2 κ m / h² + κ β_s χ_s(x)          m = ∫p_f dz / (ρ g)
    β = 2 m / h²,   K = k (1 − β̂) + β̂,   β̂ = min(max(β, 0), 1)

β = p_b/(ρ g h) is the basal pore-pressure ratio (it exceeds 1 where a layer spreads faster than
it drains), χ_s = 1 under the air supply. k is the earth-pressure coefficient of the effective
stress, the pore pressure being isotropic: a constant (``earth_pressure``, 1 by default: K = 1)
or, with ``internal_friction_angle`` = φ, Savage & Hutter's active coefficient
2 sec²φ (1 − √(1 − cos²φ sec²α_b)) − 1. ``DepthAveragedPore(transport="basal-ratio")`` carries
h β instead (decay π²κ/4h², β ≥ β_s under the supply). The derivation, the numerics (MUSCL–minmod,
hydrostatic reconstruction, HLL, SSP-RK2, friction as a projection that can stop a cell but never
reverse it) and the model's limits are in ``rust/granrs-core/src/models/depth_averaged.rs`` and
``docs/models.md``. The time loop runs in Rust with the GIL released.

    m = DepthAveragedModel(cells=400, length=2.0, basal_friction_angle=15.0)
    m.set_state(h=np.where(m.x < 0.2, 0.4, 0.0))
    m.advance(1.0)
    m.h, m.u, m.beta   # read-only live views, shape (cells,)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar, Optional

import numpy as np

from ._granrs import ParameterError, RustDepthAveraged
from .rheology import DruckerPrager

#: The defaults of the model's optional parameters: the Rust core's (``DepthAveragedConfig::new``).
_DEFAULTS = RustDepthAveraged.defaults()


#: What the pore-pressure variable carries: the depth-integrated pore pressure (eq. (7d)
#: integrated over the depth), or h β (β carried with the flow, held at β_s under the supply).
PORE_TRANSPORTS = ("depth-integrated", "basal-ratio")


@dataclass(frozen=True)
class DepthAveragedPore:
    """Pore pressure of the depth-averaged model: diffusivity κ (m² s⁻¹), supply ratio β_s, the
    extent 0 < x < ``supply_x_max`` of the basal air supply (the reservoir; 0: no supply) and the
    ``transport`` (:data:`PORE_TRANSPORTS`)."""

    diffusivity: float
    supply_ratio: float
    supply_x_max: float = 0.0
    transport: str = PORE_TRANSPORTS[0]


#: The lateral-pressure closures by name: the earth-pressure coefficient k of the effective stress
#: (the pore pressure isotropic, K = k (1 − β̂) + β̂).
CLOSURES = {
    "hydrostatic": "k = 1: the total stress isotropic and hydrostatic, K = 1 whatever β",
    "savage-hutter": "Savage & Hutter's (1989) active k of the rheology's internal friction angle and the base's",
    "rankine": "Rankine's active k = (1 − sin φ)/(1 + sin φ) of the rheology's internal friction angle φ",
}


#: Who reads the rheology's friction angle (not the closure 'hydrostatic').
ANGLE_READERS = "the closures 'savage-hutter' and 'rankine' and the 2D models; the closure 'hydrostatic' has k = 1"


def unused_error(name: str, value, reader: str = "the two-phase and granular models") -> ParameterError:
    """The error of a parameter the depth-averaged model does not read."""
    return ParameterError(
        f"invalid parameter `{name}` = {value!r} with the depth-averaged model: not used by it "
        f"(read by {reader}); allowed only with the model 'two-phase' or 'granular'"
    )


@dataclass(frozen=True)
class _Field:
    default: Any
    allowed: str
    unit: str
    doc: str
    lo: Optional[int] = None
    hi: Optional[int] = None


def _one_of(names) -> str:
    return "one of " + ", ".join(f"'{c}'" for c in names)


#: The fields of :class:`DepthAveraged`, each declared once: default, allowed values, unit, doc.
DEPTH_AVERAGED_FIELDS = {
    "closure": _Field(
        "savage-hutter",
        _one_of(CLOSURES),
        "",
        "the lateral-pressure closure: the earth-pressure coefficient k of the effective stress, the pore "
        "pressure isotropic (hydrostatic: k = 1)",
    ),
    "resolution": _Field(64, "an integer in [4, 4096]", "cells", "cells across min(L_c, H_c)", 4, 4096),
    "pore_transport": _Field(
        PORE_TRANSPORTS[0],
        _one_of(PORE_TRANSPORTS),
        "",
        "what the pore-pressure variable carries: the depth-integrated pore pressure, or h β",
    ),
}


#: The allowed values of the choice fields of :class:`DepthAveraged`.
DEPTH_AVERAGED_CHOICES = {"closure": tuple(CLOSURES), "pore_transport": PORE_TRANSPORTS}


@dataclass(frozen=True)
class DepthAveraged:
    """The depth-averaged model's own choices in a column case (``ColumnCase.depth_averaged``,
    the run files' [depth_averaged] section, ``granrs run column --model depth-averaged --set
    depth_averaged.KEY=VALUE``). Each field is declared once in :data:`DEPTH_AVERAGED_FIELDS`
    with its default, allowed values, unit and doc; a bad value raises ParameterError naming
    ``depth_averaged.FIELD`` when the object is made.

    - ``closure``: the lateral-pressure closure (:data:`CLOSURES`), the earth-pressure
      coefficient k of the effective stress; the default is chosen by measurement against the
      two-phase model over the ladder's scenes (docs/models.md, "The lateral pressure");
    - ``resolution``: cells across min(L_c, H_c) (Δx = min(L_c, H_c)/resolution);
    - ``pore_transport``: what the pore-pressure variable carries (:data:`PORE_TRANSPORTS`;
      docs/models.md, "The pore pressure")."""

    closure: str = DEPTH_AVERAGED_FIELDS["closure"].default
    resolution: int = DEPTH_AVERAGED_FIELDS["resolution"].default
    pore_transport: str = DEPTH_AVERAGED_FIELDS["pore_transport"].default

    FIELDS: ClassVar[dict] = DEPTH_AVERAGED_FIELDS

    def __post_init__(self):
        if self.closure not in DEPTH_AVERAGED_CHOICES["closure"]:
            raise ParameterError(
                f"invalid parameter `depth_averaged.closure` = {self.closure!r}: allowed {self.FIELDS['closure'].allowed}"
            )
        lo, hi = self.FIELDS["resolution"].lo, self.FIELDS["resolution"].hi
        r = self.resolution
        if isinstance(r, bool) or not isinstance(r, int) or not lo <= r <= hi:
            raise ParameterError(
                f"invalid parameter `depth_averaged.resolution` = {r!r}: allowed {self.FIELDS['resolution'].allowed}"
            )
        if self.pore_transport not in DEPTH_AVERAGED_CHOICES["pore_transport"]:
            raise ParameterError(
                f"invalid parameter `depth_averaged.pore_transport` = {self.pore_transport!r}: allowed "
                f"{self.FIELDS['pore_transport'].allowed}"
            )

    def refuse_unused(self, case, default) -> None:
        """ParameterError for the first field of a column ``case`` that its model does not read
        and that differs from ``default`` (the column's ``ColumnCase()``). The depth-averaged
        model reads the scene's ``geometry`` (but its ``height``), ``fluidisation.fluidised``,
        ``fluidisation.pore_pressure_ratio``, ``ny`` (the depth at which its front is read),
        ``t_end``, ``rest``, ``profile_times``, the base's friction angle, the pore pressure's
        diffusivity, the friction angle of a Drucker–Prager rheology (with the closures
        'savage-hutter' and 'rankine') and this object; the 2D models do not read this object."""
        if case.model != "depth-averaged":
            if self != default.depth_averaged:
                raise ParameterError(
                    f"invalid parameter `depth_averaged` = {self!r} with model = {case.model!r}: read only by the "
                    "depth-averaged model; allowed only with model = 'depth-averaged'"
                )
            return
        if not isinstance(case.rheology, DruckerPrager):
            raise unused_error(
                "rheology",
                case.rheology,
                "the 2D models; the depth-averaged closures read the friction angle of a granrs.DruckerPrager",
            )
        d = default
        rheology = dataclasses.replace(d.rheology, friction_angle=case.rheology.friction_angle)
        pore = dataclasses.replace(case.pore_pressure, diffusivity=d.pore_pressure.diffusivity)
        checks = (
            ("rheology.viscosity", case.rheology.viscosity, rheology.viscosity),
            ("rheology.projection", case.rheology.projection, rheology.projection),
            ("grains", case.grains, d.grains),
            ("fluidisation.air_supply", case.fluidisation.air_supply, d.fluidisation.air_supply),
            ("back_wall", case.back_wall, d.back_wall),
            ("geometry.height", case.geometry.height, d.geometry.height),
            ("pore_pressure", pore, d.pore_pressure),
            ("side_walls", case.side_walls, d.side_walls),
            ("active_region", case.active_region, d.active_region),
            ("time", case.time, d.time),
            ("numerics", case.numerics, d.numerics),
            ("interface", case.interface, d.interface),
            ("threads", case.threads, d.threads),
        )
        for name, value, default_value in checks:
            if value != default_value:
                if dataclasses.is_dataclass(value) and type(value) is type(default_value):
                    # the first field of an object that differs: interface.mass_correction = False
                    f = next(
                        f.name
                        for f in dataclasses.fields(value)
                        if getattr(value, f.name) != getattr(default_value, f.name)
                    )
                    name, value = f"{name}.{f}", getattr(value, f)
                raise unused_error(name, value)
        if self.closure == "hydrostatic" and case.rheology.friction_angle != d.rheology.friction_angle:
            raise unused_error("rheology.friction_angle", case.rheology.friction_angle, ANGLE_READERS)

    def earth_pressure(self, internal_friction_angle) -> dict:
        """The model's ``earth_pressure`` and ``internal_friction_angle`` for this closure;
        ``internal_friction_angle``: a callable giving the rheology's φ in degrees (called only by
        the closures that use it)."""
        if self.closure == "hydrostatic":
            return {"earth_pressure": 1.0, "internal_friction_angle": None}
        phi = internal_friction_angle()
        if self.closure == "rankine":
            s = np.sin(np.radians(phi))
            return {"earth_pressure": float((1 - s) / (1 + s)), "internal_friction_angle": None}
        return {"earth_pressure": 1.0, "internal_friction_angle": phi}


class DepthAveragedModel:
    """The depth-averaged model (see the module docstring): ``cells`` over a channel of ``length``
    [m], ``gravity`` [m s⁻²], a constant ``earth_pressure`` coefficient k of the effective stress
    (or, with ``internal_friction_angle`` φ in degrees, Savage & Hutter's active one of φ and the
    basal angle), the
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
        """Lateral pressure coefficient K = k (1 − β̂) + β̂ of each cell (a copy)."""
        return self._rust.earth_pressure()

    def effective_earth_pressure(self) -> float:
        """The earth-pressure coefficient k of the effective stress."""
        return self._rust.effective_earth_pressure()

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
