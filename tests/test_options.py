"""The options schema and its consumers: every option is declared once, in Rust (the `OPTIONS`
tables beside the configuration structs), and each consumer — the Python classes, the run-file
keys, `granrs keys` and the docs' reference — shows it with the schema's default and range.

Each test enumerates the schema, so that a new option declared in Rust is checked here without
a line written for it (and one a consumer misses fails here)."""

import dataclasses
import re
import sys
from pathlib import Path

import pytest

import granrs
from granrs import ParameterError, _granrs, config, options
from granrs.cases.column import (
    ColumnCase,
    column_interface,
    column_numerics,
    column_pore_pressure,
    column_rheology,
)

ROOT = Path(__file__).resolve().parent.parent
FLAT = [s for s in options.SCHEMA if not s.object]


def test_schema_is_the_rust_tables_and_keys_are_unique():
    # every option declared in the core's source (an `options::float/int/boolean/choice(room, key,
    # ...)` of a table) reaches Python through the binding's schema, and nothing else does
    source = "\n".join(p.read_text(encoding="utf-8") for p in (ROOT / "rust" / "granrs-core" / "src").rglob("*.rs"))
    declared = re.findall(r'\boptions::(?:float|int|boolean|choice)\(\s*"([a-z_-]+)",\s*"([a-z0-9_]+)"', source)
    assert len(declared) == len(set(declared)) > 50
    assert sorted(declared) == sorted((s.room, s.key) for s in options.SCHEMA)
    keys = [s.key for s in FLAT]
    assert len(keys) == len(set(keys))
    assert {s.group for s in options.SCHEMA} == {"common", "variant"}
    # the research switches the common case does not need are in the group of variants
    variants = {s.key for s in options.SCHEMA if s.group == "variant"}
    assert {
        "interface_yield",
        "wall_normal_stress",
        "yield_pressure",
        "sigma_location",
        "r_neighbourhood",
        "proximal_restarts",
        "pressure_gauge",
        "formulation",
        "kappa_air",
    } <= variants


def test_every_default_passes_its_own_validation_in_rust():
    for s in options.SCHEMA:
        if s.required:
            with pytest.raises(ParameterError, match=f"`{s.key}`"):
                s.check(None)
            continue
        assert s.check(s.default) == s.default, s.key
        if s.kind == "choice":
            assert s.default in s.choices


def test_out_of_range_is_refused_naming_the_option_and_its_range():
    for s in options.SCHEMA:
        if s.kind in ("float", "int") and s.hi is not None and s.hi != float("inf"):
            bad = s.hi if s.hi_open else (s.hi + 1 if s.kind == "int" else s.hi * 1.5 + 1.0)
        elif s.kind == "choice":
            bad = "no-such-choice"
        elif s.kind == "bool":
            bad = 1
        else:
            continue
        with pytest.raises(ParameterError) as info:
            s.check(bad)
        assert f"`{s.key}`" in str(info.value) and s.allowed in str(info.value), str(info.value)


def test_python_defaults_agree_with_rust():
    # the flat form and each room's object: every option, the schema's default
    n = granrs.Numerics()
    fields = {f.name for f in dataclasses.fields(n)}
    assert fields == {s.key for s in FLAT} - set(options.MODEL_ARGUMENTS)
    for s in FLAT:
        if s.key in fields:
            assert getattr(n, s.key) == s.default, s.key
    assert set(options.ROOM_OBJECTS) == {"time", "bi_projection", "interface", "active_region"}
    for room, cls in options.ROOM_OBJECTS.items():
        obj = cls() if cls is not granrs.ActiveRegion else cls(band=8)
        assert {s.key for s in cls.FIELDS.values()} == {s.key for s in options.room(room)}
        for name, s in cls.FIELDS.items():
            if not (cls is granrs.ActiveRegion and name == "band"):
                assert getattr(obj, name) == s.default, (cls, name)
    # every variant of the model's flat options is a field of its room's object, or of the numerics
    for s in FLAT:
        if s.group == "variant":
            holder = options.ROOM_OBJECTS.get(s.room, granrs.Numerics)
            assert s.key in {f.key for f in holder.FIELDS.values()}, s.key
    assert not hasattr(granrs, "Variants")
    # the defaults a model built with nothing given holds, read back from Rust
    m = granrs.Model(granrs.Grid(8, 8, 1.0, 1.0), granrs.Material(1.0, 1.0))
    held = m._rust.options()
    assert held == {s.key: s.default for s in FLAT}
    # the objects of the rheology, pore pressure and walls
    assert granrs.DruckerPrager().friction_angle == options.spec("friction_angle", "drucker-prager").default
    p = granrs.PorePressure(diffusivity=0.035)
    for s in options.room("pore_pressure"):
        if not s.required:
            assert getattr(p, s.key) == s.default, s.key


