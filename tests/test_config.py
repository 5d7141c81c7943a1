"""Run files: strict validation naming the key, --set overrides, the resolved TOML round trip, the CLI."""

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib

from granrs import ParameterError
from granrs.cases.column import ColumnCase, ColumnGeometry, Fluidisation, Grains, RestCriterion
from granrs.config import (
    KEYS,
    apply_sets,
    column_case,
    describe,
    dumps,
    load_config,
    parse_scalar,
    resolve,
    write_config,
)

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "granrs.cli", *args], capture_output=True, text=True, cwd=cwd)


@pytest.mark.parametrize("path", ["paper_fluidised.toml", "paper_dry.toml"])
def test_round_trip_load_resolve_write_load(tmp_path, path):
    cfg = load_config(EXAMPLES / path)
    written = write_config(cfg, tmp_path / "config.resolved.toml", header=["a header line"])
    again = load_config(written)
    assert again == cfg
    assert resolve(tomllib.loads(dumps(again))) == cfg
    assert cfg["fluidisation"]["fluidised"] is (path == "paper_fluidised.toml")


def test_defaults_are_the_papers_case_and_resolve_every_key():
    cfg = resolve({})
    assert all((cfg[k.section][k.name] is None) == k.optional for k in KEYS)  # absent: None
    assert cfg["geometry"]["length"] == 3.5 and cfg["pore_pressure"]["diffusivity"] == 0.035
    case = column_case(cfg)
    case.validate()
    assert case == ColumnCase(geometry=ColumnGeometry(length=3.5)) and case.grid().nx == ColumnCase().grid().nx


def test_the_rest_section_is_the_cases_rest_criterion():
    case = column_case(resolve({"rest": {"speed": 0.02, "duration": 0.1}}))
    assert case.rest == RestCriterion(speed=0.02, duration=0.1, after=RestCriterion().after)
    assert column_case(resolve({})).rest == ColumnCase().rest == RestCriterion(speed=5e-3, duration=0.05, after=0.1)
    with pytest.raises(ParameterError, match=r"`rest.duration` = -1.0: allowed a number in \[0, 10000\]"):
        RestCriterion(duration=-1.0)


def test_the_column_flags_of_the_rest_criterion_take_the_keys_ranges(tmp_path):
    run = cli("run", "column", "--rest-speed", "0", "--out", str(tmp_path / "out"))
    assert run.returncode == 2 and "`--rest-speed` = '0': allowed a number in [1e-09, 10]" in run.stderr
    run = cli("run", "column", "--rest-duration", "-1", "--out", str(tmp_path / "out"))
    assert run.returncode == 2 and "`--rest-duration` = '-1': allowed a number in [0, 10000]" in run.stderr
    assert not (tmp_path / "out").exists()


def test_integers_are_accepted_for_float_keys_and_written_as_floats():
    cfg = resolve({"geometry": {"width": 1}, "time": {"t_end": 2}})
    assert cfg["geometry"]["width"] == 1.0 and isinstance(cfg["geometry"]["width"], float)
    assert "t_end = 2.0" in dumps(cfg)


def test_sets_are_parsed_as_toml_scalars():
    raw = apply_sets(
        {"time": {"cfl": 0.5}},
        [
            "time.cfl=0.3",
            "fluidisation.fluidised=false",
            "rheology.law=mu-i",
            'output.formats=["netcdf"]',
            'output.dir="out/x y"',
        ],
    )
    cfg = resolve(raw)
    assert cfg["time"]["cfl"] == 0.3 and cfg["fluidisation"]["fluidised"] is False
    assert cfg["rheology"]["law"] == "mu-i" and cfg["output"]["formats"] == ["netcdf"]
    assert cfg["output"]["dir"] == "out/x y"
    assert parse_scalar("1e-3") == 1e-3 and parse_scalar("7") == 7


@pytest.mark.parametrize("bad", ["numerics.cfll=0.3", "nosection.cfl=1", "cfl=0.3", "time.cfl"])
def test_bad_sets_are_rejected(bad):
    with pytest.raises(ParameterError, match="invalid parameter"):
        apply_sets({}, [bad])


