"""The uniform Cartesian MAC grid (cell centres, u on vertical faces, v on horizontal faces)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._granrs import ParameterError


@dataclass(frozen=True)
class Grid:
    """``nx × ny`` cells covering ``(0, lx) × (0, ly)``."""

    nx: int
    ny: int
    lx: float
    ly: float

    def __post_init__(self) -> None:
        for name in ("nx", "ny"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, (bool, np.bool_)) or not 2 <= v <= 65536:
                raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed an integer in [2, 65536]")
        for name in ("lx", "ly"):
            v = getattr(self, name)
            if (
                isinstance(v, (bool, np.bool_))
                or not isinstance(v, (int, float, np.floating, np.integer))
                or not math.isfinite(v)
                or v <= 0
            ):
                raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed a finite number > 0 (m)")

    @property
    def dx(self) -> float:
        return self.lx / self.nx

    @property
    def dy(self) -> float:
        return self.ly / self.ny

    @property
    def h(self) -> float:
        """Smallest cell size."""
        return min(self.dx, self.dy)

    @property
    def cells(self) -> int:
        return self.nx * self.ny

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Meshgrid (x, y) of cell centres, each of shape (ny, nx)."""
        x = (np.arange(self.nx) + 0.5) * self.dx
        y = (np.arange(self.ny) + 0.5) * self.dy
        return np.meshgrid(x, y)

    def xfaces(self) -> tuple[np.ndarray, np.ndarray]:
        """Meshgrid (x, y) of u points (vertical faces), shape (ny, nx + 1)."""
        x = np.arange(self.nx + 1) * self.dx
        y = (np.arange(self.ny) + 0.5) * self.dy
        return np.meshgrid(x, y)

    def yfaces(self) -> tuple[np.ndarray, np.ndarray]:
        """Meshgrid (x, y) of v points (horizontal faces), shape (ny + 1, nx)."""
        x = (np.arange(self.nx) + 0.5) * self.dx
        y = np.arange(self.ny + 1) * self.dy
        return np.meshgrid(x, y)

    def nodes(self) -> tuple[np.ndarray, np.ndarray]:
        """Meshgrid (x, y) of cell corners, shape (ny + 1, nx + 1)."""
        x = np.arange(self.nx + 1) * self.dx
        y = np.arange(self.ny + 1) * self.dy
        return np.meshgrid(x, y)

    def __repr__(self) -> str:
        return (
            f"Grid({self.nx} × {self.ny} cells on {self.lx:g} m × {self.ly:g} m, "
            f"dx = {self.dx:.4g} m, dy = {self.dy:.4g} m)"
        )
