"""The model: materials, boundary conditions and numerics on a grid; it takes one step at a time.

Field arrays (``u``, ``v``, ``p``, ``phi``) are zero-copy, read-only NumPy views of the Rust
state, indexed ``[j, i]`` (rows along y). They stay live: after a step they show the new values.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Optional, Union

import numpy as np

from . import _granrs, options
from ._granrs import ParameterError
from .boundary import BoundaryConditions, Coulomb, FreeSlip, NavierSlip, NoSlip, Outflow
from .grid import Grid
from .materials import Material
from .options import ActiveRegion, Interface, Numerics, TimeStepping
from .rheology import RHEOLOGIES, Bingham, DruckerPrager, MuI, Newtonian
from .shapes import Shape

HALO = _granrs.build_info()["halo"]
ArrayOrFn = Union[np.ndarray, Callable[[np.ndarray, np.ndarray], np.ndarray], float]


_PORE = {s.key: s for s in options.room("pore_pressure")}


@dataclass(frozen=True)
class PorePressure:
    """The pore gas pressure equation ∂_t p_f + div(u p_f) = div(κ ∇p_f) (paper eq. 10f).

    diffusivity: κ_f in the granular phase [m² s⁻¹] (the paper: 0.035);
    basal_gradient: ∂p_f/∂y on the base [Pa/m] between basal_x_min and basal_x_max (the air
    supply under the reservoir, −β φ ρ_s g in the paper); None for no supply;
    time_scheme: 'implicit' (BDF2 with implicit diffusion, second order, no step limit from the
    diffusion; default) or 'explicit' (forward Euler, first order, stable only for
    δt ≤ h²/(4κ) = 1/(2κ(1/dx² + 1/dy²)); 'granular-only' only). An explicit run past its limit
    stops with a SimulationError naming the pore pressure, the cell and the limit.
    formulation and kappa_air are variants (docs/models.md, "Variants"): 'granular-only' (solve
    where Φ > 0, p_f = 0 on the interface; default), 'kappa-infinity' (whole domain, κ =
    kappa_air in the air, sharp sub-cell interface) or 'kappa-infinity-smoothed' (the paper's
    literal κ(Φ) = κ_f H_ε + κ_∞(1 − H_ε), whose p_f = 0 boundary sits about ε inside the grains).
    Defaults, ranges and units are the Rust schema's (``granrs.options.room("pore_pressure")``).
    """

    diffusivity: float
    formulation: str = _PORE["formulation"].default
    kappa_air: float = _PORE["kappa_air"].default
    basal_gradient: Optional[float] = _PORE["basal_gradient"].default
    basal_x_min: Optional[float] = _PORE["basal_x_min"].default
    basal_x_max: Optional[float] = _PORE["basal_x_max"].default
    time_scheme: str = _PORE["time_scheme"].default

    def __post_init__(self):
        for name, s in _PORE.items():
            object.__setattr__(self, name, s.check(getattr(self, name)))
        if self.time_scheme == "explicit" and self.formulation != "granular-only":
            raise ParameterError(
                f"invalid parameter `time_scheme` = 'explicit' with formulation {self.formulation!r}: "
                "allowed only with 'granular-only' (kappa_air in the air makes the explicit limit "
                "h²/(4κ) vanish)"
            )

    def options(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class SideWalls:
    """Friction of a channel's two vertical side walls on the 2D flow (not in the paper's model;
    Jop, Forterre & Pouliquen 2005, J. Fluid Mech. 541): the body force −(2/W) tan(α_w) p⁺ H_ε(Φ) s,
    s = u/|u| where the granular phase slides, |s| ≤ 1 where it sticks (a projection solved in
    the Picard loop with Σ; Rust walls/side.rs).

    width: the channel width W [m] (the paper's experiment: 0.10); friction_angle: α_w [degrees].
    Their ranges are the Rust schema's (``granrs.options.room("side_walls")``).
    """

    width: float
    friction_angle: float

    def __post_init__(self):
        check_side_walls(self.width, self.friction_angle, "side_walls.width", "side_walls.friction_angle")


def check_side_walls(width, friction_angle, width_name: str, angle_name: str) -> None:
    """The ranges of a channel's side walls (the Rust schema's room "side_walls"); the errors
    name the caller's parameters."""
    options.spec("width", "side_walls").check(width, width_name)
    options.spec("friction_angle", "side_walls").check(friction_angle, angle_name)


