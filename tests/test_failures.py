"""A run that fails stops with a message saying what failed, where and when, and keeps its history:
each failure mode of the stability map (docs/stability.md) is detected by granrs itself, never a
silent NaN. Small grids: seconds each."""

import json

import numpy as np
import pytest

import granrs
from granrs import BiProjection, DruckerPrager, Simulation, SimulationError
from granrs.cases.column import ColumnCase, Fluidisation, build_model, run_column
from granrs.validation import run_case
from granrs.validation.pore_pressure import pore_diffusion_error
from granrs.validation.rheology import REST_SPEED, creep_verdict, run_heap


def _cavity(n=32, **numerics):
    return granrs.Model(
        granrs.Grid(n, n, 1.0, 1.0),
        granrs.Material(1.0, numerics.pop("viscosity", 1e-3)),
        bc=granrs.BoundaryConditions(top=granrs.Velocity(tangential=1.0)),
        rheology=numerics.pop("rheology", None),
        numerics=granrs.Numerics(**numerics),
    )


# ---- blow-up and CFL ------------------------------------------------------------------------
def test_cfl_violation_is_detected_with_location_and_time():
    m = _cavity(dt=0.2)
    sim = Simulation(m, stop_time=5.0)
    with pytest.raises(SimulationError, match="CFL number") as info:
        sim.run()
    err = info.value
    assert err.step >= 1 and err.time > 0 and err.location is not None
    # the steps before the failure are kept
    assert len(sim.history["time"]) == err.step - 1
    assert "error" in sim.stop_reason


def test_blow_up_is_a_non_finite_velocity_error_not_a_silent_nan():
    # explicit viscous term at ν δt/h² = 1e200 · 1e-3 · 256, 1e202 times its limit 1/4: the
    # predictor overflows to inf/NaN in the first step. It is reported as a blow-up of the velocity
    # with its cell, not as an invalid right-hand side of the pressure solve (as it was before)
    m = _cavity(n=16, viscosity=1e200, dt=1e-3, viscous="explicit", cfl_abort=100.0)
    with pytest.raises(
        SimulationError, match=r"non-finite velocity \([uv] is NaN or inf\) after the momentum predictor"
    ) as info:
        m.advance(max_steps=5)
    err = info.value
    assert err.step == 1 and err.location is not None
    assert abs(err.time - 1e-3) < 1e-15


def test_explicit_viscous_instability_is_caught_by_the_cfl_guard_before_any_nan():
    # a milder explicit instability (ν δt/h² = 2.6, ten times the limit) grows over a few steps:
    # the CFL guard stops it while the velocity is still finite
    m = _cavity(n=16, viscosity=1.0, dt=1e-2, viscous="explicit", cfl_abort=100.0)
    with pytest.raises(SimulationError, match="CFL number .* exceeds the limit cfl_abort = 100") as info:
        m.advance(max_steps=50)
    assert np.all(np.isfinite(m.u)) and info.value.location is not None


# ---- iterations that do not converge --------------------------------------------------------
def test_pressure_solver_non_convergence_is_reported():
    m = _cavity(n=64, pressure_max_iterations=1, pressure_rtol=1e-14)
    with pytest.raises(SimulationError, match="did not converge"):
        m.advance(max_steps=3)


def test_viscous_solver_non_convergence_is_reported():
    # ν δt/h² = 1 · 0.1 · 1024 ≈ 100: Jacobi-CG needs tens of iterations, the cap is one
    m = _cavity(viscosity=1.0, dt=0.1, viscous_max_iterations=1, viscous_rtol=1e-14)
    with pytest.raises(
        SimulationError, match=r"viscous CG \(momentum predictor\) did not converge: .* after 1 iterations"
    ) as info:
        m.advance(max_steps=2)
    assert info.value.step == 1
    with pytest.raises(granrs.ParameterError, match="`viscous_max_iterations`"):
        _cavity(viscous_max_iterations=0)