MALFORMED = [
    ("[numerix]\ncfl = 0.5", "`numerix`", "unknown section"),
    ("[numerics]\ncfll = 0.5", "`numerics.cfll`", "unknown key"),
    ("[time]\ncfl = 0", "`time.cfl`", "[1e-6, 2]"),
    ("[time]\ncfl = 2.5", "`time.cfl`", "a number in"),
    ('[time]\ncfl = "0.5"', "`time.cfl`", "a number in"),
    ("[time]\ncfl = true", "`time.cfl`", "a number in"),
    ("[time]\ncfl = nan", "`time.cfl`", "a number in"),
    ("[time]\nt_end = inf", "`time.t_end`", "(s)"),
    ("[time]\nt_end = -1.0", "`time.t_end`", "(s)"),
    ("[grid]\nny = 16.0", "`grid.ny`", "an integer in [8, 4096]"),
    ("[grid]\nny = 4", "`grid.ny`", "an integer in [8, 4096]"),
    ("[grid]\nny = true", "`grid.ny`", "an integer"),
    ("[geometry]\nlength = 0.1", "`geometry.length`", "greater than geometry.width"),
    ("[geometry]\nheight = 0.3", "`geometry.height`", "beyond the column height"),
    ("[numerics]\nthreads = 0", "`numerics.threads`", "[1, 1024]"),
    ("[bi_projection]\ntheta = 1.0", "`bi_projection.theta`", "[0, 1)"),
    ("[bi_projection]\ntolerance = 0.0", "`bi_projection.tolerance`", "a number in"),
    ('[case]\nname = "dam-break"', "`case.name`", "'column'"),
    ('[rheology]\nlaw = "bingham"', "`rheology.law`", "'drucker-prager', 'mu-i'"),
    ('[fluidisation]\nfluidised = "yes"', "`fluidisation.fluidised`", "true or false"),
    ("[fluidisation]\npore_pressure_ratio = 1.2", "`fluidisation.pore_pressure_ratio`", "[0, 1]"),
    ('[fluidisation]\nair_supply = "outflow"', "`fluidisation.air_supply`", "'injection', 'literal'"),
    ("[geometry]\nwidth = 0", "`geometry.width`", "(m)"),
    ("[geometry]\naspect_ratio = 50", "`geometry.aspect_ratio`", "[0.1, 20]"),
    ("[grains]\nsolid_fraction = 0.9", "`grains.solid_fraction`", "[0.01, 0.74]"),
    ("[rheology]\nfriction_angle = 90", "`rheology.friction_angle`", "(degree)"),
    ("[pore_pressure]\ndiffusivity = 0", "`pore_pressure.diffusivity`", "(m2 s-1)"),
    ("[rheology]\nviscosity = -0.1", "`rheology.viscosity`", "(Pa s)"),
    ("[grains]\ndensity = [2500]", "`grains.density`", "(kg m-3)"),
    ("[grains]\ndiameter = 1.0", "`grains.diameter`", "(m)"),
    (
        "[variants]\nproximal_restarts = 5",
        "`variants`",
        "its key `proximal_restarts` belongs to [bi_projection]: allowed as `bi_projection.proximal_restarts`",
    ),
    ("[interface]\nwidth = 11.0", "`interface.width`", "[0, 10]"),
    ('[interface]\ntransport = "vof"', "`interface.transport`", "'level-set', 'clsvof'"),
    ('[output]\nformats = ["vtk", "hdf5"]', "`output.formats`", "'vtk', 'netcdf'"),
    ('[output]\nformats = "vtk"', "`output.formats`", "a list"),
    ('[output]\nformats = ["vtk", "vtk"]', "`output.formats`", "distinct"),
    ("[output]\nfields_every_s = -0.1", "`output.fields_every_s`", "(s)"),
    ("[output]\nfields_every_s = 0.0\nanimation = true", "`output.animation`", "fields_every_s > 0"),
    ('[output]\ndir = ""', "`output.dir`", "non-empty string"),
    ("[time]\nstep_retries = 21", "`time.step_retries`", "[0, 20]"),
    ("[rest]\nspeed = 0", "`rest.speed`", "[1e-09, 10]"),
    ("[rest]\nrest_speed = 0.01", "`rest.rest_speed`", "unknown key"),
    ("numerics = 3", "`numerics`", "a table"),
    ("[numerics.extra]\na = 1", "`numerics.extra`", "unknown key"),
    ("[time]\ncfl = ", "", "not valid TOML"),
]


