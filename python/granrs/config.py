"""Run files: a TOML file that describes one run, validated strictly before any work starts.

A run file has the sections [case], [grid], [materials], [numerics] and [output]; every key is
optional and takes the default listed in ``KEYS`` (the paper's fluidised column). Unknown
sections or keys, wrong types and out-of-range values raise ``granrs.ParameterError`` naming the
full key (``numerics.cfl``) and what is allowed, with its unit. ``granrs keys`` prints the table.

    cfg = load_config("examples/paper_fluidised.toml", sets=["numerics.t_end=0.1"])
    write_config(cfg, "out/config.resolved.toml")     # the resolved file (every key explicit)
    case = column_case(cfg)                            # a granrs.cases.column.ColumnCase

A resolved configuration is a plain ``dict[section, dict[key, value]]`` holding every key.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Union

from . import options

if sys.version_info >= (3, 11):
    import tomllib
else:  # the same parser, before it joined the standard library
    import tomli as tomllib

from ._granrs import ParameterError
from .cases.column import ColumnCase
from .cases.column.case import COLUMN_NUMERICS, OPTION_FIELD_KEYS, OPTION_FIELDS, SCENE_CHOICES, SCENE_RANGES
from .options import OptionInfo


@dataclass(frozen=True)
class Key:
    """One key of a run file: its type ('float', 'int', 'bool', 'str', 'choice', 'list'), default
    (None: derived from other keys, see ``doc``), unit, range [lo, hi] (hi excluded when
    ``hi_open``) and allowed values (choices; for a list, the allowed items)."""

    section: str
    name: str
    kind: str
    default: object
    unit: str
    doc: str
    lo: Optional[float] = None
    hi: Optional[float] = None
    hi_open: bool = False
    choices: tuple = ()
    lo_open: bool = False
    #: the schema option this key sets (None: a key of the scene or the run)
    option: Optional[OptionInfo] = None

    @property
    def full(self) -> str:
        return f"{self.section}.{self.name}"

    def allowed(self) -> str:
        """The allowed values, in words (used in error messages and in ``granrs keys``); for a key
        of a schema option, the schema's own words."""
        if self.option is not None and not self.option.optional:
            return self.option.allowed
        if self.kind in ("float", "int"):
            what = "a number" if self.kind == "float" else "an integer"
            rng = f"{'(' if self.lo_open else '['}{_fmt(self.lo)}, {_fmt(self.hi)}{')' if self.hi_open else ']'}"
            return f"{what} in {rng} ({self.unit_words})"
        if self.kind == "bool":
            return "true or false"
        if self.kind == "choice":
            return "one of " + ", ".join(f"'{c}'" for c in self.choices)
        if self.kind == "list":
            return "a list of distinct items from " + ", ".join(f"'{c}'" for c in self.choices)
        return "a non-empty string" + (f" ({self.unit_words})" if self.unit else "")

    @property
    def unit_words(self) -> str:
        return "dimensionless" if self.unit == "1" else self.unit


def _fmt(x) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


# defaults come from the column case itself, so a run file and `granrs run column` agree
_D = {f.name: f.default for f in dataclasses.fields(ColumnCase) if f.default is not dataclasses.MISSING}
_PAPER_LENGTH = ColumnCase().domain()[0]
_R = SCENE_RANGES
#: the unit words of the schema's SI symbols where a run file's comment differs
_SECTION_OF_GROUP = {"common": "numerics", "variant": "variants"}


def _from_schema(section: str, name: str, spec: OptionInfo, default, doc: Optional[str] = None) -> Key:
    """The run-file key ``section.name`` of a schema option: its kind, range, choices, unit and
    doc are the schema's; ``default`` is the column's value."""
    kind = "choice" if spec.kind == "choice" else spec.kind
    lo = spec.lo if spec.kind != "int" or spec.lo is None else int(spec.lo)
    hi = spec.hi if spec.kind != "int" or spec.hi is None else int(spec.hi)
    return Key(
        section,
        name,
        kind,
        default,
        spec.unit,
        doc or spec.doc,
        lo,
        hi,
        hi_open=spec.hi_open,
        choices=tuple(spec.choices),
        lo_open=spec.lo_open,
        option=spec,
    )