def test_picard_non_convergence_is_reported_with_its_cap():
    m = _cavity(
        viscosity=1.0,
        rheology=granrs.Bingham(5.0),
        dt=0.05,
        convection=False,
        picard_max_iterations=2,
        picard_tol=1e-12,
    )
    with pytest.raises(
        SimulationError, match="Picard iteration of the plastic projection did not converge: .* after 2 iterations"
    ) as info:
        m.advance(max_steps=2)
    assert info.value.step == 1


def test_picard_failure_names_where_and_is_retaken_then_undone():
    # adaptive δt, a cap of 2 Picard iterations that no step size meets: the step is retaken twice
    # with δt halved, the error names the node where Σ moved most and how often it was retaken, and
    # the model is left at its last accepted state (t = 0, at rest)
    m = _cavity(
        viscosity=1.0,
        rheology=granrs.Bingham(5.0),
        convection=False,
        picard_max_iterations=2,
        picard_tol=1e-12,
        step_retries=2,
    )
    with pytest.raises(
        SimulationError,
        match=r"largest increment .* in Sigma_x[xy] at (node|cell) \(i=\d+, j=\d+\).*"
        r"retaken 2 times with δt halved",
    ) as info:
        m.advance(max_steps=2)
    assert info.value.step == 1
    assert m.time == 0.0 and np.all(m.u == 0.0)
    log = _cavity(viscosity=1.0, rheology=granrs.Bingham(5.0), convection=False, picard_tol=1e-9).advance(max_steps=2)
    assert list(log["step_retries"]) == [0.0, 0.0]
    for bad in (-1, 21):
        with pytest.raises(granrs.ParameterError, match="`step_retries`"):
            _cavity(step_retries=bad)


def test_a_column_step_past_the_cfl_guard_is_retaken_not_fatal():
    # the dry column at ny = 16 with C_cfl = 0.9 (above the 0.81 of the stability map's guard):
    # the released column accelerates through a step chosen from the speeds before it, and its
    # 5th step ends at CFL 1.11 > cfl_abort = 1. Without retries that stops the run; with the
    # default 3 the step is retaken with δt halved and every accepted step keeps the guard.
    def column(**time):
        return build_model(
            ColumnCase(ny=16, fluidisation=Fluidisation(fluidised=False), time=granrs.TimeStepping(cfl=0.9, **time))
        )

    m = column(step_retries=0)
    with pytest.raises(SimulationError, match=r"CFL number .* exceeds the limit cfl_abort = 1 ") as info:
        m.advance(t_end=0.3)
    assert "retaken" not in str(info.value) and info.value.location is not None
    assert m.step_count == info.value.step - 1
    log = column().advance(t_end=0.3)
    assert np.count_nonzero(log["step_retries"]) >= 1
    assert np.max(log["cfl"]) <= 1.0
    # a guard no halving meets: reported with its retries, the model at its last accepted state
    m = column(cfl_abort=0.01, step_retries=1)
    with pytest.raises(SimulationError, match=r"CFL number .* \(the step was retaken 1 times with δt halved"):
        m.advance(t_end=0.3)
    assert (m.step_count, m.time) == (0, 0.0)


# ---- explicit pore-pressure diffusion -------------------------------------------------------
def test_explicit_pore_pressure_past_its_limit_is_detected_and_names_the_limit():
    # 2 × h²/(4κ): the checkerboard grows by |1 − 4| = 3 per step; the 1e-9 seed excites it at once
    with pytest.raises(SimulationError, match=r"pore pressure p_f grows .* explicit diffusion limit h²/\(4κ\)") as info:
        pore_diffusion_error(32, dt_factor=2.0, time_scheme="explicit", seed=1e-9)
    err = info.value
    assert err.step == 1 and err.location is not None and "δt/limit = 2.0" in str(err)


def test_explicit_pore_pressure_below_its_limit_is_accurate():
    err, _, model = pore_diffusion_error(32, dt_factor=0.9, time_scheme="explicit", seed=1e-9)
    # same exact series as the implicit scheme (2.5e-4 at 10 × the limit); measured 6.1e-4: the
    # first-order time error δt·κ·|∂²p/∂t²| stays below the spatial error scale 1e-3
    assert err < 1e-3, err
    assert np.all(np.isfinite(model.pf))


