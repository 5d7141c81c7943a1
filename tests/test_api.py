"""The Python API: construction, validation of bad input, zero-copy read-only views, errors."""

import math

import numpy as np
import pytest

import granrs
from granrs import BoundaryConditions, Grid, Material, Model, Numerics, ParameterError, Velocity


def cavity(n=16, **kw):
    return Model(Grid(n, n, 1.0, 1.0), Material(1.0, 0.01), bc=BoundaryConditions(top=Velocity(tangential=1.0)), **kw)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(nx=-4, ny=8, lx=1.0, ly=1.0), "nx"),
        (dict(nx=8, ny=1, lx=1.0, ly=1.0), "ny"),
        (dict(nx=8, ny=8, lx=math.nan, ly=1.0), "lx"),
        (dict(nx=8, ny=8, lx=1.0, ly=-2.0), "ly"),
    ],
)
def test_grid_rejects_bad_sizes(kwargs, name):
    with pytest.raises(ParameterError, match=f"`{name}`"):
        Grid(**kwargs)


def test_material_and_numerics_errors_name_the_parameter():
    with pytest.raises(ParameterError, match="`density`"):
        Material(-1.0, 1.0)
    with pytest.raises(ParameterError, match="`viscosity`"):
        Material(1.0, math.inf)
    with pytest.raises(ParameterError, match="`cfl`"):
        cavity(numerics=Numerics(cfl=-0.1))
    with pytest.raises(ParameterError, match="`threads`"):
        cavity(threads=0)
    with pytest.raises(ParameterError, match="`viscous`"):
        cavity(numerics=Numerics(viscous="semi"))
    with pytest.raises(ParameterError, match="`slip_length`"):
        granrs.NavierSlip(slip_length=0.0)
    # raised by the Rust binding, with the allowed values
    with pytest.raises(ParameterError, match="`interface_yield`.*'paper', 'granular-side', 'density-support'"):
        cavity(numerics=Numerics(interface_yield="sharp"))
    with pytest.raises(ParameterError, match="`yield_pressure`.*'absolute', 'surface-air'"):
        cavity(numerics=Numerics(yield_pressure="gauge"))
    with pytest.raises(ParameterError, match=r"`proximal_restarts` = -1: allowed an integer in \[0, 1000000\]"):
        cavity(numerics=Numerics(proximal_restarts=-1))
    from granrs import BiProjection, PorePressure
    from granrs.cases.column import ColumnCase

    with pytest.raises(ParameterError, match="`interface_yield`"):
        ColumnCase().with_options(interface_yield="sharp").validate()
    with pytest.raises(ParameterError, match=r"`kappa_air` = 0.5: allowed a number in \[1, 1e16\]"):
        ColumnCase(pore_pressure=PorePressure(0.035, kappa_air=0.5)).validate()
    with pytest.raises(ParameterError, match="`yield_pressure`"):
        BiProjection(yield_pressure="gauge")


def test_impossible_boundary_combination_is_rejected():
    # inflow through a closed box: div u = 0 has no solution
    bc = BoundaryConditions(left=Velocity(normal=1.0))
    with pytest.raises(ParameterError, match="net inflow"):
        Model(Grid(8, 8, 1.0, 1.0), Material(1.0, 0.01), bc=bc)
    # with an outflow side it is fine
    Model(
        Grid(8, 8, 1.0, 1.0),
        Material(1.0, 0.01),
        bc=BoundaryConditions(left=Velocity(normal=1.0), right=granrs.Outflow()),
    )


def test_wrong_array_shape_names_the_field():
    m = cavity()
    with pytest.raises(ParameterError, match="`u`"):
        m.set_initial(u=np.zeros((16, 16)))
    with pytest.raises(ParameterError, match="`phi`"):
        m.set_initial(phi=np.full((16, 16), np.nan))


def test_fields_are_read_only_zero_copy_live_views():
    m = cavity()
    u = m.u
    assert u.shape == (16, 17) and m.v.shape == (17, 16) and m.p.shape == (16, 16)
    assert not u.flags.writeable and not u.flags.owndata
    with pytest.raises(ValueError):
        u[0, 0] = 1.0
    before = u.copy()
    m.advance(max_steps=5)
    # the same array object shows the new state (no copy was handed out)
    assert np.max(np.abs(u - before)) > 0
    assert u is m.u


def test_views_survive_the_model_reference():
    u = cavity().u  # the view keeps the Rust model alive
    assert np.all(np.isfinite(u))


def test_repr_is_a_readable_summary():
    text = repr(cavity())
    assert "16 × 16 cells" in text and "Velocity(tangential=1.0" in text


def test_build_info_reports_release_profile():
    # `make install` builds the extension with --release (pyproject.toml: [tool.maturin] profile);
    # a debug build fails here, before any benchmark or timing is read from it
    info = granrs.build_info()
    assert info["version"] == granrs.__version__
    assert info["profile"] == "release", info
