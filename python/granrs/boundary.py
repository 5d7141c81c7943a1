"""Boundary conditions per side of the domain (left, right, bottom, top)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

from . import options
from ._granrs import ParameterError


def _finite(name: str, v: float) -> float:
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
        raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed a finite number")
    return float(v)


@dataclass(frozen=True)
class NoSlip:
    """u = 0 on the wall."""

    def spec(self):
        return ("no-slip", {})


@dataclass(frozen=True)
class FreeSlip:
    """u·n = 0, no tangential stress."""

    def spec(self):
        return ("free-slip", {})


@dataclass(frozen=True)
class Velocity:
    """Prescribed velocity: ``tangential`` wall speed (a lid), ``normal`` inflow speed (into the domain)."""

    tangential: float = 0.0
    normal: float = 0.0

    def __post_init__(self):
        _finite("tangential", self.tangential)
        _finite("normal", self.normal)

    def spec(self):
        return ("velocity", {"tangential": float(self.tangential), "normal": float(self.normal)})


@dataclass(frozen=True)
class NavierSlip:
    """u·n = 0 and u_t = slip_length ∂u_t/∂n."""

    slip_length: float

    def __post_init__(self):
        v = _finite("slip_length", self.slip_length)
        if v <= 0:
            raise ParameterError(f"invalid parameter `slip_length` = {v!r}: allowed a finite length > 0")

    def spec(self):
        return ("navier", {"slip_length": float(self.slip_length)})


@dataclass(frozen=True)
class Outflow:
    """Open boundary: zero normal velocity gradient, pressure 0."""

    def spec(self):
        return ("outflow", {})


@dataclass(frozen=True)
class Coulomb:
    """Coulomb friction wall for the granular phase (paper eq. 8–9): impermeable, tangential stress
    tan(``friction_angle``) p⁺ opposing the slip (angle α_b in degrees, the paper's 15°); free-slip
    for air, and frictionless if ``friction_angle`` is None. Every Coulomb side shares one angle."""

    friction_angle: Optional[float] = None

    def __post_init__(self):
        object.__setattr__(self, "friction_angle", options.spec("friction_angle", "coulomb").check(self.friction_angle))

    def spec(self):
        return ("coulomb", {} if self.friction_angle is None else {"friction_angle": float(self.friction_angle)})


@dataclass(frozen=True)
class FullyDeveloped:
    """Fully developed in/outflow: zero normal gradient of both velocity components and of the
    pressure. Stands in for periodicity in flows invariant along the side's normal (channels,
    layers on an incline), where a hydrostatic pressure varies along the side."""

    def spec(self):
        return ("fully-developed", {})


#: A Coulomb friction wall with its angle α_b (the paper's name for ``Coulomb``).
CoulombWall = Coulomb

_KINDS = (NoSlip, FreeSlip, Velocity, NavierSlip, Outflow, Coulomb, FullyDeveloped)


@dataclass(frozen=True)
class BoundaryConditions:
    """Velocity conditions on the four sides (default: no-slip everywhere)."""

    left: object = field(default_factory=NoSlip)
    right: object = field(default_factory=NoSlip)
    bottom: object = field(default_factory=NoSlip)
    top: object = field(default_factory=NoSlip)

    def __post_init__(self):
        for side in ("left", "right", "bottom", "top"):
            v = getattr(self, side)
            if not isinstance(v, _KINDS):
                raise ParameterError(
                    f"invalid parameter `bc.{side}` = {v!r}: allowed one of NoSlip(), FreeSlip(), Velocity(...), "
                    "NavierSlip(...), Outflow(), Coulomb(...), FullyDeveloped()"
                )

    def spec(self) -> dict:
        return {s: getattr(self, s).spec() for s in ("left", "right", "bottom", "top")}

    def __repr__(self) -> str:
        return (
            "BoundaryConditions("
            + ", ".join(f"{s}={getattr(self, s)}" for s in ("left", "right", "bottom", "top"))
            + ")"
        )
