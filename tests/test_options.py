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
from granrs.cases.column import ColumnCase
from granrs.cases.column.case import COLUMN_NUMERICS

ROOT = Path(__file__).resolve().parent.parent
FLAT = [s for s in options.SCHEMA if not s.object]


def test_schema_is_the_rust_tables_and_keys_are_unique():
    raw = _granrs.schema()
    assert [d["key"] for d in raw] == [s.key for s in options.SCHEMA]
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
    for cls, room in (
        (granrs.TimeStepping, "time"),
        (granrs.BiProjection, "bi_projection"),
        (granrs.ActiveRegion, "active_region"),
    ):
        obj = cls() if cls is not granrs.ActiveRegion else cls(band=8)
        assert {s.key for s in cls.FIELDS.values()} == {s.key for s in options.room(room)}
        for name, s in cls.FIELDS.items():
            if not (cls is granrs.ActiveRegion and name == "band"):
                assert getattr(obj, name) == s.default, (cls, name)
    assert {s.key for s in granrs.Variants.FIELDS.values()} == {s.key for s in FLAT if s.group == "variant"}
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


#: the column's own choices, where its run-file default is not the schema's (the reasons are in
#: granrs.cases.column's docstring and beside each field of ColumnCase)
COLUMN_CHOICES = {
    "theta": 0.8,
    "picard_tol": 1e-3,
    "mass_correction": True,
    "convection_scheme": "weno5",
    "kappa_air": 1e8,
    "friction_angle": 27.0,
    "wall_friction_angle": 15.0,
    "diffusivity": 0.035,
}


def test_every_run_file_key_of_an_option_has_the_schemas_range_and_a_stated_default():
    by_option = {}
    for k in config.KEYS:
        if k.option is not None:
            by_option.setdefault((k.option.room, k.option.key), []).append(k)
            o = k.option
            if not o.optional:
                assert (k.lo, k.hi, k.lo_open, k.hi_open, tuple(k.choices)) == (
                    o.lo,
                    o.hi,
                    o.lo_open,
                    o.hi_open,
                    o.choices,
                ), k.full
                assert k.allowed() == o.allowed
            assert k.section == ("variants" if o.group == "variant" else k.section), k.full
            if k.name == "active_region":
                assert k.default == 0 and o.default is None  # 0: off, the run files' None
            elif k.default != o.default:
                assert COLUMN_CHOICES.get(k.name) == k.default, (
                    f"{k.full}: default {k.default!r} is neither the schema's nor a stated column choice"
                )
    # every option of the model that TOML can hold is a run-file key (only the Model arguments'
    # `air` and the options off by default, None, are not)
    for s in FLAT:
        if s.optional or s.key == "air":
            continue
        assert (s.room, s.key) in by_option, f"option `{s.key}` has no run-file key"
    assert COLUMN_NUMERICS.items() <= COLUMN_CHOICES.items()


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
        default = "derived" if k.default is None else config.toml_value(k.default)
        row = f"| `{k.full}` | {k.allowed()} | `{default}` |"
        assert row in table, row
        assert f"| `{k.full}` | {k.allowed().replace('|', chr(92) + '|')} | `{default}` |" in keys_md, k.full
    for s in options.SCHEMA:
        default = "required" if s.required else repr(s.default)
        assert f"| `{s.key}` | {s.allowed.replace('|', chr(92) + '|')} | `{default}` | {s.group} |" in options_md, s.key


def test_a_variant_in_numerics_names_its_section():
    with pytest.raises(ParameterError, match=r"`numerics.interface_yield`.*`variants.interface_yield`"):
        config.resolve({"numerics": {"interface_yield": "paper"}})
    cfg = config.resolve({"variants": {"interface_yield": "granular-side"}, "numerics": {"pressure_rtol": 1e-9}})
    case = config.column_case(cfg)
    assert case.interface_yield == "granular-side" and case.numerics == {"pressure_rtol": 1e-9}


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
]


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
    # run-file key rheology.friction_angle → ColumnCase.friction_angle → DruckerPrager → Rust
    # RheologyLaw::DruckerPrager: the default 27 and the range (0, 90) are written only in the
    # Rust table DRUCKER_PRAGER_OPTIONS
    key = config.key("rheology.friction_angle")
    spec = options.spec("friction_angle", "drucker-prager")
    assert (key.default, key.lo, key.hi, key.lo_open, key.hi_open) == (spec.default, 0.0, 90.0, True, True)
    assert ColumnCase().friction_angle == spec.default == granrs.DruckerPrager().friction_angle
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
    # --pore-pressure-ratio → run-file key case.pore_pressure_ratio → ColumnCase.pore_pressure_ratio
    # → the basal gradient −β φ ρ_s g and the initial p_f (cases/column/build.py) → Rust
    # PorePressureConfig::basal_flux: β's default is ColumnCase's field, its range SCENE_RANGES
    key = config.key("case.pore_pressure_ratio")
    assert key.default == ColumnCase().pore_pressure_ratio and (key.lo, key.hi) == (0.0, 1.0)
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