def _column_option(section: str, name: str, doc: Optional[str] = None) -> Key:
    key, room = OPTION_FIELDS[name]
    return _from_schema(section, name, options.spec(key, room), _D[name], doc)


_AR = options.spec("active_region")
#: The schema's flat options that are run-file keys without a ColumnCase field of their own:
#: [numerics] (group common) and [variants] (group variant), at the column's values. An option
#: that is off by default (None: TOML has no null) is set from Python, ``ColumnCase(numerics=)``.
_GENERIC = tuple(
    _from_schema(_SECTION_OF_GROUP[s.group], s.key, s, COLUMN_NUMERICS.get(s.key, s.default))
    for s in options.SCHEMA
    if not s.object and s.key not in OPTION_FIELD_KEYS and s.key not in options.MODEL_ARGUMENTS and not s.optional
)

KEYS: tuple[Key, ...] = (
    Key("case", "name", "choice", "column", "", "the case to run", choices=("column",)),
    Key(
        "case",
        "aspect_ratio",
        "float",
        _D["aspect_ratio"],
        "1",
        "a = H_c / L_c, column height over width",
        *_R["aspect_ratio"],
    ),
    Key("case", "width", "float", _D["width"], "m", "L_c, width of the reservoir (gate at x = L_c)", *_R["width"]),
    Key("case", "fluidised", "bool", _D["fluidised"], "", "pore gas pressure on (initial p_f and basal air supply)"),
    Key(
        "case",
        "pore_pressure_ratio",
        "float",
        _D["pore_pressure_ratio"],
        "1",
        "β: initial and supplied pore pressure over the lithostatic one",
        *_R["pore_pressure_ratio"],
    ),
    Key(
        "case",
        "air_supply",
        "choice",
        _D["air_supply"],
        "",
        "sign of the basal air supply: injection (∂p_f/∂y = −β φρ_s g, gas flows up into the column) or the printed literal "
        "∂p_f/∂n = −β φρ_s g with n the outward normal (an outflow)",
        choices=SCENE_CHOICES["air_supply"],
    ),
    Key(
        "case",
        "back_wall",
        "choice",
        _D["back_wall"],
        "",
        "the wall at x = 0: Coulomb friction at wall_friction_angle (the paper's), or free-slip (the cross-code check)",
        choices=SCENE_CHOICES["back_wall"],
    ),
    Key("case", "rheology", "choice", _D["rheology"], "", "granular rheology", choices=("drucker-prager", "mu-i")),
    Key(
        "case",
        "channel_width",
        "float",
        0.0,
        "m",
        "friction of a channel's side walls this far apart (not in the paper's 2D model; the experiment's: 0.1), at the "
        "base's friction angle; 0: none",
        0.0,
        options.spec("width", "side_walls").hi,
    ),
    Key("grid", "ny", "int", _D["ny"], "cells", "cells over the domain height (256 is the paper's grid)", *_R["ny"]),
    Key(
        "grid",
        "length",
        "float",
        None,
        "m",
        f"channel length; default from the column case ({_PAPER_LENGTH:g} m for the paper's column)",
        0.01,
        1000.0,
    ),
    Key(
        "materials",
        "solid_fraction",
        "float",
        _D["solid_fraction"],
        "1",
        "φ, solid volume fraction of the column",
        *_R["solid_fraction"],
    ),
    Key(
        "materials", "grain_density", "float", _D["grain_density"], "kg m-3", "ρ_s, density of the grains", 1.0, 25000.0
    ),
    Key(
        "materials",
        "grain_diameter",
        "float",
        _D["grain_diameter"],
        "m",
        "d_s, grain diameter (used by mu-i)",
        1e-7,
        0.1,
    ),
    _column_option("materials", "friction_angle"),
    _column_option("materials", "wall_friction_angle", "α_b, friction angle of the base and back wall"),
    Key(
        "materials",
        "granular_viscosity",
        "float",
        _D["granular_viscosity"],
        "Pa s",
        "η_s, viscosity of the granular phase",
        *_R["granular_viscosity"],
    ),
    _column_option("materials", "diffusivity"),
    Key(
        "numerics",
        "t_end",
        "float",
        _D["t_end"],
        "s",
        "end of the simulated time (the run stops earlier at rest)",
        *_R["t_end"],
    ),
    _column_option("numerics", "cfl"),
    _column_option("numerics", "threads"),
    _column_option("numerics", "picard_tol"),
    _column_option("numerics", "theta"),
    _column_option("numerics", "step_retries"),
    _column_option("numerics", "mass_correction"),
    Key(
        "numerics",
        "active_region",
        "int",
        0,
        "cells",
        _AR.doc.replace("(None: the whole domain)", "(0: the whole domain)"),
        0,
        int(_AR.hi),  # type: ignore[arg-type]  # the schema bounds the band (tests/test_options.py)
        option=_AR,
    ),
    _column_option("numerics", "active_region_sides"),
    *(k for k in _GENERIC if k.section == "numerics"),
    _column_option("variants", "pore_formulation"),
    _column_option("variants", "kappa_air"),
    _column_option("variants", "r_neighbourhood"),
    _column_option("variants", "sigma_location"),
    _column_option("variants", "interface_yield"),
    _column_option("variants", "wall_normal_stress"),
    _column_option("variants", "yield_pressure"),
    _column_option("variants", "proximal_restarts"),
    *(k for k in _GENERIC if k.section == "variants"),
    Key("output", "dir", "str", "out/run", "path", "output folder, relative to the current directory"),
    Key("output", "fields_every_s", "float", 0.05, "s", "simulated time between field snapshots; 0: none", 0.0, 1e4),
    Key(
        "output",
        "formats",
        "list",
        ["vtk"],
        "",
        "field formats: 'vtk' (.vti + .pvd), 'netcdf' (fields.nc)",
        choices=("vtk", "netcdf"),
    ),
    Key("output", "animation", "bool", True, "", "write animation.gif from the saved fields at the end"),
    Key("output", "checkpoint_every_s", "float", 0.0, "s", "simulated time between checkpoints; 0: none", 0.0, 1e4),
)
#: Keys of [numerics] that are keys of [variants] (a run file that puts them in [numerics] is
#: told where they belong).
_VARIANT_NAMES = {k.name for k in KEYS if k.section == "variants"}
SECTIONS: tuple[str, ...] = tuple(dict.fromkeys(k.section for k in KEYS))
_BY_NAME = {k.full: k for k in KEYS}

