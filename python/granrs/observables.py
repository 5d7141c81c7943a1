"""Observables of a deposit profile h(x): thickness fronts, area quantiles, centre of mass, heights.

A column collapse ends as a deposit whose tail is a sheet a few cells thick. A single "run-out"
read where that sheet ends depends on the interface numerics and keeps moving with the grid
(docs/validation.md, "Observables"); the quantities here describe the whole deposit instead, each
from the profile h(x) sampled at the centres x_i = x₀ + (i + ½) Δx of columns of cells.

The profile (:func:`volume_profile`) is the granular volume per column of cells,

    h_i = Σ_j f_ij Δy,   f_ij = min(1, max(0, ½ + Φ_ij / Δy)),

the cell's fill fraction f read from the level set Φ (> 0 in the grains, a signed distance near
the interface): exact for a horizontal interface crossing the cell, and the same measure as a VOF
code's Σ_j f Δ (the Basilisk reference of docs/validation.md, "Cross-code check: Basilisk"). The
highest zero crossing of Φ (``granrs.cases.column.surface_profile``) is a different measure where
the deposit is thin or detached; both are written by the column case.

Observables (all lengths in metres, distances from a reference point ``x_ref``, the gate of the
column case):

* front at thickness τ (:func:`thickness_front`): the farthest x where h(x) > τ, located linearly
  between the last column above τ and the next one, x_f(τ) = x_i + Δx (h_i − τ)/(h_i − h_{i+1});
* area quantile q (:func:`area_quantile`): the x behind which the fraction q of the deposit's area
  A = Σ h_i Δx lies, the profile taken as constant on each column [x₀ + iΔx, x₀ + (i + 1)Δx];
* centre of mass x_c = Σ h_i x_i / Σ h_i (:func:`centre_of_mass`), and its travel x_c(t) − x_c(0);
* the height at the back wall, h₀ (the first column, centre Δx/2 from the wall), and at a point
  x_g (linear between the two nearest column centres, :func:`height_at`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any, Optional

import numpy as np

#: Thicknesses in metres at which :func:`observe_profile` reads a front.
FRONT_THICKNESSES_M = (1e-3, 2e-3, 5e-3, 10e-3, 20e-3)
#: Thicknesses in cells (Δy of the 2D grid) at which :func:`observe_profile` reads a front.
FRONT_THICKNESSES_CELLS = (0.5, 1.0, 2.0)
#: Area fractions of :func:`observe_profile`'s deposit quantiles.
DEPOSIT_QUANTILES = (0.5, 0.9, 0.95, 0.99)

PROFILE_DEFINITION = (
    "h(x) = sum_j f_ij dy, the granular volume per column of cells, f = min(1, max(0, 1/2 + "
    "phi/dy)) the cell's fill fraction from the level set (as a VOF code's sum_j f dy)"
)
#: The definition with the conserved volume fractions (``interface_transport = "clsvof"``).
FRACTION_PROFILE_DEFINITION = (
    "h(x) = sum_j F_ij dy, the granular volume per column of cells, F the conserved volume "
    "fraction of the clsvof transport"
)


def _volume_fraction(model):
    """The model's conserved volume fractions (``interface_transport = "clsvof"``), else None."""
    return getattr(model, "volume_fraction", None)


def model_profile_definition(model) -> str:
    """What :func:`model_volume_profile` reads for ``model``: :data:`FRACTION_PROFILE_DEFINITION`
    where it has volume fractions, else :data:`PROFILE_DEFINITION`."""
    return PROFILE_DEFINITION if _volume_fraction(model) is None else FRACTION_PROFILE_DEFINITION


def _check_profile(h, dx: float) -> np.ndarray:
    h = np.asarray(h, dtype=float)
    if h.ndim != 1 or h.size == 0:
        raise ValueError(f"invalid parameter `h`: allowed a non-empty 1D array of heights, got shape {h.shape}")
    if not np.all(np.isfinite(h)):
        raise ValueError("invalid parameter `h`: allowed finite heights only")
    if not (isinstance(dx, (int, float)) and math.isfinite(dx) and dx > 0):
        raise ValueError(f"invalid parameter `dx` = {dx!r}: allowed a positive number")
    return np.clip(h, 0.0, None)


def volume_profile(phi: np.ndarray, dy: float) -> np.ndarray:
    """Granular volume per column of cells, h_i = Σ_j f_ij Δy.

    Parameters
    ----------
    phi : ndarray, shape (ny, nx)
        Level set at the cell centres (rows j = 0 at the base), positive in the grains.
    dy : float
        Cell height Δy (m).

    Returns
    -------
    ndarray, shape (nx,)
        h_i (m), with the fill fraction f = min(1, max(0, ½ + Φ/Δy)): the exact fraction of a cell
        cut by a horizontal interface when Φ is the signed distance to it.
    """
    phi = np.asarray(phi, dtype=float)
    if phi.ndim != 2:
        raise ValueError(f"invalid parameter `phi`: allowed a 2D array (ny, nx), got shape {phi.shape}")
    if not dy > 0:
        raise ValueError(f"invalid parameter `dy` = {dy!r}: allowed a positive number")
    return np.clip(0.5 + phi / dy, 0.0, 1.0).sum(axis=0) * dy


