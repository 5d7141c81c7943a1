"""granrs.observables on profiles with exact answers: a triangle, a flat sheet, a level set."""

from __future__ import annotations

import math

import numpy as np
import pytest

from granrs import observables as obs


def _triangle(n: int, height: float = 0.3, length: float = 1.0, domain: float = 2.0):
    """h = H (1 − x/L) on [0, L], 0 beyond, at the centres of n columns on [0, domain] (L on a
    column edge)."""
    dx = domain / n
    x = (np.arange(n) + 0.5) * dx
    return np.clip(height * (1.0 - x / length), 0.0, None), dx


@pytest.mark.parametrize("n", [200, 1000])
def test_triangle_fronts_quantiles_centre_and_heights(n):
    H, L = 0.3, 1.0
    h, dx = _triangle(n, H, L)
    # fronts: the linear interpolation between column centres is exact on a linear profile, for
    # thicknesses above the last column's h = H dx/(2L) (beyond it the profile's kink at L lies
    # between the centres)
    for tau in (2 * H * dx / L, 0.01, 0.1, 0.25):
        assert obs.thickness_front(h, dx, tau) == pytest.approx(L * (1 - tau / H), abs=1e-12)
    assert math.isnan(obs.thickness_front(h, dx, H))  # nowhere thicker than the peak
    # area quantiles: ∫_0^x h = q H L/2 → x_q = L (1 − √(1 − q)). The midpoint rule is exact for the
    # cumulative area at column edges; inside a column the linear interpolation of the quadratic
    # cumulative misses it by at most dx² |h'| / (8 h(x_q)) (the 99 % quantile has the smallest h)
    for q in obs.DEPOSIT_QUANTILES:
        exact = L * (1 - math.sqrt(1 - q))
        bound = dx**2 * (H / L) / (8 * H * (1 - exact / L)) + 1e-12
        assert abs(obs.area_quantile(h, dx, q) - exact) <= bound, q
    # centre of mass L/3: the midpoint rule on x h(x) exceeds the integral by exactly
    # −dx²/24 [ (x h)' ]_0^L = H dx²/12, over the exact area H L/2: x_c = L/3 + dx²/(6L)
    assert obs.centre_of_mass(h, dx) == pytest.approx(L / 3 + dx**2 / (6 * L), abs=1e-12)
    assert obs.height_at(h, dx, 0.5) == pytest.approx(H / 2, abs=1e-12)
    o = obs.observe_profile(h, dx, cell=dx, x_ref=0.2)
    assert o["profile_area_m2"] == pytest.approx(H * L / 2, abs=1e-12)
    assert o["h_back_wall_m"] == pytest.approx(H * (1 - dx / (2 * L)), abs=1e-12)
    assert o["h_gate_m"] == pytest.approx(H * (1 - 0.2 / L), abs=1e-12)
    assert o["front_h20mm_m"] == pytest.approx(L * (1 - 0.02 / H) - 0.2, abs=1e-12)
    assert o["front_h2cell_m"] == pytest.approx(L * (1 - 2 * dx / H) - 0.2, abs=1e-12)
    assert o["q50_m"] == pytest.approx(L * (1 - math.sqrt(0.5)) - 0.2, abs=dx**2)


def test_flat_sheet_fronts_quantiles_and_centre():
    # a sheet h = h0 on [0, L] (L on a column edge): quantiles q L and centre L/2 exactly; every
    # front below h0 interpolates between the last full column (centre L − dx/2) and the empty one,
    # x_f = L − dx/2 + dx (1 − τ/h0): within half a column of the sheet's end, thinner fronts farther
    n, domain, L, h0 = 400, 2.0, 1.25, 0.004
    dx = domain / n
    h = np.where((np.arange(n) + 0.5) * dx < L, h0, 0.0)
    for tau in (1e-3, 2e-3, 3.9e-3):
        assert obs.thickness_front(h, dx, tau) == pytest.approx(L - dx / 2 + dx * (1 - tau / h0), abs=1e-12)
    assert math.isnan(obs.thickness_front(h, dx, 5e-3))
    for q in obs.DEPOSIT_QUANTILES + (1.0,):
        assert obs.area_quantile(h, dx, q) == pytest.approx(q * L, abs=1e-12)
    assert obs.centre_of_mass(h, dx) == pytest.approx(L / 2, abs=1e-12)
    o = obs.observe_profile(h, dx, cell=2e-3, x_ref=0.2, x0=-0.1)  # shifted: every distance moves by x0
    assert o["front_h1cell_m"] == pytest.approx(L - 0.1 - dx / 2 + dx * (1 - 2e-3 / h0) - 0.2, abs=1e-12)
    assert math.isnan(o["front_h5mm_m"]) and math.isnan(o["front_h2cell_m"])
    assert o["centre_of_mass_m"] == pytest.approx(L / 2 - 0.3, abs=1e-12)
    assert o["q90_m"] == pytest.approx(0.9 * L - 0.3, abs=1e-12)
    assert o["h_back_wall_m"] == o["h_gate_m"] == h0


def test_volume_profile_of_a_level_set_is_the_filled_height():
    # Φ = s(x) − y, the signed distance to a horizontal surface in each column: Σ_j f Δy = s exactly
    # (the fill fraction ½ + Φ/Δy is the cut cell's exact fraction); a column of air (s < 0) is empty
    ny, dy = 40, 0.01
    s = np.array([0.0, 0.003, 0.0125, 0.2, 0.39999, -0.5])
    y = (np.arange(ny) + 0.5)[:, None] * dy
    h = obs.volume_profile(s[None, :] - y, dy)
    np.testing.assert_allclose(h, np.clip(s, 0.0, None), atol=1e-14)


def test_summary_travel_and_front_maxima():
    first = {"centre_of_mass_m": -0.1, "front_h1mm_m": 0.0}
    last = {"centre_of_mass_m": 0.25, "front_h1mm_m": 1.0, "q50_m": math.nan}
    out = obs.summarise(last, first, {"front_h1mm_m": [0.0, 1.3, 1.0], "centre_of_mass_m": [-0.1, 0.3, 0.25]})
    assert out["centre_of_mass_travel_m"] == pytest.approx(0.35)
    assert out["max_front_h1mm_m"] == 1.3 and "max_centre_of_mass_m" not in out
    assert out["q50_m"] is None  # undefined values are JSON nulls
    assert "volume per column" in out["profile_definition"]
    assert obs.observable_keys()[:5] == [
        "front_h1mm_m",
        "front_h2mm_m",
        "front_h5mm_m",
        "front_h10mm_m",
        "front_h20mm_m",
    ]


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: obs.thickness_front([0.1, 0.0], 0.1, 0.0), "thickness"),
        (lambda: obs.area_quantile([0.1, 0.0], 0.1, 1.5), "q"),
        (lambda: obs.centre_of_mass([[0.1]], 0.1), "h"),
        (lambda: obs.centre_of_mass([0.1, np.nan], 0.1), "h"),
        (lambda: obs.height_at([0.1], -1.0, 0.0), "dx"),
        (lambda: obs.volume_profile(np.zeros(3), 0.1), "phi"),
        (lambda: obs.observe_profile([0.1], 0.1, 0.0, 0.0), "cell"),
    ],
)
def test_bad_input_names_the_parameter(call, name):
    with pytest.raises(ValueError, match=f"`{name}`"):
        call()
