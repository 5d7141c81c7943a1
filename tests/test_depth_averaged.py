"""The depth-averaged model: its closures, its pore pressure, the cross-code check against
IMEX_SfloW2D v2, fluidisation against the base's friction, and the refusal of what it does not read.

The equations and their derivation: rust/granrs-core/src/models/depth_averaged.rs and
docs/models.md ("The depth-averaged model"); the Rust tests cover the numerics
(`cargo test --release -p granrs-core --test depth_averaged`).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math

import numpy as np
import pytest

from granrs import (
    ActiveRegion,
    BiProjection,
    CoulombWall,
    DepthAveraged,
    DepthAveragedModel,
    DepthAveragedPore,
    Interface,
    ParameterError,
    SideWalls,
)
from granrs.cases.column import (
    ColumnCase,
    Fluidisation,
    Grains,
    build_depth_averaged,
    column_rheology,
    jop_mu_i,
    run_column,
)
from granrs.cli import main
from granrs.validation import run_case
from granrs.validation.peer import (
    DA_CENTRE_OF_MASS_TOLERANCE,
    DA_PROFILE_TOLERANCE,
    DA_RUNOUT_TOLERANCE,
    peer_depth_averaged,
)


def test_the_closures_give_k_of_the_effective_stress_and_k_1_is_selectable_by_name():
    # Savage & Hutter's active k at φ = 27°, δ = 15°: 0.5464 (their eq. 3.14); Rankine's
    # (1 − sin 27°)/(1 + sin 27°) = 0.3755; 'hydrostatic': k = 1, K = 1 whatever β
    def model(closure, beta=0.0):
        case = ColumnCase(model="depth-averaged", depth_averaged=DepthAveraged(closure=closure))
        kw = DepthAveraged(closure=closure).earth_pressure(lambda: case.internal_friction_angle)
        pore = DepthAveragedPore(0.035, 0.9, 0.0) if beta else None
        m = DepthAveragedModel(8, 1.0, basal_friction_angle=15.0, pore=pore, **kw)
        m.set_state(h=0.1, beta=beta)
        return m

    assert model("savage-hutter").effective_earth_pressure() == pytest.approx(0.5464, abs=1e-4)
    s = math.sin(math.radians(27.0))
    assert model("rankine").effective_earth_pressure() == pytest.approx((1 - s) / (1 + s), rel=1e-14)
    assert model("hydrostatic").effective_earth_pressure() == 1.0
    # the pore pressure is isotropic: K = k (1 − β) + β
    k = model("savage-hutter").effective_earth_pressure()
    np.testing.assert_allclose(model("savage-hutter", 0.9).earth_pressure(), k * 0.1 + 0.9, rtol=1e-14)
    np.testing.assert_allclose(model("hydrostatic", 0.9).earth_pressure(), 1.0, rtol=1e-14)
    with pytest.raises(ParameterError, match=r"`depth_averaged.closure` = 'k1': allowed one of 'hydrostatic'"):
        DepthAveraged(closure="k1")
    with pytest.raises(ParameterError, match=r"`depth_averaged.resolution` = 2: allowed an integer in \[4, 4096\]"):
        DepthAveraged(resolution=2)
    with pytest.raises(ParameterError, match=r"`depth_averaged.pore_transport` = 'x'"):
        DepthAveraged(pore_transport="x")
    with pytest.raises(ParameterError, match="`pore.transport`"):
        DepthAveragedModel(8, 1.0, pore=DepthAveragedPore(0.035, 0.9, 0.0, transport="x"))


def test_the_depth_integrated_pore_pressure_rises_above_one_under_the_spreading_column(tmp_path):
    # eq. (7d) integrated over the depth carries ∫p_f dz: as the column spreads faster than it
    # drains (t_d = h²/2κ = 2.3 s at h = 0.4 m), the basal ratio under the reservoir rises above 1,
    # as in the 2D model (1.47 at t = 0.4 s, ny = 32; docs/models.md). Measured 2.35 at 0.29 s (at
    # the 2D lowest row's height); the h β transport cannot exceed its initial 0.9.
    peaks = {}
    for transport in ("depth-integrated", "basal-ratio"):
        case = ColumnCase(model="depth-averaged", t_end=0.6, depth_averaged=DepthAveraged(pore_transport=transport))
        run_column(case, tmp_path / transport, progress=False)
        rows = list(csv.DictReader((tmp_path / transport / "front.csv").open()))
        peaks[transport] = max(float(r["pf_ratio_reservoir"]) for r in rows)
    assert peaks["depth-integrated"] > 1.5, peaks
    assert peaks["basal-ratio"] <= 0.9 + 1e-12, peaks


def test_peer_depth_averaged_passes_against_imex_sflow2d():
    # the dry column, k = 1, Coulomb tan 15°, 2 mm cells as the peer's: measured run-outs −0.54 %
    # (1 mm) and −0.09 % (5 mm), the centre of mass −0.20 %, the profile 0.37 % in L1; the bars
    # (2 %, 2 %, 5 %) are the validation case's (granrs.validation.peer)
    rec = run_case("peer-depth-averaged")
    m = rec["metrics"]
    assert rec["passed"] is True, m["failures"]
    for key in ("front_1mm", "front_5mm"):
        assert abs(m["runout_m"][key]["rel_diff"]) <= DA_RUNOUT_TOLERANCE
    assert abs(m["centre_of_mass_x_m"]["rel_diff"]) <= DA_CENTRE_OF_MASS_TOLERANCE
    assert m["profile_l1_rel_diff"] <= DA_PROFILE_TOLERANCE
    # the fronts against time: the 5 mm front within 4 mm (two cells) at every output time
    assert m["front_vs_time"]["front_5mm"]["max_abs_diff_m"] <= 0.0041
    assert m["mass_rel_error"] < 1e-12


@pytest.mark.slow
def test_peer_depth_averaged_at_the_peers_1_mm_cells():
    # 1 mm cells against the peer's 1 mm run: measured −0.27 % (1 mm run-out), −0.11 % centre of
    # mass, 0.20 % profile; the same bars, and the 5 mm front within 2 mm (two cells) in time
    metrics, _, passed = peer_depth_averaged(200)
    assert passed, metrics["failures"]
    assert metrics["front_vs_time"]["front_5mm"]["max_abs_diff_m"] <= 0.0021
    # and the run-outs move by less than the tolerance from 2 to 1 mm cells (grid convergence)
    coarse, _, _ = peer_depth_averaged(100)
    for key in ("front_1mm", "front_5mm"):
        a, b = coarse["runout_m"][key]["granrs"], metrics["runout_m"][key]["granrs"]
        assert abs(a - b) / b < DA_RUNOUT_TOLERANCE / 2


@pytest.mark.parametrize("angle", [10.0, 15.0, 20.0, 25.0, 30.0])
def test_fluidisation_never_shortens_the_run_out_whatever_the_base_friction(angle):
    # β = 0.9 and the default closure: the fluidised run-out is at least the dry one. Measured
    # ratios 2.47, 2.23, 1.87, 1.45, 1.15 at 10-30° (docs/img/depth_averaged_angle_sweep.csv): the
    # bound is the experiment's and the two-phase model's: fluidisation lengthens a flow
    runs = {}
    for fluidised in (True, False):
        case = ColumnCase(
            model="depth-averaged", fluidisation=Fluidisation(fluidised=fluidised), base=CoulombWall(angle)
        )
        m = build_depth_averaged(case)
        m.advance(3.0)
        runs[fluidised] = m.front(0.5 * case.domain()[1] / case.ny) - case.geometry.width
    assert runs[True] >= runs[False], runs


@pytest.mark.parametrize(
    "change, name",
    [
        (dict(rheology=jop_mu_i(27.0, grain_diameter=75e-6, grain_density=2500.0, viscosity=0.1)), "`rheology`"),
        (dict(back_wall="free-slip"), "`back_wall` = 'free-slip'"),
        (
            dict(rheology=dataclasses.replace(column_rheology(), projection=BiProjection(proximal_restarts=5))),
            "`rheology.projection.",
        ),
        (dict(interface=Interface(mass_correction=True, piece_removal_cells=4)), "`interface.piece_removal_cells` = 4"),
        (dict(side_walls=SideWalls(0.1, 15.0)), "`side_walls`"),
        (dict(active_region=ActiveRegion(8)), "`active_region`"),
        (dict(grains=Grains(diameter=1e-3)), "`grains.diameter` = 0.001"),
        (
            dict(
                depth_averaged=DepthAveraged(closure="hydrostatic"),
                rheology=dataclasses.replace(ColumnCase().rheology, friction_angle=30.0),
            ),
            "`rheology.friction_angle` = 30.0",
        ),
    ],
)
def test_a_depth_averaged_case_refuses_what_the_model_does_not_read(change, name, tmp_path):
    case = ColumnCase(model="depth-averaged", **change)
    with pytest.raises(ParameterError, match="with the depth-averaged model: not used by it") as err:
        run_column(case, tmp_path / "out", progress=False)
    assert name in str(err.value)
    assert not (tmp_path / "out").exists()
    # and the 2D models refuse the depth-averaged model's own choices
    with pytest.raises(ParameterError, match="`depth_averaged` .* read only by the depth-averaged model"):
        ColumnCase(depth_averaged=DepthAveraged(closure="hydrostatic")).validate()


@pytest.mark.parametrize(
    "section, name",
    [
        ('[rheology]\nlaw = "mu-i"', "`rheology.law` = 'mu-i'"),
        ("[bi_projection]\nproximal_restarts = 5", "`bi_projection.proximal_restarts` = 5"),
        ("[interface]\npiece_removal_cells = 4", "`interface.piece_removal_cells` = 4"),
        ('[fluidisation]\nair_supply = "literal"', "`fluidisation.air_supply` = 'literal'"),
        ("[side_walls]\nwidth = 0.1", "`side_walls.width` = 0.1"),
        ("[active_region]\nband = 8", "`active_region.band` = 8"),
        ("[output]\nfields_every_s = 0.1", "`output.fields_every_s` = 0.1"),
    ],
)
def test_a_depth_averaged_run_file_refuses_the_keys_the_model_does_not_read(section, name, tmp_path, capsys):
    out = tmp_path / "run"
    output = f'[output]\ndir = "{out}"\n'
    f = tmp_path / "run.toml"
    for body, needle in (
        (f'[case]\nmodel = "depth-averaged"\n{section}\n', name),
        ('[case]\nmodel = "depth-averaged"\nback_wall = "free-slip"\n', "`case.back_wall` = 'free-slip'"),
    ):
        text = body.replace("[output]\n", output) if "[output]" in body else body + output
        f.write_text(text)
        assert main(["run", str(f), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert "with the depth-averaged model: not used by it" in err and needle in err, err
        assert not out.exists()


def test_the_command_line_refuses_the_flags_and_keys_the_depth_averaged_model_does_not_read(tmp_path, capsys):
    out = tmp_path / "o"
    for args, name in (
        (["--set", "bi_projection.proximal_restarts=5"], "`bi_projection.proximal_restarts` = 5"),
        (["--set", "case.back_wall=free-slip"], "`case.back_wall` = 'free-slip'"),
        (["--rheology", "mu-i"], "`--rheology` = 'mu-i'"),
        (["--active-region", "8"], "`--active-region` = 8"),
        (["--channel-width", "0.1"], "`--channel-width` = 0.1"),
    ):
        assert main(["run", "column", "--model", "depth-averaged", *args, "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert name in err and "depth-averaged" in err, err
        assert not out.exists()
    # its own keys go through --set, and a 2D model refuses them
    assert main(["run", "column", "--set", "depth_averaged.closure=hydrostatic", "--out", str(out), "--quiet"]) == 2
    assert "read only by the depth-averaged model" in capsys.readouterr().err and not out.exists()
    argv = ["run", "column", "--model", "depth-averaged", "--set", "depth_averaged.closure=hydrostatic"]
    assert main([*argv, "--t-end", "0.2", "--out", str(out), "--quiet"]) == 0
    case = json.loads((out / "summary.json").read_text())["case"]
    assert case["depth_averaged"]["closure"] == "hydrostatic"