def fraction_profile(fraction: np.ndarray, dy: float) -> np.ndarray:
    """Granular volume per column of cells from the volume fractions, h_i = Σ_j F_ij Δy.

    Parameters
    ----------
    fraction : ndarray, shape (ny, nx)
        Volume fraction F of the grains in each cell (rows j = 0 at the base), in [0, 1].
    dy : float
        Cell height Δy (m).

    Returns
    -------
    ndarray, shape (nx,)
        h_i (m).
    """
    fraction = np.asarray(fraction, dtype=float)
    if fraction.ndim != 2:
        raise ValueError(f"invalid parameter `fraction`: allowed a 2D array (ny, nx), got shape {fraction.shape}")
    if not dy > 0:
        raise ValueError(f"invalid parameter `dy` = {dy!r}: allowed a positive number")
    return fraction.sum(axis=0) * dy


def model_volume_profile(model) -> np.ndarray:
    """The granular volume per column of a model: :func:`fraction_profile` of its conserved
    volume fractions when it has them (``interface_transport = "clsvof"``), else
    :func:`volume_profile` of its level set."""
    fraction = _volume_fraction(model)
    if fraction is not None:
        return fraction_profile(fraction, model.grid.dy)
    return volume_profile(model.phi, model.grid.dy)


def thickness_front(h, dx: float, thickness: float, x0: float = 0.0) -> float:
    """Farthest x where h(x) > τ.

    Parameters
    ----------
    h : array_like
        Profile at the column centres x_i = x₀ + (i + ½)Δx.
    dx : float
        Column width Δx.
    thickness : float
        τ > 0 (m).
    x0 : float
        Left edge of the first column (the back wall).

    Returns
    -------
    float
        x_f = x_i + Δx (h_i − τ)/(h_i − h_{i+1}) with i the last column where h_i > τ (x_i for the
        last column of the domain); NaN when h ≤ τ everywhere. Detached pieces ahead of the main
        mass count: the front is that of the material, thinner than τ beyond it.
    """
    h = _check_profile(h, dx)
    if not thickness > 0:
        raise ValueError(f"invalid parameter `thickness` = {thickness!r}: allowed a positive number")
    above = np.nonzero(h > thickness)[0]
    if above.size == 0:
        return math.nan
    i = int(above[-1])
    x = x0 + (i + 0.5) * dx
    if i + 1 < h.size:
        x += dx * (h[i] - thickness) / (h[i] - h[i + 1])
    return float(x)


def area_quantile(h, dx: float, q: float, x0: float = 0.0) -> float:
    """The x behind which the fraction q of the deposit's area lies.

    Parameters
    ----------
    h : array_like
        Profile, constant on each column [x₀ + iΔx, x₀ + (i + 1)Δx].
    dx : float
        Column width Δx.
    q : float
        Fraction in (0, 1].
    x0 : float
        Left edge of the first column.

    Returns
    -------
    float
        x_q with ∫_{x₀}^{x_q} h dx = q Σ h_i Δx, found linearly inside the column where the
        cumulative area reaches it; x₀ for an empty profile.
    """
    h = _check_profile(h, dx)
    if not (isinstance(q, (int, float)) and 0.0 < q <= 1.0):
        raise ValueError(f"invalid parameter `q` = {q!r}: allowed a fraction in (0, 1]")
    cum = np.cumsum(h) * dx
    if cum[-1] <= 0.0:
        return float(x0)
    target = q * cum[-1]
    i = min(int(np.searchsorted(cum, target * (1.0 - 1e-15))), h.size - 1)
    before = cum[i - 1] if i > 0 else 0.0
    frac = min(1.0, max(0.0, (target - before) / (h[i] * dx))) if h[i] > 0 else 1.0
    return float(x0 + (i + frac) * dx)


def centre_of_mass(h, dx: float, x0: float = 0.0) -> float:
    """Horizontal centre of mass x_c = Σ h_i x_i / Σ h_i of the profile (NaN for an empty one).

    Parameters
    ----------
    h : array_like
        Profile at the column centres x_i = x₀ + (i + ½)Δx.
    dx : float
        Column width Δx.
    x0 : float
        Left edge of the first column.
    """
    h = _check_profile(h, dx)
    total = float(h.sum())
    if total <= 0.0:
        return math.nan
    x = x0 + (np.arange(h.size) + 0.5) * dx
    return float(np.dot(h, x) / total)


def height_at(h, dx: float, x: float, x0: float = 0.0) -> float:
    """h at the point x, linear between the two nearest column centres (the end value beyond them).

    Parameters
    ----------
    h : array_like
        Profile at the column centres x_i = x₀ + (i + ½)Δx.
    dx : float
        Column width Δx.
    x : float
        Where to read it.
    x0 : float
        Left edge of the first column.
    """
    h = _check_profile(h, dx)
    xc = x0 + (np.arange(h.size) + 0.5) * dx
    return float(np.interp(x, xc, h))


