"""The paper's column collapse end to end (granrs.cases.column, `granrs run column`).

Fast tests run the coarse grid ny = 32 (about 10–20 s each on 2 cores) and check the outputs, not
the timing. Measured at ny = 32 (docs/validation.md, "Column collapse"): fluidised run-out
1.98 m, non-fluidised 0.96 m (ratio 2.07); the paper's grid is ny = 256.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from granrs import ParameterError, SimulationError
from granrs.cases.column import (PAPER_RUNOUT_SIM, ColumnCase, farthest_material, front_position, run_column)


def _run_cli(out: Path, *args: str) -> dict:
    cmd = [sys.executable, "-m", "granrs.cli", "run", "column", "--out", str(out), "--quiet", *args]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="module")
def coarse_runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("column")
    dry = _run_cli(base / "dry", "--ny", "32", "--no-fluidised")
    wet = _run_cli(base / "wet", "--ny", "32", "--compare-with", str(base / "dry"))
    return base, dry, wet


def test_outputs_are_complete(coarse_runs):
    base, dry, wet = coarse_runs
    for name in ("summary.json", "front.csv", "profiles.csv", "history.npz", "front.png", "profiles.png"):
        assert (base / "wet" / name).stat().st_size > 0
    for key in ("runout_m", "t_end_s", "steps", "nx", "ny", "cells", "wall_s", "mass_rel_error", "fluidised",
                "rheology", "threads", "version"):
        assert key in wet
    assert wet["fluidised"] and not dry["fluidised"]
    assert wet["ny"] == 32 and wet["cells"] == wet["nx"] * wet["ny"]
    rows = list(csv.reader(open(base / "wet" / "front.csv")))
    assert rows[0][:2] == ["t_s", "front_m"]
    t = np.array([float(r[0]) for r in rows[1:]])
    assert np.all(np.diff(t) > 0) and t[-1] == pytest.approx(wet["t_end_s"], abs=0.011)


def test_front_legend_says_run_out_only_at_rest(coarse_runs):
    from granrs.cases.column import _front_label

    base, dry, wet = coarse_runs
    # the coarse runs stop at t_end: the legend gives the front reached then, not a run-out
    assert wet["stop_reason"] in ("stop_time", "rest")
    label = _front_label(wet)
    if wet["stop_reason"] == "rest":
        assert "run-out" in label and "(at rest)" in label
    else:
        assert "not at rest" in label and "run-out" not in label and f"t = {wet['t_end_s']:g} s" in label
    rested = {**wet, "stop_reason": "rest", "model": "granular", "active_region": 8}
    assert _front_label(rested).startswith("fluidised, granular-only, active region 8, ny = 32: run-out")
    failed = {**wet, "stop_reason": "error: the granular material reached the far end", "t_end_s": 2.63}
    assert _front_label(failed).endswith("at t = 2.63 s (stopped by an error)")


def test_mass_is_conserved_with_the_default_correction(coarse_runs):
    # the global correction solves for the area to the secant tolerance (1e-10 in the dam break)
    _, dry, wet = coarse_runs
    assert dry["mass_rel_error"] < 1e-6 and wet["mass_rel_error"] < 1e-6


def test_fluidisation_lengthens_the_runout(coarse_runs):
    # paper: the non-fluidised run-out is "almost halved"; at ny = 32 the measured ratio is 2.07,
    # at the paper's grid the issue asks for 1.7–2.2. The coarse test asks only for the sign and
    # size of the effect: a ratio above 1.5, and run-outs within 50 % of the paper's (coarse grid).
    _, dry, wet = coarse_runs
    assert wet["runout_m"] / dry["runout_m"] > 1.5
    assert abs(wet["runout_m"] / PAPER_RUNOUT_SIM - 1) < 0.5


def test_front_has_three_phases(coarse_runs):
    # acceleration, a stretch of near-constant speed, deceleration to rest. Measured at ny = 32:
    # peak speed 2.65 m/s at t = 0.40 s, within 80 % of it from 0.17 to 0.83 s (0.66 s), late mean
    # |speed| 6 % of the peak (the receding tongue); the bounds leave about 2× margin each way
    base, _, wet = coarse_runs
    # the running maximum of the front on 0.05 s samples: the late thin tongue breaks and joins
    # again from one 0.01 s sample to the next (jumps of a few cells), which a pointwise
    # derivative would take for the peak speed
    data = np.genfromtxt(base / "wet" / "front.csv", delimiter=",", skip_header=1)
    t, x = data[::5, 0], np.maximum.accumulate(data[:, 1])[::5]
    speed = np.gradient(x, t)
    k = np.argmax(speed)
    assert t[k] > 0.15, "the front accelerates first"
    plateau = (speed > 0.8 * speed[k])
    assert t[plateau].max() - t[plateau].min() > 0.3, "a stretch of near-constant speed"
    assert np.abs(speed[t > 2.5]).mean() < 0.1 * speed[k], "the front decelerates to rest"


def test_front_position_bridges_small_gaps_and_ignores_droplets():
    dx = 0.01
    phi = -np.ones((3, 40))
    phi[0, :10] = 0.5 * dx
    phi[0, 12:15] = 0.5 * dx        # a 2-cell gap: bridged
    phi[0, 30:32] = 0.5 * dx        # a droplet 15 cells ahead: ignored by the front
    x = front_position(phi, dx)
    assert 0.145 < x < 0.16
    assert farthest_material(phi, dx) == pytest.approx(0.32)


def test_far_end_is_an_error_with_outputs_kept(tmp_path):
    case = ColumnCase(ny=16, length=0.45, t_end=1.0, fluidised=False)
    with pytest.raises(SimulationError, match="far end"):
        run_column(case, tmp_path, progress=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["stop_reason"].startswith("error") and (tmp_path / "front.png").exists()


@pytest.mark.parametrize("field,value", [("ny", 4), ("aspect_ratio", -1.0), ("pore_pressure_ratio", 1.5),
                                         ("cfl", 0.0), ("rheology", "bingham")])
def test_bad_parameters_name_themselves(tmp_path, field, value):
    with pytest.raises(ParameterError, match=f"`{field}`"):
        run_column(ColumnCase(**{field: value}), tmp_path, progress=False)


def _reference(ny: int, fluidised: bool) -> float:
    lines = (Path(__file__).parent / "data" / "column_reference.csv").read_text().splitlines()
    rows = csv.DictReader(line for line in lines if not line.startswith("#"))
    return next(float(r["runout_m"]) for r in rows if int(r["ny"]) == ny and int(r["fluidised"]) == int(fluidised))


def test_coarse_runouts_match_the_stored_reference(coarse_runs):
    # regression: the same code gives the same numbers bit for bit; 5 % allows for legitimate
    # round-off-level changes, which move the late thin tongue: three such changes (the pressure
    # gauge, the redistancing reach, nx 248 → 256) left the fronts equal to 3 digits up to
    # t = 0.6 s and moved the final run-outs by up to 3.7 % (wet 2.052 / 1.975 / 2.032 m,
    # dry 0.909 / 0.934 / 0.905 m)
    _, dry, wet = coarse_runs
    assert wet["runout_m"] == pytest.approx(_reference(32, True), rel=0.05)
    assert dry["runout_m"] == pytest.approx(_reference(32, False), rel=0.05)


@pytest.mark.slow
def test_ny64_runouts_ratio_and_mass(tmp_path):
    # ny = 64 (about 4 + 3 min on 2 cores): stored reference within 5 % (the late tongue: see the
    # ny = 32 test), the ratio
    # range 1.7–2.2 (measured 1.81), dense area within 1 % (measured 1e-10 with the correction)
    wet = run_column(ColumnCase(ny=64), tmp_path / "wet", progress=False)
    dry = run_column(ColumnCase(ny=64, fluidised=False), tmp_path / "dry", progress=False)
    assert wet["runout_m"] == pytest.approx(_reference(64, True), rel=0.05)
    assert dry["runout_m"] == pytest.approx(_reference(64, False), rel=0.05)
    assert 1.7 <= wet["runout_m"] / dry["runout_m"] <= 2.2
    assert max(wet["mass_rel_error"], dry["mass_rel_error"]) < 0.01


def test_active_region_runs_the_column_on_a_window(tmp_path):
    """The active region (Numerics.active_region, docs/models.md): at ny = 16 to t = 0.3 s the
    steps run on a 48 × 16 window of the 128 × 16 channel and the front is the whole-domain one
    to 8e-5 relative (measured; bound 0.5 %, a tenth of the ny = 64 differences in the docs);
    the views stay the whole domain's."""
    from granrs.cases.column import build_model
    fronts = {}
    for band in (None, 8):
        m = build_model(ColumnCase(ny=16, active_region=band))
        m._rust.advance(0.3, None)
        fronts[band] = front_position(m.phi, m.grid.dx)
        assert m.phi.shape == (16, 128)
        if band is None:
            assert m.active_window is None
        else:
            wx, wy = m.active_window
            assert wx < 128 and wx % 8 == 0 and wy <= 16
            assert np.all(m.u[:, wx + 1:] == 0.0), "the air outside the window is at rest"
    assert fronts[8] == pytest.approx(fronts[None], rel=5e-3)


@pytest.mark.parametrize("value", [1, 2.5, True])
def test_active_region_bad_band_names_itself(tmp_path, value):
    with pytest.raises(ParameterError, match="`active_region`"):
        run_column(ColumnCase(ny=16, active_region=value), tmp_path, progress=False)


def test_active_region_refused_for_a_single_phase_model():
    from granrs import Grid, Material, Model, Numerics
    with pytest.raises(ParameterError, match="active_region"):
        Model(Grid(16, 16, 1.0, 1.0), Material(1.0, 0.01), numerics=Numerics(active_region=4))


def test_wall_normal_stress_choice_names_itself(tmp_path):
    with pytest.raises(ParameterError, match="`wall_normal_stress`"):
        run_column(ColumnCase(ny=16, wall_normal_stress="effective"), tmp_path, progress=False)
    from granrs import Grid, Material, Model, Numerics
    with pytest.raises(ParameterError, match="wall_normal_stress"):
        Model(Grid(16, 16, 1.0, 1.0), Material(1.0, 0.01), numerics=Numerics(wall_normal_stress="effective"))