@pytest.mark.parametrize(
    "text,key,allowed", MALFORMED, ids=[f"{i:02d}-{m[1] or 'syntax'}" for i, m in enumerate(MALFORMED)]
)
def test_malformed_run_files_are_rejected_naming_the_key(tmp_path, text, key, allowed):
    path = tmp_path / "bad.toml"
    path.write_text(text + "\n")
    with pytest.raises(ParameterError) as info:
        load_config(path)
    message = str(info.value)
    assert key in message and allowed in message, message
    assert str(path) in message


def test_keys_table_documents_every_key_with_its_unit():
    text = describe()
    for k in KEYS:
        assert f"`{k.full}`" in text
    assert "(m2 s-1)" in text and "(Pa s)" in text and "(degree)" in text


def test_cli_runs_a_file_with_sets_and_writes_the_resolved_configuration(tmp_path):
    out = tmp_path / "run"
    r = cli(
        "run",
        str(EXAMPLES / "paper_fluidised.toml"),
        "--set",
        "grid.ny=16",
        "--set",
        "time.t_end=0.04",
        "--set",
        "output.fields_every_s=0.02",
        "--set",
        'output.formats=["vtk"]',
        "--set",
        "output.animation=false",
        "--out",
        str(out),
        "--quiet",
    )
    assert r.returncode == 0, r.stderr
    resolved = out / "config.resolved.toml"
    text = resolved.read_text()
    assert text.startswith("# granrs ") and "command: " in text and "--set grid.ny=16" in text
    expected = load_config(
        EXAMPLES / "paper_fluidised.toml",
        [
            "grid.ny=16",
            "time.t_end=0.04",
            "output.fields_every_s=0.02",
            'output.formats=["vtk"]',
            "output.animation=false",
            f'output.dir="{out}"',
        ],
    )
    assert load_config(resolved) == expected
    assert (out / "summary.json").exists() and (out / "fields.pvd").exists()


def test_cli_rejects_a_bad_file_before_any_work(tmp_path):
    out = tmp_path / "never"
    path = tmp_path / "bad.toml"
    path.write_text(f'[time]\ncfl = 2.5\n[output]\ndir = "{out}"\n')
    r = cli("run", str(path))
    assert r.returncode == 2 and "`time.cfl`" in r.stderr and "[1e-6, 2]" in r.stderr
    assert not out.exists()
    r = cli("run", str(EXAMPLES / "paper_dry.toml"), "--ny", "16")
    assert r.returncode == 2 and "--set" in r.stderr
    r = cli("run", str(EXAMPLES / "paper_dry.toml"), "--set", "rheology.friction_angle=95", "--out", str(out))
    assert r.returncode == 2 and "`rheology.friction_angle`" in r.stderr and not out.exists()


def test_no_saved_fields_turns_the_default_animation_off():
    # the animation's default gives way when no fields are saved; asked for explicitly, it is refused (above)
    cfg = resolve({"output": {"fields_every_s": 0.0}})
    assert cfg["output"]["animation"] is False
    cfg = resolve({"output": {"formats": []}})
    assert cfg["output"]["animation"] is False
    assert resolve({})["output"]["animation"] is True


def test_the_column_case_describes_its_scene_in_at_most_20_fields():
    # the scene's numbers are grouped into small objects (geometry, grains, fluidisation, rest):
    # ColumnCase holds 19 fields
    assert len(dataclasses.fields(ColumnCase)) <= 20
    names = {f.name for f in dataclasses.fields(ColumnCase)}
    assert {"geometry", "grains", "fluidisation", "rest", "depth_averaged", "interface"} <= names
    assert not names & {"aspect_ratio", "width", "solid_fraction", "fluidised", "variants"}


