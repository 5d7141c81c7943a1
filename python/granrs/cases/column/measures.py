"""Measures of the column's fields: the front on the lowest row of cells, the farthest material,
the deposit quantile, the surface profile, the basal pore-pressure ratio and the granular speed
of the rest criterion."""

from __future__ import annotations

import math

import numpy as np

from ..._granrs import VOLUME_FRACTION_MIN, ParameterError


def front_cell(phi: np.ndarray, max_gap: int = 2) -> int | None:
    """The last cell of the granular mass on the lowest row of cells (None without any): walking
    from the back wall along the cells with Φ > 0, gaps of at most ``max_gap`` cells are bridged
    (a front broken by one under-resolved cell), larger ones end the mass (detached droplets ahead
    of it do not count; see :func:`farthest_material`)."""
    inside = np.nonzero(phi[0] > 0)[0]
    if inside.size == 0:
        return None
    breaks = np.nonzero(np.diff(inside) > max_gap + 1)[0]
    return int(inside[breaks[0]] if breaks.size else inside[-1])


def front_position(phi: np.ndarray, dx: float, max_gap: int = 2) -> float:
    """Front of the granular mass on the lowest row of cells, after its last cell
    (:func:`front_cell`), at the linear zero crossing of Φ."""
    row = phi[0]
    i = front_cell(phi, max_gap)
    if i is None:
        return 0.0
    x = (i + 0.5) * dx
    if i + 1 < row.size:
        x += dx * row[i] / (row[i] - row[i + 1])
    return float(x)


def granular_speed(model) -> float:
    """The largest cell-centre speed over the cells that hold granular material (0 without any):
    Φ > 0, and with the conserved volume fraction (``interface_transport = "clsvof"``) also every
    cell with F above ``VOLUME_FRACTION_MIN`` (a film thinner than half a cell has Φ < 0 at its
    centres). What the column's rest criterion (:class:`RestCriterion`) and summary.json's
    ``final_granular_speed_m_s`` read."""
    uc, vc = model.centre_velocity()
    inside = model.phi > 0
    fraction = getattr(model, "volume_fraction", None)
    if fraction is not None:
        inside = inside | (fraction > VOLUME_FRACTION_MIN)
    return float(np.max(np.hypot(uc, vc)[inside])) if inside.any() else 0.0


def farthest_material(phi: np.ndarray, dx: float) -> float:
    """Largest x of a cell with Φ > 0 anywhere (detached droplets included)."""
    cols = np.nonzero((phi > 0).any(axis=0))[0]
    return float((cols[-1] + 1) * dx) if cols.size else 0.0


#: Fraction of the deposit's area behind ``runout_q99_m`` (summary.json).
DEPOSIT_QUANTILE = 0.99


def deposit_quantile(h: np.ndarray, dx: float, x_gate: float, q: float = DEPOSIT_QUANTILE) -> float:
    """Distance from the gate behind which the fraction ``q`` of the deposit's area lies: the
    cumulative area of the profile h (cell i spans [i dx, (i + 1) dx]) reaches q of the total,
    located linearly inside the cell where it does. Unlike the front, it does not jump when a
    thin piece of the tongue drops below the front's threshold (docs/validation.md,
    "Predictability of the late run-out")."""
    if not 0.0 < q <= 1.0:
        raise ParameterError(f"invalid parameter `q` = {q!r}: allowed a fraction in (0, 1]")
    h = np.clip(np.asarray(h, dtype=float), 0.0, None)
    cum = np.cumsum(h) * dx
    if cum.size == 0 or cum[-1] <= 0.0:
        return 0.0
    target = q * cum[-1]
    i = int(np.searchsorted(cum, target))
    before = cum[i - 1] if i > 0 else 0.0
    frac = (target - before) / (h[i] * dx) if h[i] > 0 else 1.0
    return float((i + frac) * dx - x_gate)


def surface_profile(phi: np.ndarray, dy: float) -> np.ndarray:
    """Height h(x) of the granular surface in each column: the highest zero crossing of Φ."""
    ny, nx = phi.shape
    inside = phi > 0
    j = ny - 1 - np.argmax(inside[::-1], axis=0)  # highest granular cell of each column
    cols = np.arange(nx)
    h = (j + 0.5) * dy
    below = j + 1 < ny  # interpolate to the zero crossing with the cell above
    a, b = phi[j[below], cols[below]], phi[j[below] + 1, cols[below]]
    h[below] += dy * a / (a - b)
    h[~inside.any(axis=0)] = 0.0
    return h


def basal_pore_pressure_ratio(pf_base: np.ndarray, h: np.ndarray, weight: float, mask: np.ndarray) -> float:
    """Share of the granular weight carried by the gas at the base over the columns ``mask``:
    Σ p_f(first cell row) / Σ φρ_s g h(x), h the surface height (``surface_profile``) and
    ``weight`` = φρ_s g. β at the start under the reservoir (less the half cell between the base
    and the first row); 0 where the gas has escaped; above 1 where the pore pressure exceeds the
    weight (p_s < 0: no friction at all). NaN where ``mask`` holds no material."""
    sel = mask & (h > 0)
    w = weight * float(np.sum(h[sel]))
    return float(np.sum(pf_base[sel]) / w) if w > 0 else math.nan