Config = dict  # dict[section, dict[key, value]], every key present once resolved


def _bad(key: Key, value, extra: str = "") -> ParameterError:
    return ParameterError(f"invalid parameter `{key.full}` = {value!r}: allowed {key.allowed()}{extra}")


def _check_value(key: Key, value):
    """The value converted to the key's type (an int for a float key becomes a float); raises
    ParameterError naming the key when the type or range is wrong."""
    if key.kind in ("float", "int"):
        ok_type = isinstance(value, int) if key.kind == "int" else isinstance(value, (int, float))
        if isinstance(value, bool) or not ok_type:
            raise _bad(key, value)
        number = float(value) if key.kind == "float" else value
        lo = -math.inf if key.lo is None else key.lo
        hi = math.inf if key.hi is None else key.hi
        too_high = number >= hi if key.hi_open else number > hi
        too_low = number <= lo if key.lo_open else number < lo
        infinite_ok = math.isinf(number) and (number > 0 and hi == math.inf or number < 0 and lo == -math.inf)
        if math.isnan(number) or (not math.isfinite(number) and not infinite_ok) or too_low or too_high:
            raise _bad(key, value)
        return number
    if key.kind == "bool":
        if not isinstance(value, bool):
            raise _bad(key, value)
        return value
    if key.kind == "choice":
        if not isinstance(value, str) or value not in key.choices:
            raise _bad(key, value)
        return value
    if key.kind == "list":
        if (
            not isinstance(value, list)
            or not all(isinstance(v, str) and v in key.choices for v in value)
            or len(set(value)) != len(value)
        ):
            raise _bad(key, value)
        return list(value)
    if not isinstance(value, str) or not value.strip():
        raise _bad(key, value)
    return value