#: the column's own choices, where its run-file default is not the schema's: each is stated once,
#: in the column's default objects (granrs.cases.column.column_rheology, column_numerics,
#: column_interface, column_pore_pressure, with the measured reasons in their docstrings), and the
#: base's α_b
COLUMN_CHOICES = {
    "bi_projection.theta": 0.8,
    "bi_projection.tolerance": 1e-3,
    "interface.mass_correction": True,
    "numerics.convection_scheme": "weno5",
    "pore_pressure.kappa_air": 1e8,
    "pore_pressure.diffusivity": 0.035,
    "base.friction_angle": 15.0,
}


def test_the_columns_choices_are_its_default_objects():
    case = ColumnCase()
    assert case.rheology == column_rheology() and case.numerics == column_numerics()
    assert case.interface == column_interface() and case.pore_pressure == column_pore_pressure()
    held = {
        "bi_projection.theta": case.rheology.projection.theta,
        "bi_projection.tolerance": case.rheology.projection.tolerance,
        "interface.mass_correction": case.interface.mass_correction,
        "numerics.convection_scheme": case.numerics.convection_scheme,
        "pore_pressure.kappa_air": case.pore_pressure.kappa_air,
        "pore_pressure.diffusivity": case.pore_pressure.diffusivity,
        "base.friction_angle": case.base.friction_angle,
    }
    assert held == COLUMN_CHOICES
    # every other option of the column's objects is the schema's default
    for name, obj in case.objects().items():
        for field, s in obj.FIELDS.items():
            section = {"rheology.projection": "bi_projection"}.get(name, name)
            if f"{section}.{field}" not in COLUMN_CHOICES:
                assert getattr(obj, field) == s.default, (name, field)


def test_every_run_file_key_of_an_option_has_the_schemas_range_and_a_stated_default():
    by_option = {}
    for k in config.KEYS:
        if k.option is None:
            continue
        o = k.option
        by_option.setdefault((o.room, o.key), []).append(k)
        assert (k.lo, k.hi, k.lo_open, k.hi_open, tuple(k.choices)) == (o.lo, o.hi, o.lo_open, o.hi_open, o.choices)
        assert k.allowed() == o.allowed.removeprefix("None or ") + ("; absent: none" if k.optional else "")
        if not o.object:  # a flat option: in the section of its room's object, else [numerics]
            assert k.section == (o.room if o.room in options.ROOM_OBJECTS else "numerics"), k.full
        if k.optional:
            # absent: None, an option that can be off, or the main key of an object that can be absent
            assert k.default is None and (o.optional or k.full in ("side_walls.width", "side_walls.friction_angle"))
        elif k.default != o.default:
            assert COLUMN_CHOICES.get(k.full) == k.default, (
                f"{k.full}: default {k.default!r} is neither the schema's nor a stated column choice"
            )
    # every option of the model is a run-file key, those off by default (None) included: only the
    # Model argument `air` (case.model) and the pore pressure's supply (the scene's) are not
    scene = {("model", "air"), ("pore_pressure", "basal_gradient"), ("pore_pressure", "basal_x_min")}
    scene |= {("pore_pressure", "basal_x_max")}
    laws = {"bingham", "mu-i"}  # made from rheology.law and rheology.friction_angle (jop_mu_i)
    for s in options.SCHEMA:
        if (s.room, s.key) in scene or s.room in laws:
            continue
        assert len(by_option.get((s.room, s.key), [])) == 1, f"option `{s.room}.{s.key}` has no single run-file key"


