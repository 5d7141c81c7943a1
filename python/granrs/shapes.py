"""Initial shapes of the dense phase; the Rust core computes their exact signed distance
(sub-cell accurate, so a column of 113.8 × 227.6 cells sits exactly where it should)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ._granrs import ParameterError


def _num(name, v):
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
        raise ParameterError(f"invalid parameter `{name}` = {v!r}: allowed a finite number")
    return float(v)


class Shape:
    """Base class: shapes combine with ``|`` (union) and ``-`` (difference)."""

    def spec(self):  # pragma: no cover - abstract
        raise NotImplementedError

    def __or__(self, other):
        return Union((self, other))

    def __sub__(self, other):
        return Difference(self, other)


@dataclass(frozen=True)
class Rectangle(Shape):
    """The rectangle (x0, x1) × (y0, y1); extend it past the walls (e.g. x0 = −1) for a column
    against them."""

    x0: float
    x1: float
    y0: float
    y1: float

    def __post_init__(self):
        for k in ("x0", "x1", "y0", "y1"):
            _num(k, getattr(self, k))
        if self.x1 <= self.x0:
            raise ParameterError(f"invalid parameter `x1` = {self.x1}: allowed a value > x0 = {self.x0}")
        if self.y1 <= self.y0:
            raise ParameterError(f"invalid parameter `y1` = {self.y1}: allowed a value > y0 = {self.y0}")

    def spec(self):
        return ("rectangle", [self.x0, self.x1, self.y0, self.y1])


@dataclass(frozen=True)
class Circle(Shape):
    xc: float
    yc: float
    radius: float

    def __post_init__(self):
        _num("xc", self.xc), _num("yc", self.yc)
        if _num("radius", self.radius) <= 0:
            raise ParameterError(f"invalid parameter `radius` = {self.radius}: allowed a length > 0")

    def spec(self):
        return ("circle", [self.xc, self.yc, self.radius])


@dataclass(frozen=True)
class SlottedDisk(Shape):
    """Zalesak's disk: the disk minus the slot |x − xc| ≤ slot_width/2, y ≤ slot_top."""

    xc: float
    yc: float
    radius: float
    slot_width: float
    slot_top: float

    def spec(self):
        return ("slotted-disk", [self.xc, self.yc, self.radius, self.slot_width, self.slot_top])


@dataclass(frozen=True)
class HalfPlane(Shape):
    """{(x − px, y − py)·(nx, ny) ≤ 0}: a layer below the line through (px, py) with normal (nx, ny)
    pointing into the light phase (a flat layer of height H: HalfPlane(0, H, 0, 1))."""

    px: float
    py: float
    nx: float
    ny: float

    def spec(self):
        return ("half-plane", [self.px, self.py, self.nx, self.ny])


@dataclass(frozen=True)
class Union(Shape):
    parts: tuple

    def spec(self):
        return ("union", [p.spec() for p in self.parts])


@dataclass(frozen=True)
class Difference(Shape):
    a: Shape
    b: Shape

    def spec(self):
        return ("difference", [self.a.spec(), self.b.spec()])