def resolve(raw: dict) -> Config:
    """Validates a parsed run file (a dict of tables) and returns the resolved configuration:
    every key present, defaults filled in, derived defaults computed. Raises ParameterError."""
    if not isinstance(raw, dict):
        raise ParameterError(f"invalid run file: allowed a TOML table with sections {', '.join(SECTIONS)}")
    for section, table in raw.items():
        if section not in SECTIONS:
            raise ParameterError(
                f"invalid parameter `{section}`: unknown section; allowed sections "
                + ", ".join(f"[{s}]" for s in SECTIONS)
            )
        if not isinstance(table, dict):
            raise ParameterError(f"invalid parameter `{section}` = {table!r}: allowed a table [{section}]")
        for name in table:
            if section == "numerics" and name in _VARIANT_NAMES:
                raise ParameterError(
                    f"invalid parameter `numerics.{name}`: a numerical variant; allowed as "
                    f'`variants.{name}` in the section [variants] (docs/models.md, "Variants")'
                )
            if f"{section}.{name}" not in _BY_NAME:
                names = ", ".join(k.name for k in KEYS if k.section == section)
                raise ParameterError(
                    f"invalid parameter `{section}.{name}`: unknown key in [{section}]; allowed keys {names}"
                )
    cfg: Config = {s: {} for s in SECTIONS}
    for key in KEYS:
        table = raw.get(key.section, {})
        if key.name in table:
            cfg[key.section][key.name] = _check_value(key, table[key.name])
        else:
            cfg[key.section][key.name] = list(key.default) if isinstance(key.default, list) else key.default
    _derive_and_cross_check(cfg, given={(s, k) for s, t in raw.items() if isinstance(t, dict) for k in t})
    return cfg


def _derive_and_cross_check(cfg: Config, given: frozenset | set = frozenset()) -> None:
    """Derived values and the checks between keys. ``given``: the (section, key) pairs the run file
    set; a default that another key makes meaningless gives way (the animation's default when no
    fields are saved) instead of being refused."""
    case, grid, out = cfg["case"], cfg["grid"], cfg["output"]
    if grid["length"] is None:
        length = ColumnCase(aspect_ratio=case["aspect_ratio"], width=case["width"]).domain()[0]
        grid["length"] = float(f"{length:.12g}")  # 3.5, not 3.5000000000000004
    if grid["length"] <= case["width"]:
        raise ParameterError(
            f"invalid parameter `grid.length` = {grid['length']!r}: allowed a length (m) greater than "
            f"case.width = {case['width']!r} m (the gate)"
        )
    if out["animation"] and not (out["fields_every_s"] > 0 and out["formats"]):
        if ("output", "animation") in given:
            raise ParameterError(
                "invalid parameter `output.animation` = true: allowed only with output.fields_every_s "
                "> 0 and a non-empty output.formats (the animation is made from the saved fields)"
            )
        out["animation"] = False  # the default animates saved fields: with none saved there is nothing to animate