def test_an_absent_optional_key_is_none_and_its_section_needs_its_main_key():
    cfg = config.resolve({})
    assert cfg["active_region"]["band"] is None and cfg["side_walls"]["width"] is None and cfg["time"]["dt"] is None
    case = config.column_case(cfg)
    assert case.active_region is None and case.side_walls is None and case.time.dt is None
    case = config.column_case(
        config.resolve({"active_region": {"band": 8, "sides": "open-right"}, "side_walls": {"width": 0.1}})
    )
    assert case.active_region == granrs.ActiveRegion(8, sides="open-right")
    assert case.side_walls == granrs.SideWalls(0.1, case.base.friction_angle)  # absent angle: the base's
    for raw, name in (
        ({"active_region": {"sides": "open-right"}}, "active_region.sides"),
        ({"side_walls": {"friction_angle": 10.0}}, "side_walls.friction_angle"),
    ):
        with pytest.raises(ParameterError, match=f"`{name}`: allowed only with"):
            config.resolve(raw)
    rows = config.describe()
    for full in ("active_region.band", "side_walls.width", "side_walls.friction_angle", "time.dt"):
        assert any(line.startswith(f"| `{full}` |") and "| `absent` |" in line for line in rows.splitlines()), full


def test_granrs_keys_and_the_docs_reference_show_each_option():
    table = config.describe()
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        import granrs_docs
    finally:
        sys.path.pop(0)
    keys_md, options_md = granrs_docs.keys_markdown(), granrs_docs.options_markdown()
    for k in config.KEYS:
        if k.option is None:
            continue
        default = ("absent" if k.optional else "derived") if k.default is None else config.toml_value(k.default)
        row = f"| `{k.full}` | {k.allowed()} | `{default}` |"
        assert row in table, row
        assert f"| `{k.full}` | {k.allowed().replace('|', chr(92) + '|')} | `{default}` |" in keys_md, k.full
    renamed = {
        (s.room, s.key): f"{cls.__name__}.{name}"
        for cls in options.ROOM_OBJECTS.values()
        for name, s in cls.FIELDS.items()
        if name != s.key
    }
    assert renamed[("bi_projection", "picard_tol")] == "BiProjection.tolerance"
    for s in options.SCHEMA:
        default = "required" if s.required else repr(s.default)
        field = f" (`{renamed[s.room, s.key]}`)" if (s.room, s.key) in renamed else ""
        row = f"| `{s.key}`{field} | {s.allowed.replace('|', chr(92) + '|')} | `{default}` | {s.group} |"
        assert row in options_md, s.key


def test_a_variant_in_numerics_names_its_section():
    with pytest.raises(ParameterError, match=r"`numerics.interface_yield`.*`bi_projection.interface_yield`"):
        config.resolve({"numerics": {"interface_yield": "paper"}})
    raw = {"bi_projection": {"interface_yield": "granular-side"}, "numerics": {"pressure_rtol": 1e-9}}
    case = config.column_case(config.resolve(raw))
    assert case.rheology.projection.interface_yield == "granular-side" and case.numerics.pressure_rtol == 1e-9
    assert dataclasses.replace(case.numerics, pressure_rtol=1e-8) == column_numerics()


