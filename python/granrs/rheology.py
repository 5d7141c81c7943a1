"""Rheologies of the dense (granular) phase: Newtonian, Bingham, Drucker–Prager, μ(I).

The deviatoric stress is T = 2η D(u) + τ Σ with Σ = P(Σ + r D(u)) (Aravena et al. eq. 5–7):

==================  ==========================  ==========================================
law                 yield stress τ              viscosity of the dense phase (η)
==================  ==========================  ==========================================
``Newtonian()``     0                           η
``Bingham(τ_y)``    ``yield_stress``            η
``DruckerPrager``   tan(``friction_angle``) p⁺  η (the paper's D-P model, η_s)
``MuI``             ``mu_s`` p⁺                 η + (μ₂ − μ_s) p⁺ / (2|D| + (I₀/d)√(p⁺/ρ_s))
==================  ==========================  ==========================================

η is the law's ``viscosity`` where given (it must then be ``dense.viscosity``: one viscosity of the
dense phase), else ``dense.viscosity``. |D| = √(½ Σ D_ij²), so a simple shear u(y) has the shear
stress η u' + τ sign(u'). p is the model pressure (fix its gauge with an ``Outflow`` side, as the paper's open top). Angles are in degrees.
How the yield stress is imposed is a numerical choice of the law's ``projection``, a
``granrs.BiProjection``: ``plastic="projection"`` (the bi-projection, default; ``theta``,
``tolerance``, ``max_iterations``, ...) or a regularisation (``"papanastasiou"``,
``"bi-viscous"``, with ``regularisation=...``). Parameter ranges and defaults are the Rust
schema's (``granrs.options``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

from . import options
from ._granrs import ParameterError
from .options import BiProjection


def _law_param(law: str, name: str, value) -> float:
    """``value`` as a float, checked in Rust against the law's option ``name`` (its room in the
    schema is the law's name); ParameterError naming ``name`` and its range otherwise."""
    return options.spec(name, law).check(value, name)


def _viscosity(rheology) -> None:
    v = rheology.viscosity
    if v is not None and (not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or v <= 0):
        raise ParameterError(f"invalid parameter `viscosity` = {v!r}: allowed None or a finite number > 0 (Pa s)")
    if v is not None:
        object.__setattr__(rheology, "viscosity", float(v))


def _projection(rheology) -> None:
    _viscosity(rheology)
    p = rheology.projection
    if p is not None and not isinstance(p, BiProjection):
        raise ParameterError(f"invalid parameter `projection` = {p!r}: allowed a granrs.BiProjection or None")


_DP = options.spec("friction_angle", "drucker-prager")
#: The internal friction angle α of the granular phase, in degrees, as (lo, hi), both ends
#: excluded (α = 0 has no yield stress): the Rust schema's range of DruckerPrager.friction_angle.
FRICTION_ANGLE_RANGE = (_DP.lo, _DP.hi)


def check_friction_angle(v, name: str = "friction_angle") -> float:
    """``v`` as a float if it is an angle in FRICTION_ANGLE_RANGE; else ParameterError naming ``name``."""
    return _DP.check(v, name)


@dataclass(frozen=True)
class Newtonian:
    """No yield stress: T = 2η D(u)."""

    projection = None

    def spec(self):
        return ("newtonian", {})


@dataclass(frozen=True)
class Bingham:
    """Bingham plastic: T = 2η D(u) + τ_y Σ with a constant ``yield_stress`` τ_y [Pa];
    ``viscosity``: η [Pa s] (None: the dense material's); ``projection``: the numerics of its
    bi-projection (None: the model's numerics)."""

    yield_stress: float
    viscosity: Optional[float] = None
    projection: Optional[BiProjection] = None

    def __post_init__(self):
        object.__setattr__(self, "yield_stress", _law_param("bingham", "yield_stress", self.yield_stress))
        _projection(self)

    def spec(self):
        return ("bingham", {"yield_stress": float(self.yield_stress)})


@dataclass(frozen=True)
class DruckerPrager:
    """The paper's D-P model: T = 2η_s D(u) + tan(α) p⁺ Σ, ``friction_angle`` α in degrees (the
    schema's default: the paper's 27°); ``viscosity``: η_s [Pa s] (None: the dense material's);
    ``projection``: the numerics of its bi-projection (``granrs.BiProjection(theta, tolerance,
    ...)``; None: the model's numerics)."""

    friction_angle: float = _DP.default
    viscosity: Optional[float] = None
    projection: Optional[BiProjection] = None

    def __post_init__(self):
        object.__setattr__(self, "friction_angle", check_friction_angle(self.friction_angle))
        _projection(self)

    def spec(self):
        return ("drucker-prager", {"friction_angle": float(self.friction_angle)})


@dataclass(frozen=True)
class MuI:
    """μ(I) rheology (paper eq. 3–5): μ(I) = μ_s + (μ₂ − μ_s)/(I₀/I + 1), I = 2|D| d √(ρ_s/p);
    ``viscosity``: η [Pa s] of the viscous part (None: the dense material's); ``projection``: the
    numerics of its bi-projection (None: the model's numerics)."""

    mu_s: float
    mu_2: float
    i0: float
    grain_diameter: float
    grain_density: float
    viscosity: Optional[float] = None
    projection: Optional[BiProjection] = None

    def __post_init__(self):
        for k in ("mu_s", "mu_2", "i0", "grain_diameter", "grain_density"):
            object.__setattr__(self, k, _law_param("mu-i", k, getattr(self, k)))
        if not self.mu_2 > self.mu_s:
            raise ParameterError(
                f"invalid parameter `mu_2` = {self.mu_2!r}: allowed a finite number > mu_s = {self.mu_s}"
            )
        _projection(self)

    def spec(self):
        return ("mu-i", {k: float(getattr(self, k)) for k in ("mu_s", "mu_2", "i0", "grain_diameter", "grain_density")})


RHEOLOGIES = (Newtonian, Bingham, DruckerPrager, MuI)