# ---- memory ------------------------------------------------------------------------------------
def estimate_memory(
    grid: Grid,
    *,
    plastic: bool = True,
    pore_pressure: bool = False,
    air: str = "resolved",
    side_walls: bool = False,
    step_retries: int = 3,
    pressure_solver: str = "multigrid-cg",
) -> int:
    """Bytes the core allocates for a model on ``grid`` with these options: the Rust count
    (``ModelConfig::memory_estimate``, models/memory.rs) of a model with Coulomb walls
    (``plastic``), a pore pressure, the granular-only model (``air = 'free-surface'``), side
    walls, step retries and the chosen pressure solver."""
    config = {
        "grid": (grid.nx, grid.ny, float(grid.lx), float(grid.ly)),
        "bc": {"bottom": ("coulomb", {"friction_angle": 15.0}) if plastic else ("no-slip", {})},
        "dense": (1000.0, 0.1),
        "light": (1.0, 2e-5),
        "pore_pressure": {"diffusivity": 1.0} if pore_pressure else None,
        "side_walls": {"width": 0.1, "friction_angle": 15.0} if side_walls else None,
        "options": {"air": air, "step_retries": step_retries, "pressure_solver": pressure_solver},
    }
    return int(_granrs.RustModel.estimate_memory(config)[0])


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
        raise ParameterError(
            f"invalid parameter `grid` = {grid.nx} x {grid.ny} cells: {what} needs about "
            f"{estimate / 2**30:.3g} GiB, more than the {avail / 2**30:.3g} GiB of memory available "
            f"(MemAvailable); allowed a grid of at most about "
            f"{int(grid.cells * avail / estimate):d} cells on this machine"
        )


def _check_window_gauge(opts: dict, bc: BoundaryConditions, rheology, light, air: str) -> None:
    """ParameterError naming ``numerics.pressure_gauge`` when an active region meets a pressure
    gauge other than 'top' on a two-phase model whose right and top sides are walls (the case
    where the Rust check, ``TwoPhaseModel::validate_active_region``, refuses the gauge; its other
    refusals keep their own words): the window's top side sets the pressure's constant. 'auto'
    resolves as in Rust (``ModelConfig::resolved_pressure_gauge``): 'top' with a pressure-dependent
    law or a Coulomb wall with an angle, else 'mean'."""
    if opts.get("active_region") is None or light is None or air != "resolved":
        return
    sides = [getattr(bc, s) for s in ("left", "right", "bottom", "top")]
    walls = (NoSlip, FreeSlip, NavierSlip, Coulomb)
    if any(isinstance(b, Outflow) for b in sides) or not all(isinstance(b, walls) for b in (bc.right, bc.top)):
        return
    gauge = opts["pressure_gauge"]
    pressure_law = isinstance(rheology, (DruckerPrager, MuI))
    coulomb = any(isinstance(b, Coulomb) and b.friction_angle is not None for b in sides)
    if gauge == "mean" or gauge == "auto" and not (pressure_law or coulomb):
        resolved = (
            " (here 'mean': no pressure-dependent law and no Coulomb wall with an angle)" if gauge == "auto" else ""
        )
        raise ParameterError(
            f"invalid parameter `numerics.pressure_gauge` = {gauge!r}{resolved}: not allowed with `active_region` "
            "(the window's top side sets the pressure's constant); allowed 'top', or 'auto' with a "
            "pressure-dependent law (DruckerPrager, MuI) or a Coulomb wall with a friction angle"
        )