@pytest.mark.parametrize(
    "section, name, place",
    [
        ("variants", "proximal_restarts", "bi_projection.proximal_restarts"),
        ("variants", "wall_normal_stress", "bi_projection.wall_normal_stress"),
        ("variants", "piece_removal_cells", "interface.piece_removal_cells"),
        ("variants", "interface_velocity", "interface.velocity"),
        ("variants", "pressure_gauge", "numerics.pressure_gauge"),
        ("numerics", "mass_correction", "interface.mass_correction"),
        ("materials", "grain_density", "grains.density"),
        ("case", "aspect_ratio", "geometry.aspect_ratio"),
        ("grid", "length", "geometry.length"),
    ],
)
def test_a_key_outside_its_objects_section_is_refused_naming_that_section(section, name, place, tmp_path):
    # a key given in a section that is not one ([variants], [materials]) or in another object's
    # section ([case], [grid], [numerics]) is refused naming the section of the object that owns
    # it: in a run file, and with --set
    owner = place.split(".")[0]
    if section in config.SECTIONS:
        told = rf"`{section}.{name}`: not a key of \[{section}\]; allowed as `{re.escape(place)}`"
    else:
        told = (
            rf"`{section}`: unknown section; its key `{name}` belongs to \[{owner}\]: allowed as `{re.escape(place)}`"
        )
    with pytest.raises(ParameterError, match=told):
        config.resolve({section: {name: 1}})
    run_file = tmp_path / "misplaced.toml"
    run_file.write_text(f"[{section}]\n{name} = 1\n")
    with pytest.raises(ParameterError, match=told):
        config.load_config(run_file)
    with pytest.raises(ParameterError, match=told):
        config.apply_sets({}, [f"{section}.{name}=1"])


# ---- provenance: from the CLI flag or run-file key to the Rust use, each default and range once
#: the Python files on the way from the CLI and the run files to the Rust model
CHAIN = [
    "cli.py",
    "config.py",
    "options.py",
    "model.py",
    "rheology.py",
    "boundary.py",
    "cases/column/case.py",
    "cases/column/build.py",
    "cases/column/run.py",
    "cases/column/__init__.py",
    "cases/column/depth_averaged.py",
    "depth_averaged.py",
]


def cli_parser_actions(cli):
    """The actions of `granrs run`'s parser (its flags)."""
    import argparse

    captured = {}
    real = argparse.ArgumentParser.parse_args

    def grab(self, args=None, namespace=None):
        captured["run"] = self._subparsers._group_actions[0].choices["run"]
        raise SystemExit(0)

    argparse.ArgumentParser.parse_args = grab
    try:
        with pytest.raises(SystemExit):
            cli.main(["info"])
    finally:
        argparse.ArgumentParser.parse_args = real
    return captured["run"]._actions


def _python_sources():
    return [ROOT / "python" / "granrs" / f for f in CHAIN]


def _rust_sources():
    return list((ROOT / "rust").rglob("src/**/*.rs"))


def _count(paths, pattern):
    rx = re.compile(pattern)
    return [
        (p.relative_to(ROOT) if p.is_relative_to(ROOT) else p, i + 1)
        for p in paths
        for i, line in enumerate(p.read_text().splitlines())
        if rx.search(line)
    ]


def test_the_friction_angle_is_declared_once():
    # --friction-angle → run-file key rheology.friction_angle → ColumnCase.rheology, a DruckerPrager → Rust
    # RheologyLaw::DruckerPrager: the default 27 and the range (0, 90) are written only in the
    # Rust table DRUCKER_PRAGER_OPTIONS
    key = config.key("rheology.friction_angle")
    spec = options.spec("friction_angle", "drucker-prager")
    assert (key.default, key.lo, key.hi, key.lo_open, key.hi_open) == (spec.default, 0.0, 90.0, True, True)
    assert ColumnCase().rheology.friction_angle == spec.default == granrs.DruckerPrager().friction_angle
    from granrs import cli

    flag = next(a for a in cli_parser_actions(cli) if "--friction-angle" in a.option_strings)
    import argparse

    with pytest.raises(argparse.ArgumentTypeError, match=r"`--friction-angle` = '90': allowed a number in \(0, 90\)"):
        flag.type("90")  # the flag's range is the key's, the schema's
    rust = [
        (p, m.group(0))
        for p in _rust_sources()
        for m in re.finditer(r'"friction_angle",\s*27(\.0)?\s*,', p.read_text())
    ]
    assert len(rust) == 1 and "rheology" in str(rust[0][0]), rust
    py = _count(
        _python_sources(), r"friction_angle.*\b27(\.0)?\b|friction.*\b(89|90)(\.0)?\b|FRICTION_ANGLE_RANGE\s*=\s*\(\s*0"
    )
    assert py == [], py