def parse_scalar(text: str):
    """A value given on the command line, parsed as a TOML value (``0.3``, ``true``, ``"a"``,
    ``["vtk"]``); text that is not valid TOML is taken as a bare string (``mu-i``)."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_sets(raw: dict, sets: Iterable[str]) -> dict:
    """A copy of ``raw`` with ``section.key=value`` overrides applied (values parsed by ``parse_scalar``)."""
    raw = {s: dict(t) if isinstance(t, dict) else t for s, t in raw.items()}
    for item in sets:
        if "=" not in item:
            raise ParameterError(f"invalid parameter `--set {item}`: allowed section.key=value, e.g. numerics.cfl=0.3")
        dotted, text = item.split("=", 1)
        set_value(raw, dotted.strip(), parse_scalar(text.strip()))
    return raw


def set_value(raw: dict, dotted: str, value) -> None:
    """Sets ``raw[section][key] = value`` in place for a dotted key known to ``KEYS``."""
    if dotted not in _BY_NAME:
        raise ParameterError(
            f"invalid parameter `{dotted}`: unknown key; allowed keys " + ", ".join(k.full for k in KEYS)
        )
    section, name = dotted.split(".", 1)
    table = raw.setdefault(section, {})
    if not isinstance(table, dict):
        raise ParameterError(f"invalid parameter `{section}` = {table!r}: allowed a table [{section}]")
    table[name] = value


def key(dotted: str) -> Key:
    """The ``Key`` of a dotted name; ParameterError if unknown."""
    if dotted not in _BY_NAME:
        raise ParameterError(f"invalid parameter `{dotted}`: unknown key; allowed keys " + ", ".join(_BY_NAME))
    return _BY_NAME[dotted]


def read_raw(path: Union[str, Path]) -> dict:
    """The parsed TOML of a run file (not yet validated); ParameterError if unreadable or not TOML."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise ParameterError(f"invalid run file `{path}`: cannot be read ({err.strerror or err})") from None
    except UnicodeDecodeError as err:
        raise ParameterError(
            f"invalid run file `{path}`: not UTF-8 text (byte {err.object[err.start]:#04x} at offset "
            f"{err.start}); allowed a TOML file in UTF-8"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ParameterError(f"invalid run file `{path}`: not valid TOML ({err})") from None


def load_config(path: Union[str, Path], sets: Iterable[str] = ()) -> Config:
    """Reads, overrides (``sets``: ``section.key=value``) and validates a run file."""
    raw = apply_sets(read_raw(path), sets)
    try:
        return resolve(raw)
    except ParameterError as err:
        raise ParameterError(f"{path}: {err}") from None


# ---- writing TOML -------------------------------------------------------------------------------
def toml_value(value) -> str:
    """A Python scalar or list of scalars as a TOML value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # JSON's escapes are valid TOML basic-string escapes
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise ParameterError(f"invalid parameter value {value!r}: cannot be written as TOML")


def dumps(cfg: Config, header: Iterable[str] = ()) -> str:
    """The configuration as TOML text, each key commented with its unit and meaning; ``header``
    lines go first as comments."""
    lines = [f"# {h}" for h in header]
    for section in SECTIONS:
        lines += ["", f"[{section}]"] if lines else [f"[{section}]"]
        for k in (k for k in KEYS if k.section == section):
            if section not in cfg or k.name not in cfg[section] or cfg[section][k.name] is None:
                continue
            unit = f" [{k.unit_words}]" if k.unit and k.unit != "path" else ""
            lines.append(f"{k.name} = {toml_value(cfg[section][k.name])}  # {k.doc}{unit}")
    return "\n".join(lines) + "\n"


def write_config(cfg: Config, path: Union[str, Path], header: Iterable[str] = ()) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dumps(cfg, header), encoding="utf-8")
    return path


def describe() -> str:
    """The table of keys (markdown): key, type and allowed values with units, default, meaning."""
    rows = ["| key | allowed | default | meaning |", "|---|---|---|---|"]
    for k in KEYS:
        default = "derived" if k.default is None else toml_value(k.default)
        rows.append(f"| `{k.full}` | {k.allowed()} | `{default}` | {k.doc} |")
    return "\n".join(rows) + "\n"


def column_case(cfg: Config) -> ColumnCase:
    """The ``ColumnCase`` of a resolved configuration."""
    c, g, m, n, v = cfg["case"], cfg["grid"], cfg["materials"], cfg["numerics"], cfg["variants"]
    fields = {name: section[name] for section in (m, n, v) for name in section if name in OPTION_FIELDS}
    fields["active_region"] = n["active_region"] or None
    # the schema's other options: passed on where they differ from the column's values
    extra = {
        k.name: cfg[k.section][k.name]
        for k in _GENERIC
        if cfg[k.section][k.name] != COLUMN_NUMERICS.get(k.name, k.option.default if k.option else None)
    }
    return ColumnCase(
        aspect_ratio=c["aspect_ratio"],
        width=c["width"],
        fluidised=c["fluidised"],
        channel_width=c["channel_width"] or None,
        air_supply=c["air_supply"],
        back_wall=c["back_wall"],
        pore_pressure_ratio=c["pore_pressure_ratio"],
        rheology=c["rheology"],
        ny=g["ny"],
        length=g["length"],
        t_end=n["t_end"],
        solid_fraction=m["solid_fraction"],
        grain_density=m["grain_density"],
        grain_diameter=m["grain_diameter"],
        granular_viscosity=m["granular_viscosity"],
        numerics=extra,
        **fields,
    )