def test_pore_time_scheme_is_validated():
    with pytest.raises(granrs.ParameterError, match="`time_scheme`"):
        granrs.PorePressure(diffusivity=1.0, time_scheme="crank-nicolson")
    with pytest.raises(granrs.ParameterError, match="`time_scheme`.*granular-only"):
        granrs.PorePressure(diffusivity=1.0, formulation="kappa-infinity", time_scheme="explicit")


# ---- creep of a heap that should rest -------------------------------------------------------
def test_regularised_heap_creep_is_flagged_by_the_metric():
    _, log = run_heap(20.0, 16, plastic="papanastasiou", regularisation=1000.0)
    v = creep_verdict(log)
    # Papanastasiou m = 1000 s creeps at ~2.4e-4 m/s whatever δt (docs/stability.md): 4 orders
    # above the rest criterion
    assert v["verdict"] == "creeps" and v["creep_speed"] > 1e3 * REST_SPEED, v
    assert "exceeds the rest criterion 1e-08 m/s" in v["message"]
    _, log = run_heap(20.0, 16, theta=0.0)
    assert creep_verdict(log)["verdict"] == "at rest"


def test_heap_at_rest_case_reports_both_verdicts():
    rec = run_case("heap-at-rest", slope=20.0, n=16, regularised=True)
    m = rec["metrics"]
    assert m["verdict"] == "at rest" and m["regularised_verdict"] == "creeps", m
    assert "creeps" in m["regularised_message"] and rec["passed"]


# ---- a column run that fails keeps its outputs ----------------------------------------------
def test_failed_column_run_keeps_summary_and_front(tmp_path):
    # plain Uzawa (θ = 0) with a 1e-8 Picard tolerance and the wide neighbourhood of r (the option
    # r_neighbourhood = 2, whose r is ~1600 times smaller under the surface): the iteration
    # does not converge within the case's 1000 iterations at the third step of the collapse
    # (increment 2.1e-8, t = 5.9 ms). With w = 0 the same run converges.
    with pytest.raises(SimulationError, match="Picard iteration .* did not converge.*outputs written to"):
        run_column(
            ColumnCase(
                ny=16,
                t_end=0.3,
                rheology=DruckerPrager(
                    viscosity=0.1, projection=BiProjection(theta=0.0, tolerance=1e-8, r_neighbourhood=2)
                ),
            ),
            tmp_path,
            progress=False,
        )
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["stop_reason"].startswith("error:") and "Picard" in summary["stop_reason"], summary
    assert summary["steps"] >= 1 and summary["t_end_s"] > 0
    rows = (tmp_path / "front.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,") and len(rows) >= 2, rows


def test_a_column_run_that_fails_at_its_first_step_reports_it_and_keeps_its_outputs(tmp_path):
    # one Picard iteration per step cannot reach the tolerance 1e-3 from Σ = 0 (the first
    # increment is 0.14 at ny = 8): the first step fails, is retaken three times with δt halved,
    # and the run stops before any step is recorded, with empty history arrays
    with pytest.raises(
        SimulationError, match=r"step 1, t = 0.*Picard iteration .* did not converge.*outputs written to"
    ):
        run_column(
            ColumnCase(ny=8, t_end=0.1, fluidisation=Fluidisation(fluidised=False)).with_options(
                picard_max_iterations=1
            ),
            tmp_path,
            progress=False,
        )
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["stop_reason"].startswith("error:") and "Picard" in summary["stop_reason"], summary
    assert summary["steps"] == 0 and summary["t_end_s"] == 0.0
    assert summary["pressure_iterations_max"] == 0 and "bi_projection_iterations" not in summary
    with np.load(tmp_path / "history.npz") as hist:
        assert hist["time"].size == 0 and "picard_iterations" in hist.files
    for name in ("front.csv", "profiles.csv", "front.png", "profiles.png"):
        assert (tmp_path / name).exists(), name