#: the values of ActiveRegion.sides / Numerics.active_region_sides (the Rust schema's)
ACTIVE_REGION_SIDES = options.spec("active_region_sides").choices
#: where the plastic tensor lives (BiProjection.sigma_location; the Rust schema's)
SIGMA_LOCATIONS = options.spec("sigma_location").choices


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

    The numerical options come from ``numerics`` (a ``granrs.Numerics``, the flat form of every
    option) and, where given, from the objects of their rooms, which hold their own options:
    ``time_stepping`` (``granrs.TimeStepping``), the rheology's ``projection``
    (``granrs.BiProjection``), ``interface`` (``granrs.Interface``) and ``active_region``
    (``granrs.ActiveRegion``); an option that ``numerics`` sets away from its default and an object
    sets otherwise is refused (``granrs.options.merge``). The rheology's ``viscosity``, where
    given, is ``dense.viscosity``. Every value is checked in Rust against the schema
    (``granrs.options``); ``model.numerics`` holds the options in force.
    """

    #: set by ``Model.check``: the constructor stops before allocating the model
    _check_only: bool = False

    def __init__(
        self,
        grid: Grid,
        dense: Material,
        light: Optional[Material] = None,
        bc: Optional[BoundaryConditions] = None,
        gravity=(0.0, 0.0),
        numerics: Optional[Numerics] = None,
        threads: int = 1,
        rheology=None,
        pore_pressure: Optional[PorePressure] = None,
        air: str = "resolved",
        side_walls: Optional[SideWalls] = None,
        time_stepping: Optional[TimeStepping] = None,
        active_region: Optional[ActiveRegion] = None,
        interface: Optional[Interface] = None,
    ):
        air = options.spec("air").check(air)
        if air == "free-surface" and light is None:
            raise ParameterError(
                "invalid parameter `air` = 'free-surface': allowed only with a light material (the surface is Φ = 0)"
            )
        if not isinstance(grid, Grid):
            raise ParameterError(f"invalid parameter `grid` = {grid!r}: allowed a granrs.Grid")
        if not isinstance(dense, Material):
            raise ParameterError(f"invalid parameter `dense` = {dense!r}: allowed a granrs.Material")
        if light is not None and not isinstance(light, Material):
            raise ParameterError(f"invalid parameter `light` = {light!r}: allowed a granrs.Material or None")
        threads = options.spec("threads").check(threads)
        if rheology is None:
            rheology = Newtonian()
        if not isinstance(rheology, RHEOLOGIES):
            raise ParameterError(
                f"invalid parameter `rheology` = {rheology!r}: allowed granrs.Newtonian(), Bingham(...), "
                "DruckerPrager(...) or MuI(...)"
            )
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
        if (
            isinstance(gravity, (str, bytes))
            or not hasattr(gravity, "__len__")
            or len(gravity) != 2
            or not all(
                isinstance(g, (int, float, np.integer, np.floating)) and not isinstance(g, bool) and math.isfinite(g)
                for g in gravity
            )
        ):
            raise ParameterError(
                f"invalid parameter `gravity` = {gravity!r}: allowed a pair of finite numbers (g_x, g_y) "
                "in m/s², e.g. (0.0, -9.81)"
            )
        self.gravity = (float(gravity[0]), float(gravity[1]))
        if numerics is not None and not isinstance(numerics, Numerics):
            raise ParameterError(f"invalid parameter `numerics` = {numerics!r}: allowed a granrs.Numerics or None")
        if pore_pressure is not None and not isinstance(pore_pressure, PorePressure):
            raise ParameterError(
                f"invalid parameter `pore_pressure` = {pore_pressure!r}: allowed a granrs.PorePressure or None"
            )
        self.pore_pressure = pore_pressure
        # the flat options: numerics, then each room's object given (an option set in both is refused)
        objects = {}
        for name, obj, cls in (
            ("time_stepping", time_stepping, TimeStepping),
            ("interface", interface, Interface),
            ("active_region", active_region, ActiveRegion),
        ):
            if obj is not None and not isinstance(obj, cls):
                raise ParameterError(f"invalid parameter `{name}` = {obj!r}: allowed a granrs.{cls.__name__} or None")
            if obj is not None:
                objects[name] = obj
        if getattr(rheology, "projection", None) is not None:
            objects["rheology.projection"] = rheology.projection
        viscosity = getattr(rheology, "viscosity", None)
        if viscosity is not None and viscosity != dense.viscosity:
            raise ParameterError(
                f"invalid parameter `rheology.viscosity` = {viscosity!r}: allowed None or the dense material's "
                f"viscosity {dense.viscosity!r} Pa s (one viscosity of the dense phase)"
            )
        opts = options.merge(numerics if numerics is not None else Numerics(), objects)
        _check_window_gauge(opts, self.bc, rheology, light, air)
        self.numerics = Numerics(**opts)
        opts.update(threads=threads, air=air)
        self.config = {
            "grid": (grid.nx, grid.ny, float(grid.lx), float(grid.ly)),
            "bc": self.bc.spec(),
            "dense": (dense.density, dense.viscosity),
            "light": None if light is None else (light.density, light.viscosity),
            "gravity": self.gravity,
            "rheology": rheology.spec(),
            "pore_pressure": None if pore_pressure is None else pore_pressure.options(),
            "side_walls": None
            if side_walls is None
            else {"width": float(side_walls.width), "friction_angle": float(side_walls.friction_angle)},
            "options": opts,
        }
        # memory before any work: the Rust count of this configuration (models/memory.rs)
        self.memory_estimate = int(_granrs.RustModel.estimate_memory(self.config)[0])
        memory_check(grid, self.memory_estimate)
        if self._check_only:
            return
        self._rust = _granrs.RustModel(self.config)
        self.air = air
        self.threads = threads
        names = ("u", "v", "p", "phi") + (("pf",) if pore_pressure is not None else ())
        self._views = {name: self._view(name) for name in names}
        if opts.get("interface_transport") == "clsvof" and light is not None:
            self._views["volume_fraction"] = self._view("volume_fraction")
        self._has_plastic = isinstance(rheology, (Bingham, DruckerPrager, MuI)) or any(
            isinstance(getattr(self.bc, s), Coulomb) and getattr(self.bc, s).friction_angle is not None
            for s in ("left", "right", "bottom", "top")
        )
        if self._has_plastic:
            for name in ("sigma_xx", "sigma_xy", "trial_norm", "yield_stress"):
                self._views[name] = self._view(name)

    @classmethod
    def check(cls, *args, **kwargs) -> int:
        """Checks ``Model(*args, **kwargs)`` as the constructor does (every argument, every option
        and every rule between them, in Rust, and the memory) without allocating the model;
        returns the memory estimate in bytes. Raises the constructor's ``ParameterError``."""
        model = cls.__new__(cls)
        model._check_only = True
        cls.__init__(model, *args, **kwargs)
        return model.memory_estimate

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
    def volume_fraction(self) -> Optional[np.ndarray]:
        """Dense volume fraction F at cell centres, shape (ny, nx), read-only live view; None
        unless ``interface_transport = "clsvof"``."""
        return self._views.get("volume_fraction")

    @property
    def pf(self) -> np.ndarray:
        """Pore gas pressure at cell centres, shape (ny, nx), read-only live view (fluidised models only)."""
        if "pf" not in self._views:
            raise ParameterError(
                "invalid parameter `pf`: allowed only for a model with pore_pressure (this one is not fluidised)"
            )
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

    def exact_step_problem(self) -> Optional[dict]:
        """The discrete problem of the last step taken with ``BiProjection(solver="newton")``, for an
        independent check of its solution, or None.

        Minimise ½xᵀAx − bᵀx + Σ_k w_k |B_k x + β_k| over the unknown faces x: ``A`` as triplets
        (``a_rows``, ``a_cols``, ``a_vals``, duplicates summed, size ``n``), ``b``, the terms' weights
        ``w`` and sizes ``dim`` (2: a plastic location, 1: a friction face), their rows of B stacked
        in compressed rows (``b_indptr``, ``b_indices``, ``b_data``) with offsets ``beta``, and the
        solution the step returned: ``x`` and the multipliers ``sigma`` (stacked like B's rows)."""
        out = self._rust.exact_step_problem()
        return None if out is None else dict(out)

    def wall_friction(self, side: str):
        """(s, τ_b) along a Coulomb side's tangential faces (arrays), or None without friction."""
        out = self._rust.wall_friction(side)
        return None if out is None else (np.asarray(out[0]), np.asarray(out[1]))

    def set_initial(
        self,
        u: Optional[ArrayOrFn] = None,
        v: Optional[ArrayOrFn] = None,
        p: Optional[ArrayOrFn] = None,
        phi: Optional[ArrayOrFn] = None,
        pf: Optional[ArrayOrFn] = None,
        balance_pressure: bool = True,
    ) -> None:
        """Sets initial fields from arrays, constants or functions f(x, y) evaluated at the
        field's points. With ``balance_pressure`` (and no explicit ``p``), p is set so that the
        body force is balanced (one pressure solve)."""
        points = {
            "u": self.grid.xfaces,
            "v": self.grid.yfaces,
            "p": self.grid.centres,
            "phi": self.grid.centres,
            "pf": self.grid.centres,
        }
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
                    raise ParameterError(
                        f"invalid parameter `{name}`: the function f(x, y) raised {type(err).__name__}: "
                        f"{err}; allowed a function of NumPy arrays x, y of shape {x.shape}"
                    ) from None
                what = "the function's result"
                if value is None or np.ndim(value) == 0:
                    raise ParameterError(
                        f"invalid parameter `{name}`: {what} is {value!r}; allowed an array of shape "
                        f"{x.shape} (write f(x, y) with NumPy, e.g. np.where(...) or 0 * x + c)"
                    )
            raw = np.asarray(value)
            if raw.dtype.kind not in "biuf":
                raise ParameterError(
                    f"invalid parameter `{name}`: {what} has dtype {raw.dtype}; allowed real numbers "
                    f"(float64), shape {x.shape}"
                )
            arr = raw.astype(float)
            if arr.ndim == 0:
                arr = np.full(x.shape, float(arr))
            if arr.shape != x.shape:
                raise ParameterError(
                    f"invalid parameter `{name}`: {what} has shape {arr.shape}; allowed shape {x.shape} "
                    f"(ny, nx) = ({self.grid.ny}, {self.grid.nx}) for {name}"
                )
            if not np.all(np.isfinite(arr)):
                bad = np.argwhere(~np.isfinite(arr))[0]
                raise ParameterError(
                    f"invalid parameter `{name}`: {what} is not finite at (j, i) = ({bad[0]}, {bad[1]}); "
                    "allowed finite numbers"
                )
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
        if not isinstance(shape, Shape):
            raise ParameterError(f"invalid parameter `shape` = {shape!r}: allowed a granrs.shapes shape")
        self._rust.set_shape(shape.spec())
        if balance_pressure:
            self._rust.initialise_pressure()

    def dense_area(self) -> float:
        """Area of the dense phase {Φ > 0} (sub-cell accurate), m²."""
        return self._rust.dense_area()

    def dense_volume(self) -> Optional[float]:
        """The conserved dense volume Σ F dx dy (m² per metre of width) with
        ``interface_transport = "clsvof"``; None otherwise."""
        return self._rust.dense_volume()

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
        viscous_iterations, pore_iterations, picard_iterations, picard_increment,
        picard_r_halvings, picard_restarts (the proximal restarts of the step, at most
        ``proximal_restarts``), step_retries, pieces_removed: the cells of the detached pieces of
        the dense phase turned to air, ``piece_removal_cells``; mass_shift: the global mass
        correction's shift δ of Φ in m)."""
        if t_end is None and max_steps is None:
            raise ParameterError("invalid parameter `t_end/max_steps`: allowed at least one of them")
        if t_end is not None and (
            isinstance(t_end, bool)
            or not isinstance(t_end, (int, float, np.floating))
            or not math.isfinite(t_end)
            or t_end < self.time
        ):
            raise ParameterError(
                f"invalid parameter `t_end` = {t_end!r}: allowed a finite time >= the model time {self.time!r} s"
            )
        if max_steps is not None and (
            isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 0
        ):
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

    def state(self) -> dict:
        """A copy of the whole state the next step starts from (fields, time, step count, the
        clock's and the iterations' memory), as a dict of NumPy arrays and numbers: what a
        checkpoint stores (granrs.io.checkpoint). Restoring it with :meth:`restore` into a model
        built the same way continues the run to the bit; a model built with other options
        continues the same state with them."""
        return self._rust.checkpoint_state()

    def restore(self, state: dict) -> None:
        """Sets the model's state to ``state``, a dict from :meth:`state` of a model on the same
        grid (the same keys and array shapes; ParameterError or ValueError otherwise)."""
        self._rust.restore_state(state)

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
            "dense": asdict(self.dense),
            "light": None if self.light is None else asdict(self.light),
            "bc": {k: v[0] for k, v in self.bc.spec().items()},
            "gravity": list(self.gravity),
            "numerics": self.numerics.options(),
            "threads": self.threads,
            "pore_pressure": None if self.pore_pressure is None else asdict(self.pore_pressure),
            "rheology": self.rheology.spec(),
        }

    def __repr__(self) -> str:
        phases = f"dense {self.dense}" + ("" if self.light is None else f", light {self.light}")
        return (
            f"Model on {self.grid}\n  {phases}\n  {self.bc}\n  gravity {self.gravity}, threads {self.threads}\n"
            f"  t = {self.time:.6g} s after {self.step_count} steps"
        )