def _mm(t: float) -> str:
    return f"{1e3 * t:g}mm"


def _cells(c: float) -> str:
    return f"{c:g}cell"


def front_keys(cells: Iterable[float] = FRONT_THICKNESSES_CELLS, metres: Iterable[float] = FRONT_THICKNESSES_M) -> list:
    """Names of the thickness fronts of :func:`observe_profile`: ``front_h{τ}mm_m`` and ``front_h{c}cell_m``."""
    return [f"front_h{_mm(t)}_m" for t in metres] + [f"front_h{_cells(c)}_m" for c in cells]


def quantile_keys(quantiles: Iterable[float] = DEPOSIT_QUANTILES) -> list:
    """Names of the deposit quantiles of :func:`observe_profile`: ``q{100 q}_m``."""
    return [f"q{100 * q:g}_m" for q in quantiles]


def observe_profile(
    h,
    dx: float,
    cell: float,
    x_ref: float,
    x0: float = 0.0,
    metres: Iterable[float] = FRONT_THICKNESSES_M,
    cells: Iterable[float] = FRONT_THICKNESSES_CELLS,
    quantiles: Iterable[float] = DEPOSIT_QUANTILES,
) -> dict:
    """Every observable of one profile, as distances from ``x_ref``.

    Parameters
    ----------
    h : array_like
        Profile at the column centres x_i = x₀ + (i + ½)Δx (m).
    dx : float
        Column width Δx (m).
    cell : float
        The cell size (m) of the thickness fronts given in cells (the 2D grid's Δy).
    x_ref : float
        Origin of the reported distances (the gate, x = L_c).
    x0 : float
        Left edge of the first column (the back wall).
    metres, cells, quantiles : iterables of float
        Front thicknesses in metres and in cells, area fractions of the quantiles.

    Returns
    -------
    dict
        ``front_h{τ}mm_m``, ``front_h{c}cell_m`` (:func:`thickness_front` − x_ref), ``q{100q}_m``
        (:func:`area_quantile` − x_ref), ``centre_of_mass_m`` (:func:`centre_of_mass` − x_ref),
        ``h_back_wall_m`` (h of the first column), ``h_gate_m`` (:func:`height_at` x_ref) and
        ``profile_area_m2`` (Σ h_i Δx).
    """
    h = _check_profile(h, dx)
    if not cell > 0:
        raise ValueError(f"invalid parameter `cell` = {cell!r}: allowed a positive number")
    metres, cells, quantiles = list(metres), list(cells), list(quantiles)
    out = {}
    for key, tau in zip(front_keys(cells, metres), metres + [c * cell for c in cells]):
        out[key] = thickness_front(h, dx, tau, x0) - x_ref
    for key, q in zip(quantile_keys(quantiles), quantiles):
        out[key] = area_quantile(h, dx, q, x0) - x_ref
    out["centre_of_mass_m"] = centre_of_mass(h, dx, x0) - x_ref
    out["h_back_wall_m"] = float(h[0])
    out["h_gate_m"] = height_at(h, dx, x_ref, x0)
    out["profile_area_m2"] = float(h.sum() * dx)
    return out


def observable_keys(
    metres: Iterable[float] = FRONT_THICKNESSES_M,
    cells: Iterable[float] = FRONT_THICKNESSES_CELLS,
    quantiles: Iterable[float] = DEPOSIT_QUANTILES,
) -> list:
    """Every key of :func:`observe_profile`, in its order (the columns of a time series)."""
    return (
        front_keys(cells, metres)
        + quantile_keys(quantiles)
        + ["centre_of_mass_m", "h_back_wall_m", "h_gate_m", "profile_area_m2"]
    )


def summarise(final: dict, initial: dict, records: Optional[dict] = None, definition: str = PROFILE_DEFINITION) -> dict:
    """summary.json's ``observables``: the final profile's, with the travel and the fronts' maxima.

    Parameters
    ----------
    final : dict
        :func:`observe_profile` of the final profile.
    initial : dict
        :func:`observe_profile` of the initial profile.
    records : dict, optional
        Time series of the same keys (lists), for the largest value each front reached.
    definition : str, optional
        The profile's definition (:func:`model_profile_definition`), written as
        ``profile_definition``.

    Returns
    -------
    dict
        The final value of every observable (None where undefined), ``centre_of_mass_travel_m`` =
        x_c(end) − x_c(0), ``max_front_h…`` (the largest value of each front over the records)
        and ``profile_definition``.
    """
    out: dict[str, Any] = {k: _json_float(v) for k, v in final.items()}
    out["centre_of_mass_travel_m"] = _json_float(final["centre_of_mass_m"] - initial["centre_of_mass_m"])
    for k, v in (records or {}).items():
        if k.startswith("front_h") and len(v):
            arr = np.asarray(v, dtype=float)
            out["max_" + k] = _json_float(np.nanmax(arr)) if np.any(np.isfinite(arr)) else None
    out["profile_definition"] = definition
    return out


def _json_float(v) -> Optional[float]:
    v = float(v)
    return v if math.isfinite(v) else None
