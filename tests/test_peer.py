"""The cross-code check against Basilisk (granrs.validation.peer, `granrs validate peer-dry-column`)."""

from __future__ import annotations

import numpy as np
import pytest

from granrs import ParameterError
from granrs.validation import peer, run_case


def _as_run(ref: dict, scale=None, shift: int = 0) -> dict:
    """The reference dressed as a granrs run (front.csv's names), its profile optionally scaled
    pointwise by ``scale(x)`` and moved downstream by ``shift`` columns (empty behind)."""
    h = ref["h"] * (scale(ref["x"]) if scale is not None else 1.0)
    if shift:
        h = np.concatenate([np.zeros(shift), h[:-shift]])
    f = ref["fronts"]
    return {
        "x": ref["x"],
        "h": h,
        "dx": ref["dx"],
        "fronts": {
            "t_s": f["t_s"],
            "front_m": f["front_first_row_m"],
            "front_h20mm_m": f["front_h_2cm_m"],
            "front_h0.5cell_m": f["front_h_half_cell_m"],
        },
    }


@pytest.mark.parametrize("n", peer.REFERENCE_RESOLUTIONS)
def test_the_reference_against_itself_passes_with_no_difference(n):
    ref = peer.load_reference(n)
    m = peer.compare(_as_run(ref), ref, finer=True)
    assert m["passed"] and m["failures"] == []
    assert m["bulk_max_rel_diff"] == 0.0 and m["bulk_l1_rel_diff"] == 0.0
    assert all(v["max_abs_diff_m"] == 0.0 for v in m["front_vs_time"].values())
    # the stored data are those of the reference's README: the deposit holds the column's
    # 0.08 m² (0.2 m × 0.4 m) and its height at the gate is 0.124 m at both resolutions
    assert m["basilisk"]["area_m2"] == pytest.approx(0.08, rel=1e-3)
    assert m["basilisk"]["h_gate_m"] == pytest.approx(0.124, abs=5e-4)
    # the README's fronts: the last record of the front files
    last = {32: (2.033, 0.686, 1.702), 64: (2.194, 0.695, 1.907)}[n]
    f = ref["fronts"]
    got = (f["front_h_half_cell_m"][-1], f["front_h_2cm_m"][-1], f["front_first_row_m"][-1])
    np.testing.assert_allclose(got, last, atol=5e-4)


def test_a_bulk_off_by_more_than_the_tolerance_fails_at_the_finer_resolution_only():
    ref = peer.load_reference(64)

    # 12 % more near the back wall (x < −0.1 m), the rest untouched: the centre of mass moves by
    # less than its 10 %, the pointwise bulk check fails
    def bump(x):
        return np.where(x < -0.1, 1.12, 1.0)

    m = peer.compare(_as_run(ref, bump), ref, finer=True)
    assert not m["passed"] and m["failures"][0].startswith("bulk")
    assert m["bulk_max_rel_diff"] == pytest.approx(0.12, abs=1e-9)
    assert abs(m["rel_diff"]["centre_of_mass_m"]) < peer.CENTRE_OF_MASS_TOLERANCE
    assert peer.compare(_as_run(ref, bump), ref, finer=False)["passed"]  # coarser: reported, not judged
    # 8 %: within the tolerance
    assert peer.compare(_as_run(ref, lambda x: np.full_like(x, 1.08)), ref, finer=True)["passed"]


def test_a_centre_of_mass_off_by_more_than_the_tolerance_fails():
    ref = peer.load_reference(32)
    # the whole deposit moved 4 cells (5 cm) downstream, its last 4 columns (the film at the far
    # wall) dropped: x_c moves by 5 cm less what those columns held, about +18 %
    m = peer.compare(_as_run(ref, shift=4), ref, finer=False)
    assert not m["passed"] and m["failures"][0].startswith("centre of mass")
    assert 0.04 < m["abs_diff_m"]["centre_of_mass_m"] < 0.05


def test_a_resolution_without_reference_is_run_and_not_judged():
    # 8 cells per H_c (a 48 × 16 grid, a few seconds): no Basilisk data, passed None
    rec = run_case("peer-dry-column", n=[8], t_end=0.3)
    assert rec["passed"] is None and rec["metrics"]["runs"]["8"]["passed"] is None
    assert rec["metrics"]["runs"]["8"]["observables"]["centre_of_mass_m"] > -0.1
    with pytest.raises(ParameterError, match="`n`"):
        run_case("peer-dry-column", n=[2])


def test_a_sensitivity_run_changes_only_the_options_it_names_and_records_them():
    base, changed = peer.peer_case(8), peer.peer_case(8, options={"proximal_restarts": 20, "anderson_depth": 5})
    assert base.rheology.projection.proximal_restarts == 0
    assert changed.rheology.projection.proximal_restarts == 20
    assert changed.rheology.projection.anderson_depth == 5
    assert changed.rheology.friction_angle == base.rheology.friction_angle == 27.0
    assert changed.back_wall == base.back_wall == "free-slip"
    with pytest.raises(ParameterError, match="no_such_option"):
        peer.peer_case(8, options={"no_such_option": 1})
    metrics, _, passed = peer.peer_dry_column([8], t_end=0.05, options={"proximal_restarts": 3})
    assert passed is None and metrics["options"] == {"proximal_restarts": 3}


@pytest.fixture(scope="module")
def peer_record():
    # the shared set-up at 32 and 64 cells per H_c: about 20 s + 4 min on the 2-core machine
    return run_case("peer-dry-column")


@pytest.mark.slow
def test_granrs_agrees_with_basilisk_in_the_bulk_and_the_centre_of_mass(peer_record):
    """What agrees (docs/validation.md, "Cross-code check: Basilisk"; measured 2026-12-01): at 64
    cells per H_c the centre of mass within 1.0 % (10 % allowed), the bulk's L1 difference 5.9 %
    and the back-wall height −5.5 % (both bounded by the case's 10 %); at 32 the bulk's L1 6.9 %."""
    runs = peer_record["metrics"]["runs"]
    fine, coarse = runs["64"], runs["32"]
    assert abs(fine["rel_diff"]["centre_of_mass_m"]) <= peer.CENTRE_OF_MASS_TOLERANCE
    assert fine["bulk_l1_rel_diff"] <= peer.BULK_TOLERANCE and coarse["bulk_l1_rel_diff"] <= peer.BULK_TOLERANCE
    assert abs(fine["rel_diff"]["h_back_wall_m"]) <= peer.BULK_TOLERANCE
    # the dense area is kept (mass correction) and the volume profile holds it
    for r in (fine, coarse):
        assert r["mass_rel_error"] < 1e-6 and r["observables"]["profile_area_m2"] == pytest.approx(0.08, rel=0.01)


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="measured 2026-12-01: the bulk differs by 10.1 % (10 % allowed) one cell behind "
    "the gate at 64 cells per H_c, and the centre of mass by -11.5 % at 32 cells "
    "per H_c; docs/validation.md, 'Cross-code check: Basilisk'",
)
def test_the_cross_code_case_passes(peer_record):
    """The case's own verdict. It fails today by the margins in the reason: this test turns red
    (strict) the day it passes, so that the docs are updated with it."""
    assert peer_record["passed"] is True
