"""Rheologies of the dense (granular) phase: Newtonian, Bingham, Drucker–Prager, μ(I).

The deviatoric stress is T = 2η D(u) + τ Σ with Σ = P(Σ + r D(u)) (Aravena et al. eq. 5–7):

==================  ==========================  ==========================================
law                 yield stress τ              viscosity of the dense phase
==================  ==========================  ==========================================
``Newtonian()``     0                           ``dense.viscosity``
``Bingham(τ_y)``    ``yield_stress``            ``dense.viscosity``
``DruckerPrager``   tan(``friction_angle``) p⁺  ``dense.viscosity`` (the paper's D-P model)
``MuI``             ``mu_s`` p⁺                 ``dense.viscosity`` + (μ₂ − μ_s) p⁺ / (2|D| + (I₀/d)√(p⁺/ρ_s))
==================  ==========================  ==========================================

|D| = √(½ Σ D_ij²), so a simple shear u(y) has the shear stress η u' + τ sign(u'). p is the model
pressure (fix its gauge with an ``Outflow`` side, as the paper's open top). Angles are in degrees.
How the yield stress is imposed is a numerical choice: ``Numerics(plastic="projection")`` (the
bi-projection, default) or a regularisation (``"papanastasiou"``, ``"bi-viscous"``, with
``Numerics(regularisation=...)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ._granrs import ParameterError


def _number(name: str, v, lo: float = 0.0, strict: bool = False, hi: float = math.inf) -> float:
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    ok = ok and (v > lo if strict else v >= lo) and v < hi
    if not ok:
        rng = f"{'>' if strict else '>='} {lo}" + ("" if math.isinf(hi) else f" and < {hi}")
        raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed a finite number {rng}")
    return float(v)


#: The internal friction angle α of the granular phase, in degrees: (lo, hi], lo excluded (α = 0
#: has no yield stress). DruckerPrager, the column case, run files and ``granrs keys`` use it.
FRICTION_ANGLE_RANGE = (0.0, 89.0)


def check_friction_angle(v, name: str = "friction_angle") -> float:
    """``v`` as a float if it is an angle in FRICTION_ANGLE_RANGE; else ParameterError naming ``name``."""
    lo, hi = FRICTION_ANGLE_RANGE
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo < v <= hi:
        raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed an angle in degrees in ({lo:g}, {hi:g}]")
    return float(v)


@dataclass(frozen=True)
class Newtonian:
    """No yield stress: T = 2η D(u)."""

    def spec(self):
        return ("newtonian", {})


@dataclass(frozen=True)
class Bingham:
    """Bingham plastic: T = 2η D(u) + τ_y Σ with a constant ``yield_stress`` τ_y [Pa]."""

    yield_stress: float

    def __post_init__(self):
        _number("yield_stress", self.yield_stress)

    def spec(self):
        return ("bingham", {"yield_stress": float(self.yield_stress)})


@dataclass(frozen=True)
class DruckerPrager:
    """The paper's D-P model: T = 2η_s D(u) + tan(α) p⁺ Σ, ``friction_angle`` α in degrees (27°)."""

    friction_angle: float

    def __post_init__(self):
        check_friction_angle(self.friction_angle)

    def spec(self):
        return ("drucker-prager", {"friction_angle": float(self.friction_angle)})


@dataclass(frozen=True)
class MuI:
    """μ(I) rheology (paper eq. 3–5): μ(I) = μ_s + (μ₂ − μ_s)/(I₀/I + 1), I = 2|D| d √(ρ_s/p)."""

    mu_s: float
    mu_2: float
    i0: float
    grain_diameter: float
    grain_density: float

    def __post_init__(self):
        _number("mu_s", self.mu_s)
        _number("mu_2", self.mu_2, self.mu_s, strict=True)
        _number("i0", self.i0, strict=True)
        _number("grain_diameter", self.grain_diameter, strict=True)
        _number("grain_density", self.grain_density, strict=True)

    def spec(self):
        return ("mu-i", {k: float(getattr(self, k)) for k in ("mu_s", "mu_2", "i0", "grain_diameter", "grain_density")})


RHEOLOGIES = (Newtonian, Bingham, DruckerPrager, MuI)