def test_the_pore_pressure_ratio_is_declared_once():
    # --pore-pressure-ratio → run-file key fluidisation.pore_pressure_ratio → ColumnCase's
    # Fluidisation.pore_pressure_ratio → the basal gradient −β φ ρ_s g and the initial p_f
    # (cases/column/build.py) → Rust PorePressureConfig::basal_flux: β's default is Fluidisation's
    # field, its range Fluidisation.RANGES
    key = config.key("fluidisation.pore_pressure_ratio")
    assert key.default == ColumnCase().fluidisation.pore_pressure_ratio and (key.lo, key.hi) == (0.0, 1.0)
    defaults = _count(_python_sources(), r"pore_pressure_ratio\s*(:\s*float\s*)?=\s*[0-9]|β \(0\.9")
    assert [str(p) for p, _ in defaults] == ["python/granrs/cases/column/case.py"], defaults
    ranges = _count(
        _python_sources(), r'"pore_pressure_ratio"[^)]*\(\s*0\.0\s*,\s*1\.0\s*\)|pore_pressure_ratio.*0\.0, 1\.0'
    )
    assert len(ranges) == 1 and str(ranges[0][0]) == "python/granrs/cases/column/case.py", ranges
    assert _count(_rust_sources(), r"pore_pressure_ratio") == []


def test_the_provenance_checks_can_fail(tmp_path, monkeypatch):
    # a second default written elsewhere is found by the same pattern
    extra = tmp_path / "granrs_extra.py"
    extra.write_text("pore_pressure_ratio: float = 0.9\nfriction_angle: float = 27.0\n")
    assert _count([extra], r"pore_pressure_ratio\s*(:\s*float\s*)?=\s*[0-9]")
    assert _count([extra], r"friction_angle.*\b27(\.0)?\b")


NEW_OPTION = """
import importlib, sys
sys.path.insert(0, {ext!r})
import granrs
from granrs import _granrs
real_schema, real_check = _granrs.schema, _granrs.check_option
fake = dict(key="fake_tolerance", room="model", kind="float", default=1e-3, optional=False, required=False,
            unit="1", doc="a tolerance declared in Rust only", group="common",
            allowed="a number in [0, 1] (dimensionless)", lo=0.0, hi=1.0, lo_open=False, hi_open=False,
            choices=(), object=False)
_granrs.schema = lambda: [fake] + real_schema()
_granrs.check_option = lambda key, value, room=None, name=None: (
    float(value) if key == "fake_tolerance" else real_check(key, value, room=room, name=name))
import granrs.options, granrs.rheology, granrs.model, granrs.cases.column.case, granrs.cases.column, granrs.config
for m in ("options", "rheology", "model", "cases.column.case", "cases.column.build", "cases.column", "config"):
    importlib.reload(sys.modules["granrs." + m])
from granrs import config, options
import granrs_docs
assert options.Numerics.FIELDS["fake_tolerance"].default == 1e-3
assert options.Numerics(fake_tolerance=0.5).options()["fake_tolerance"] == 0.5
k = config.key("numerics.fake_tolerance")
assert (k.default, k.lo, k.hi, k.doc) == (1e-3, 0.0, 1.0, "a tolerance declared in Rust only")
assert config.column_case(config.resolve({{"numerics": {{"fake_tolerance": 0.25}}}})).numerics.fake_tolerance == 0.25
assert "| `numerics.fake_tolerance` | a number in [0, 1] (dimensionless) | `0.001` |" in config.describe()
assert "| `numerics.fake_tolerance` |" in granrs_docs.keys_markdown()
assert "| `fake_tolerance` | a number in [0, 1] (dimensionless) | `0.001` | common |" in granrs_docs.options_markdown()
print("ok")
"""


