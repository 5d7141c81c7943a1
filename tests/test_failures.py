"""A run that blows up stops with a message saying what failed, where and when, and keeps its history."""

import pytest

import granrs
from granrs import Simulation, SimulationError


def test_cfl_violation_is_detected_with_location_and_time():
    m = granrs.Model(granrs.Grid(32, 32, 1.0, 1.0), granrs.Material(1.0, 1e-3),
                     bc=granrs.BoundaryConditions(top=granrs.Velocity(tangential=1.0)),
                     numerics=granrs.Numerics(dt=0.2))
    sim = Simulation(m, stop_time=5.0)
    with pytest.raises(SimulationError, match="CFL number") as info:
        sim.run()
    err = info.value
    assert err.step >= 1 and err.time > 0 and err.location is not None
    # the steps before the failure are kept
    assert len(sim.history["time"]) == err.step - 1
    assert "error" in sim.stop_reason


def test_solver_non_convergence_is_reported():
    m = granrs.Model(granrs.Grid(64, 64, 1.0, 1.0), granrs.Material(1.0, 1e-3),
                     bc=granrs.BoundaryConditions(top=granrs.Velocity(tangential=1.0)),
                     numerics=granrs.Numerics(pressure_max_iterations=1, pressure_rtol=1e-14))
    with pytest.raises(SimulationError, match="did not converge"):
        m.advance(max_steps=3)
