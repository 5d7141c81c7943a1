"""Materials: density and viscosity (the granular rheology adds to these)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ._granrs import ParameterError


@dataclass(frozen=True)
class Material:
    """A Newtonian material: ``density`` [kg m⁻³] and dynamic ``viscosity`` [Pa s]."""

    density: float
    viscosity: float

    def __post_init__(self) -> None:
        for name in ("density", "viscosity"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or v <= 0:
                raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed a finite number > 0")

    @property
    def kinematic_viscosity(self) -> float:
        return self.viscosity / self.density


#: Air as in the paper (§2.1): ρ_f = 1 kg m⁻³, η_f = 2e-5 Pa s.
AIR = Material(density=1.0, viscosity=2e-5)
#: Water at 20 °C.
WATER = Material(density=1000.0, viscosity=1.0e-3)