def test_an_option_declared_in_rust_reaches_every_consumer():
    # a new option in the schema (as its Rust declaration exports it) appears, with nothing written
    # for it in Python, in Numerics, the run files' [numerics], the ColumnCase built from them,
    # `granrs keys` and the docs' key and option references (a child process: the modules are
    # made again from the extended schema)
    import subprocess

    code = NEW_OPTION.format(ext=str(ROOT / "docs" / "_ext"))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]


def test_an_option_set_in_two_places_is_refused_naming_both():
    grid, dense = granrs.Grid(8, 8, 1.0, 1.0), granrs.Material(1.0, 1.0)
    with pytest.raises(ParameterError, match=r"`numerics.cfl` = 0.3: also set by `time_stepping.cfl` = 0.5"):
        granrs.Model(grid, dense, numerics=granrs.Numerics(cfl=0.3), time_stepping=granrs.TimeStepping())
    # the same value in both places, or an object alone, is one setting
    granrs.Model(grid, dense, numerics=granrs.Numerics(cfl=0.3), time_stepping=granrs.TimeStepping(cfl=0.3))
    with pytest.raises(
        ParameterError, match=r"`numerics.picard_tol` = 1e-06: also set by `rheology.projection.tolerance`"
    ):
        ColumnCase(numerics=granrs.Numerics(picard_tol=1e-6)).validate()
    with pytest.raises(ParameterError, match="`rheology.viscosity` = 0.5: allowed None or the dense material's"):
        granrs.Model(grid, dense, rheology=granrs.DruckerPrager(viscosity=0.5))


def test_with_options_puts_each_option_into_the_object_that_holds_it():
    case = ColumnCase().with_options(theta=0.6, picard_tol=1e-4, dt=1e-3, proximal_restarts=2, pressure_rtol=1e-9)
    assert (case.rheology.projection.theta, case.rheology.projection.tolerance) == (0.6, 1e-4)
    assert case.time.dt == 1e-3 and case.rheology.projection.proximal_restarts == 2
    assert case.numerics.pressure_rtol == 1e-9
    case = ColumnCase().with_options(piece_removal_cells=4, interface_velocity="extended")
    assert (case.interface.piece_removal_cells, case.interface.velocity) == (4, "extended")
    assert ColumnCase().rheology.projection.theta == 0.8  # the original is unchanged
    with pytest.raises(ParameterError, match="`active_region_sides`.*only with an active_region"):
        ColumnCase().with_options(active_region_sides="open-right")
    with pytest.raises(ParameterError, match="`no_such_option`: not an option"):
        ColumnCase().with_options(no_such_option=1)
    with pytest.raises(ParameterError, match=r"`theta` = 1.5: allowed a number in \[0, 1\)"):
        ColumnCase().with_options(theta=1.5)


def test_the_clocks_options_are_checked_together_in_rust():
    """TimeConfig::validate's rule across options (time_stepping/clock.rs): a CFL number for
    the light phase above cfl_abort, which would have every step it sets rejected, is refused
    when the object is made, whichever of the two is set; within it, it is kept."""
    for kw in ({"cfl_light": 1.5}, {"cfl_light": 0.9, "cfl_abort": 0.8}):
        with pytest.raises(ParameterError, match=r"`time.cfl_light` = .*at most time.cfl_abort"):
            granrs.TimeStepping(**kw)
    with pytest.raises(ParameterError, match=r"`time.cfl_light` = 1.5"):
        ColumnCase().with_options(cfl_light=1.5)
    assert granrs.TimeStepping(cfl_light=0.9).cfl_light == 0.9
    with pytest.raises(ParameterError, match=r"`room` = rheology: allowed 'time'"):
        granrs._granrs.check_room("rheology", {})
    assert ColumnCase().with_options(cfl_light=0.8, cfl_abort=0.8).time.cfl_light == 0.8