@pytest.mark.parametrize(
    "make, key, allowed",
    [
        (lambda: ColumnGeometry(aspect_ratio=0.0), "geometry.aspect_ratio", "[0.1, 20]"),
        (lambda: ColumnGeometry(width=20.0), "geometry.width", "[0.001, 10]"),
        (lambda: ColumnGeometry(width=0.2, length=0.1), "geometry.length", "(0.2, 1000]"),
        (lambda: ColumnGeometry(height=0.2), "geometry.height", "(0.4, 1000]"),
        (lambda: Grains(solid_fraction=0.8), "grains.solid_fraction", "[0.01, 0.74]"),
        (lambda: Grains(density=True), "grains.density", "[1, 25000]"),
        (lambda: Grains(diameter=float("nan")), "grains.diameter", "[1e-07, 0.1]"),
        (lambda: Fluidisation(fluidised=1), "fluidisation.fluidised", "True or False"),
        (lambda: Fluidisation(pore_pressure_ratio=-0.1), "fluidisation.pore_pressure_ratio", "[0, 1]"),
        (lambda: Fluidisation(air_supply="outflow"), "fluidisation.air_supply", "'injection', 'literal'"),
        (lambda: ColumnCase(geometry=(2.0, 0.2)).validate(), "geometry", "ColumnGeometry"),
        (lambda: ColumnCase(grains=None).validate(), "grains", "Grains"),
    ],
)
def test_each_scene_object_refuses_a_bad_value_naming_its_full_key(make, key, allowed):
    with pytest.raises(
        ParameterError, match=rf"invalid parameter `{re.escape(key)}` = .*allowed .*{re.escape(allowed)}"
    ):
        make()


def test_a_run_file_with_every_objects_section_round_trips_through_its_resolved_file(tmp_path):
    text = """
[case]
model = "two-phase"
back_wall = "free-slip"
[geometry]
aspect_ratio = 1.5
width = 0.25
length = 3.0
height = 0.5
[grains]
solid_fraction = 0.6
density = 2400.0
diameter = 1e-4
[fluidisation]
fluidised = true
pore_pressure_ratio = 0.7
air_supply = "literal"
[grid]
ny = 16
[bi_projection]
proximal_restarts = 3
interface_yield = "granular-side"
wall_normal_stress = "total"
sigma_location = "centres"
wall_r = "local"
[interface]
transport = "clsvof"
plic_normal = "youngs"
mass_correction = false
width = 2.0
redistance_tolerance = 0.01
velocity = "extended"
[numerics]
pressure_gauge = "top"
"""
    path = tmp_path / "every.toml"
    path.write_text(text)
    cfg = load_config(path)
    written = write_config(cfg, tmp_path / "config.resolved.toml")
    resolved = written.read_text()
    for section in ("[geometry]", "[grains]", "[fluidisation]", "[interface]", "[bi_projection]"):
        assert section in resolved
    assert "[variants]" not in resolved and "[materials]" not in resolved
    again = load_config(written)
    assert again == cfg
    case = column_case(again)
    assert case == column_case(cfg)
    assert case.geometry == ColumnGeometry(aspect_ratio=1.5, width=0.25, length=3.0, height=0.5)
    assert case.grains == Grains(solid_fraction=0.6, density=2400.0, diameter=1e-4)
    assert case.fluidisation == Fluidisation(fluidised=True, pore_pressure_ratio=0.7, air_supply="literal")
    p = case.rheology.projection
    assert (p.proximal_restarts, p.interface_yield, p.wall_normal_stress, p.sigma_location, p.wall_r) == (
        3,
        "granular-side",
        "total",
        "centres",
        "local",
    )
    i = case.interface
    assert (i.transport, i.plic_normal, i.mass_correction, i.width, i.redistance_tolerance, i.velocity) == (
        "clsvof",
        "youngs",
        False,
        2.0,
        0.01,
        "extended",
    )
    assert case.numerics.pressure_gauge == "top"