def test_the_depth_averaged_binding_takes_one_configuration_object():
    from granrs.depth_averaged import DepthAveragedModel

    defaults = _granrs.RustDepthAveraged.defaults()
    m = DepthAveragedModel(cells=8, length=1.0)
    assert {k: m.config[k] for k in defaults} == defaults  # the Python defaults are the Rust core's
    with pytest.raises(ParameterError, match="`config` = cell: allowed a key .* one of cells, length"):
        _granrs.RustDepthAveraged({"cell": 8, "length": 1.0})
    with pytest.raises(ParameterError, match="`cells`"):
        _granrs.RustDepthAveraged({"length": 1.0})
    with pytest.raises(ParameterError, match="`cfl`"):
        _granrs.RustDepthAveraged({"cells": 8, "length": 1.0, "cfl": 0.9})


def _window_refusal(grid, **kw) -> str:
    try:
        granrs.Model.check(grid, **kw)
    except ParameterError as err:
        return str(err)
    return ""


def test_an_active_region_refuses_a_pressure_gauge_other_than_top_by_the_gauge_s_key(monkeypatch):
    """An active region needs the 'top' pressure gauge on a two-phase model with walls right and
    top: the refusal names `numerics.pressure_gauge` and what is allowed, exactly where the Rust
    check refuses the combination (its message names `active_region` with no value), over every
    gauge, a law with and without a pressure-dependent yield stress and a base with and without a
    Coulomb angle ('auto' resolves to 'top' with either); an outflow side and the granular-only
    model keep the Rust check's own refusals."""
    import granrs.model

    grid = granrs.Grid(32, 16, 2.0, 1.0)
    check = granrs.model._check_window_gauge
    refused = 0
    for gauge in ("auto", "mean", "top"):
        for rheology in (granrs.Newtonian(), granrs.Bingham(yield_stress=1.0), granrs.DruckerPrager(27.0)):
            for bc in (
                granrs.BoundaryConditions(bottom=granrs.NoSlip()),
                granrs.BoundaryConditions(bottom=granrs.CoulombWall(15.0)),
                granrs.BoundaryConditions(bottom=granrs.CoulombWall()),
                granrs.BoundaryConditions(right=granrs.Outflow()),
            ):
                for air in ("resolved", "free-surface"):
                    kw = dict(
                        dense=granrs.Material(1000.0, 1.0),
                        light=granrs.AIR,
                        gravity=(0.0, -9.81),
                        rheology=rheology,
                        bc=bc,
                        air=air,
                        active_region=granrs.ActiveRegion(4),
                        numerics=granrs.Numerics(pressure_gauge=gauge),
                    )
                    python = _window_refusal(grid, **kw)
                    monkeypatch.setattr(granrs.model, "_check_window_gauge", lambda *args: None)
                    rust = _window_refusal(grid, **kw)
                    monkeypatch.setattr(granrs.model, "_check_window_gauge", check)
                    by_gauge = python.startswith(f"invalid parameter `numerics.pressure_gauge` = {gauge!r}")
                    assert by_gauge == ("with this pressure gauge" in rust), (gauge, rheology, bc, air, python, rust)
                    assert by_gauge or python == rust
                    refused += by_gauge
    assert refused == 3 * 3 + 2 * 2  # 'mean' with each law and base; 'auto' without τ(p) or a Coulomb angle
    message = _window_refusal(
        grid,
        dense=granrs.Material(1000.0, 1.0),
        light=granrs.AIR,
        active_region=granrs.ActiveRegion(4),
        numerics=granrs.Numerics(pressure_gauge="mean"),
    )
    assert (
        message.startswith("invalid parameter `numerics.pressure_gauge` = 'mean': not allowed with `active_region`")
        and "allowed 'top'" in message
    ), message
