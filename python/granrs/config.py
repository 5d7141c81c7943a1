"""Run files: a TOML file that describes one run, validated strictly before any work starts.

A run file has the sections of ``SECTIONS``, one per object of
:class:`~granrs.cases.column.ColumnCase`: the scene ([case], [geometry], [grains],
[fluidisation], [grid]), its physics ([rheology] and its [bi_projection], [base],
[pore_pressure], [side_walls], [interface], [active_region], [time], [rest], [depth_averaged],
[numerics]) and [output]. Every key is optional and takes the default listed in ``KEYS`` (the
paper's fluidised column); a key whose default is None (``Key.optional``: the side walls, the
active region's band, a fixed δt, ...) is off while absent. Unknown
sections or keys, wrong types and out-of-range values raise ``granrs.ParameterError`` naming the
full key (``time.cfl``) and what is allowed, with its unit. ``granrs keys`` prints the table.

    cfg = load_config("examples/paper_fluidised.toml", sets=["time.t_end=0.1"])
    write_config(cfg, "out/config.resolved.toml")     # the resolved file (every key explicit)
    case = column_case(cfg)                            # a granrs.cases.column.ColumnCase

A resolved configuration is a plain ``dict[section, dict[key, value]]`` holding every key.
"""

from __future__ import annotations

import json
import math
import re
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
from .boundary import CoulombWall
from .cases.column import ColumnCase
from .cases.column.case import (
    MODELS,
    SCENE_CHOICES,
    SCENE_RANGES,
    ColumnGeometry,
    Fluidisation,
    Grains,
    RestCriterion,
    jop_mu_i,
)
from .cases.column.depth_averaged import refuse_unused_keys
from .depth_averaged import DEPTH_AVERAGED_CHOICES, DEPTH_AVERAGED_FIELDS, DepthAveraged
from .io.outputs import control_character
from .model import PorePressure, SideWalls
from .options import (
    ROOM_OBJECTS,
    ActiveRegion,
    BiProjection,
    Interface,
    Numerics,
    OptionInfo,
    TimeStepping,
    parse_options as parse_options,
    parse_scalar as parse_scalar,
)
from .rheology import DruckerPrager


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
    #: the key may be absent: its value is then None (TOML has no null; ``doc`` says what None is)
    optional: bool = False

    @property
    def full(self) -> str:
        return f"{self.section}.{self.name}"

    def allowed(self) -> str:
        """The allowed values, in words (used in error messages and in ``granrs keys``); for a key
        of a schema option, the schema's own words."""
        if self.option is not None:
            words = self.option.allowed.removeprefix("None or ")
            return words + ("; absent: none" if self.optional else "")
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
_C = ColumnCase()
_PAPER_LENGTH = _C.domain()[0]
_R = SCENE_RANGES


def _from_schema(section: str, name: str, spec: OptionInfo, default, optional: bool = False, doc: str = "") -> Key:
    """The run-file key ``section.name`` of a schema option: its kind, range, choices, unit and
    doc are the schema's; ``default`` is the column's value; ``optional``: the key may be absent,
    its value then None (TOML has no null), which ``doc`` or the schema's doc explains."""
    lo = spec.lo if spec.kind != "int" or spec.lo is None else int(spec.lo)
    hi = spec.hi if spec.kind != "int" or spec.hi is None else int(spec.hi)
    return Key(
        section,
        name,
        spec.kind,
        default,
        spec.unit,
        doc or spec.doc,
        lo,
        hi,
        hi_open=spec.hi_open,
        choices=tuple(spec.choices),
        lo_open=spec.lo_open,
        option=spec,
        optional=optional,
    )


def _object_keys(section: str, obj, exclude: tuple = ()) -> tuple[Key, ...]:
    """The keys of a room's object (``TimeStepping``, ``BiProjection``, ...) at the column's values:
    one per field, optional where the schema's default is None."""
    return tuple(
        _from_schema(section, name, s, getattr(obj, name), optional=s.optional and s.default is None)
        for name, s in obj.FIELDS.items()
        if name not in exclude
    )


def _room_keys(section: str, room: str, obj, exclude: tuple = (), docs: Optional[dict] = None) -> tuple[Key, ...]:
    """The keys of a schema room's options at ``obj``'s values (None: optional keys)."""
    docs = docs or {}
    return tuple(
        _from_schema(
            section,
            s.key,
            s,
            None if obj is None else getattr(obj, s.key),
            optional=obj is None or s.optional,
            doc=docs.get(s.key, ""),
        )
        for s in options.room(room)
        if s.key not in exclude
    )


#: The flat options of no room's object (``options.ROOM_OBJECTS``): the run files' [numerics].
_NUMERICS = tuple(
    _from_schema("numerics", n, s, getattr(_C.numerics, n), optional=s.optional and s.default is None)
    for n, s in Numerics.FIELDS.items()
    if s.room not in ROOM_OBJECTS
)
_BASE = options.spec("friction_angle", "coulomb")

KEYS: tuple[Key, ...] = (
    Key("case", "name", "choice", "column", "", "the case to run", choices=("column",)),
    Key("case", "model", "choice", _C.model, "", "the model (docs/howto/choosing-a-model.md)", choices=MODELS),
    Key(
        "case",
        "back_wall",
        "choice",
        _C.back_wall,
        "",
        "the wall at x = 0: Coulomb friction at base.friction_angle (the paper's), or free-slip (the cross-code check)",
        choices=SCENE_CHOICES["back_wall"],
    ),
    Key(
        "geometry",
        "aspect_ratio",
        "float",
        _C.geometry.aspect_ratio,
        "1",
        "a = H_c / L_c, column height over width",
        *ColumnGeometry.RANGES["aspect_ratio"],
    ),
    Key(
        "geometry",
        "width",
        "float",
        _C.geometry.width,
        "m",
        "L_c, width of the reservoir (gate at x = L_c)",
        *ColumnGeometry.RANGES["width"],
    ),
    Key(
        "geometry",
        "length",
        "float",
        None,
        "m",
        f"channel length, more than geometry.width (the gate); derived: L_c + 8.25 H_c "
        f"({_PAPER_LENGTH:g} m for the paper's column; the grid rounds the domain up by at most 3 %)",
        0.01,
        1000.0,
    ),
    Key(
        "geometry",
        "height",
        "float",
        None,
        "m",
        "height of the domain, more than the column height H_c = aspect_ratio × width; absent: 1.125 H_c "
        "(the paper's 0.45 m)",
        0.01,
        1000.0,
        optional=True,
    ),
    Key(
        "grains",
        "solid_fraction",
        "float",
        _C.grains.solid_fraction,
        "1",
        "φ, solid volume fraction of the column",
        *Grains.RANGES["solid_fraction"],
    ),
    Key(
        "grains",
        "density",
        "float",
        _C.grains.density,
        "kg m-3",
        "ρ_s, density of the grains",
        *Grains.RANGES["density"],
    ),
    Key(
        "grains",
        "diameter",
        "float",
        _C.grains.diameter,
        "m",
        "d_s, grain diameter (used by mu-i)",
        *Grains.RANGES["diameter"],
    ),
    Key(
        "fluidisation",
        "fluidised",
        "bool",
        _C.fluidisation.fluidised,
        "",
        "pore gas pressure on (initial p_f and basal air supply)",
    ),
    Key(
        "fluidisation",
        "pore_pressure_ratio",
        "float",
        _C.fluidisation.pore_pressure_ratio,
        "1",
        "β: initial and supplied pore pressure over the lithostatic one",
        *Fluidisation.RANGES["pore_pressure_ratio"],
    ),
    Key(
        "fluidisation",
        "air_supply",
        "choice",
        _C.fluidisation.air_supply,
        "",
        "sign of the basal air supply: injection (∂p_f/∂y = −β φρ_s g, gas flows up into the column) or the printed literal "
        "∂p_f/∂n = −β φρ_s g with n the outward normal (an outflow)",
        choices=Fluidisation.CHOICES["air_supply"],
    ),
    Key("grid", "ny", "int", _C.ny, "cells", "cells over the domain height (256 is the paper's grid)", *_R["ny"]),
    Key(
        "rheology",
        "law",
        "choice",
        _C.rheology.spec()[0],
        "",
        "granular rheology: the paper's Drucker–Prager, or μ(I) with μ_s = tan(friction_angle) (jop_mu_i)",
        choices=("drucker-prager", "mu-i"),
    ),
    _from_schema(
        "rheology", "friction_angle", options.spec("friction_angle", "drucker-prager"), _C.rheology.friction_angle
    ),
    Key(
        "rheology",
        "viscosity",
        "float",
        _C.rheology.viscosity,
        "Pa s",
        "η_s, viscosity of the granular phase",
        0.0,
        1e6,
        lo_open=True,
    ),
    *_object_keys("bi_projection", _C.rheology.projection),
    _from_schema(
        "base",
        "friction_angle",
        _BASE,
        _C.base.friction_angle,
        doc="α_b, friction angle of the base and of a Coulomb back wall",
    ),
    *_room_keys(
        "pore_pressure", "pore_pressure", _C.pore_pressure, exclude=("basal_gradient", "basal_x_min", "basal_x_max")
    ),
    *_room_keys(
        "side_walls",
        "side_walls",
        None,
        docs={
            "width": "W, the friction of a channel's side walls this far apart (not in the paper's 2D model; the "
            "experiment's: 0.1); absent: no side walls",
            "friction_angle": "α_w, friction angle of the side walls; absent: base.friction_angle",
        },
    ),
    *_object_keys("interface", _C.interface),
    *_object_keys("active_region", ActiveRegion()),
    Key(
        "time",
        "t_end",
        "float",
        _C.t_end,
        "s",
        "end of the simulated time (the run stops earlier at rest)",
        *_R["t_end"],
    ),
    *_object_keys("time", _C.time),
    Key(
        "rest",
        "speed",
        "float",
        _C.rest.speed,
        "m/s",
        "the run stops at rest: the largest granular speed below this for rest.duration",
        *RestCriterion.RANGES["speed"],
    ),
    Key(
        "rest",
        "duration",
        "float",
        _C.rest.duration,
        "s",
        "how long the granular speed stays below rest.speed before the run stops",
        *RestCriterion.RANGES["duration"],
    ),
    Key(
        "rest",
        "after",
        "float",
        _C.rest.after,
        "s",
        "the time after the release from which the rest criterion is applied",
        *RestCriterion.RANGES["after"],
    ),
    *(
        Key(
            "depth_averaged",
            name,
            "int" if f.lo is not None else "choice",
            f.default,
            f.unit,
            f"{f.doc} (the depth-averaged model only)",
            f.lo,
            f.hi,
            choices=DEPTH_AVERAGED_CHOICES.get(name, ()),
        )
        for name, f in DEPTH_AVERAGED_FIELDS.items()
    ),
    _from_schema("numerics", "threads", options.spec("threads"), _C.threads),
    *_NUMERICS,
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
SECTIONS: tuple[str, ...] = tuple(dict.fromkeys(k.section for k in KEYS))
_BY_NAME = {k.full: k for k in KEYS}
#: The full keys of each key name, and of each schema option's key and each ColumnCase field
#: name a run-file key holds under another name (a key in the wrong section, or in a section
#: that is not one, is told where it belongs).
_PLACES: dict[str, list[str]] = {}
for _k in KEYS:
    for _name in dict.fromkeys((_k.name, *((_k.option.key,) if _k.option is not None else ()))):
        _PLACES.setdefault(_name, []).append(_k.full)
for _name, _full in (("grain_density", "grains.density"), ("grain_diameter", "grains.diameter")):
    _PLACES.setdefault(_name, []).append(_full)


def _misplaced(section: str, name: str) -> Optional[ParameterError]:
    """The error for ``section.name``, not a key, where ``name`` is a key elsewhere (None otherwise)."""
    places = [f for f in _PLACES.get(name, []) if f != f"{section}.{name}"]
    if not places:
        return None
    allowed = " or ".join(f"`{p}`" for p in places)
    if section not in SECTIONS:
        owners = " or ".join(dict.fromkeys(f"[{p.split('.')[0]}]" for p in places))
        return ParameterError(
            f"invalid parameter `{section}`: unknown section; its key `{name}` belongs to {owners}: allowed as {allowed}"
        )
    return ParameterError(f"invalid parameter `{section}.{name}`: not a key of [{section}]; allowed as {allowed}")


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
    bad = control_character(value)
    if bad is not None:
        raise _bad(key, value, f" without control characters (it holds a {bad})")
    return value


def resolve(raw: dict) -> Config:
    """Validates a parsed run file (a dict of tables) and returns the resolved configuration:
    every key present, defaults filled in, derived defaults computed. Raises ParameterError."""
    if not isinstance(raw, dict):
        raise ParameterError(f"invalid run file: allowed a TOML table with sections {', '.join(SECTIONS)}")
    for section, table in raw.items():
        if section not in SECTIONS:
            for name in table if isinstance(table, dict) else ():
                err = _misplaced(section, name)
                if err is not None:
                    raise err
            raise ParameterError(
                f"invalid parameter `{section}`: unknown section; allowed sections "
                + ", ".join(f"[{s}]" for s in SECTIONS)
            )
        if not isinstance(table, dict):
            raise ParameterError(f"invalid parameter `{section}` = {table!r}: allowed a table [{section}]")
        for name in table:
            if f"{section}.{name}" not in _BY_NAME:
                err = _misplaced(section, name)
                if err is not None:
                    raise err
                names = ", ".join(k.name for k in KEYS if k.section == section)
                raise ParameterError(
                    f"invalid parameter `{section}.{name}`: unknown key in [{section}]; allowed keys {names}"
                )
    cfg: Config = {s: {} for s in SECTIONS}
    for key in KEYS:
        table = raw.get(key.section, {})
        if key.name in table and not (key.optional and table[key.name] is None):
            cfg[key.section][key.name] = _check_value(key, table[key.name])
        else:
            cfg[key.section][key.name] = list(key.default) if isinstance(key.default, list) else key.default
    given = {(s, k) for s, t in raw.items() if isinstance(t, dict) for k, v in t.items() if v is not None}
    _derive_and_cross_check(cfg, given=given)
    return cfg


#: The sections of an object that is off (None) while their main key is absent.
_MAIN_KEY = {"active_region": "band", "side_walls": "width"}


def _derive_and_cross_check(cfg: Config, given: frozenset | set = frozenset()) -> None:
    """Derived values and the checks between keys. ``given``: the (section, key) pairs the run file
    set; a default that another key makes meaningless gives way (the animation's default when no
    fields are saved) instead of being refused."""
    case, geometry, out = cfg["case"], cfg["geometry"], cfg["output"]
    # a key set away from its default that the model does not read, before any work (a resolved
    # configuration resolved again gives every key: those at their defaults are not refused)
    refuse_unused_keys(cfg, {(s, k) for s, k in given if k in cfg[s] and cfg[s][k] != _BY_NAME[f"{s}.{k}"].default})
    if geometry["length"] is None:
        shape = ColumnGeometry(aspect_ratio=geometry["aspect_ratio"], width=geometry["width"])
        length = ColumnCase(geometry=shape).domain()[0]
        geometry["length"] = float(f"{length:.12g}")  # 3.5, not 3.5000000000000004
    if geometry["length"] <= geometry["width"]:
        raise ParameterError(
            f"invalid parameter `geometry.length` = {geometry['length']!r}: allowed a length (m) greater than "
            f"geometry.width = {geometry['width']!r} m (the gate)"
        )
    ColumnGeometry(**geometry)  # the height above the column
    for section, what in (
        ("active_region", "the window's band of air cells (absent: the whole domain)"),
        ("side_walls", "the channel width (absent: no side walls)"),
    ):
        needs = _MAIN_KEY[section]
        if cfg[section][needs] is None:
            extra = sorted(
                k
                for s_, k in given
                if s_ == section and k != needs and cfg[section][k] != _BY_NAME[f"{section}.{k}"].default
            )
            if extra:
                raise ParameterError(
                    f"invalid parameter `{section}.{extra[0]}`: allowed only with `{section}.{needs}`, {what}"
                )
    if out["animation"] and not (out["fields_every_s"] > 0 and out["formats"]):
        if ("output", "animation") in given:
            raise ParameterError(
                "invalid parameter `output.animation` = true: allowed only with output.fields_every_s "
                "> 0 and a non-empty output.formats (the animation is made from the saved fields)"
            )
        out["animation"] = False  # the default animates saved fields: with none saved there is nothing to animate
    # keys that the options chosen would not use: refused, naming what would use them
    fixed = cfg["time"]["dt"]
    adaptive = f"allowed only with the adaptive step, time.dt absent (time.dt = {fixed!r} s fixes the step)"
    inert = (
        (
            ("bi_projection", "regularisation"),
            cfg["bi_projection"]["plastic"] == "projection",
            "allowed only with bi_projection.plastic = 'papanastasiou' or 'bi-viscous', whose regularisation it is "
            "(bi_projection.plastic is 'projection')",
        ),
        *((("time", name), fixed is not None, adaptive) for name in ("cfl", "cfl_light", "max_dt", "max_growth")),
        (
            ("time", "cfl_light"),
            case["model"] == "granular",
            "allowed only with the two-phase model, which resolves the light phase whose step it sets "
            "(case.model = 'granular' does not)",
        ),
    )
    for (section, name), unused, why in inert:
        if unused and (section, name) in given and cfg[section][name] is not None:
            raise ParameterError(f"invalid parameter `{section}.{name}` = {cfg[section][name]!r}: not used; {why}")


def apply_sets(raw: dict, sets: Iterable[str]) -> dict:
    """A copy of ``raw`` with ``section.key=value`` overrides applied (values parsed by ``parse_scalar``)."""
    raw = {s: dict(t) if isinstance(t, dict) else t for s, t in raw.items()}
    for item in sets:
        bad = control_character(item)
        if bad is not None:
            raise ParameterError(
                f"invalid parameter `--set {item!r}`: it holds a {bad}; allowed one line section.key=value "
                "without control characters"
            )
        if "=" not in item:
            raise ParameterError(f"invalid parameter `--set {item}`: allowed section.key=value, e.g. time.cfl=0.3")
        dotted, text = item.split("=", 1)
        set_value(raw, dotted.strip(), parse_scalar(text.strip()))
    return raw


def set_value(raw: dict, dotted: str, value) -> None:
    """Sets ``raw[section][key] = value`` in place for a dotted key known to ``KEYS``."""
    if dotted not in _BY_NAME:
        section, _, name = dotted.rpartition(".")
        err = _misplaced(section, name) if section else None
        if err is not None:
            raise err
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


#: The run-file key of each name the model's and the case's errors use (a schema option's key,
#: a ColumnCase field) where it differs from the key's own name in its section.
_FULL_NAMES: dict[str, str] = {
    name: fulls.pop()
    for name, fulls in (
        (n, {k.full for k in KEYS if k.name == n or (k.option is not None and k.option.key == n)})
        for n in {k.name for k in KEYS} | {k.option.key for k in KEYS if k.option is not None}
    )
    if len(fulls) == 1
} | {
    "model": "case.model",
    "active_region": "active_region.band",
    "side_walls": "side_walls.width",
    "rheology": "rheology.law",
}


def full_key_message(message: str) -> str:
    """``message`` with each parameter it names in backticks as its run-file key
    (`pressure_update` → `numerics.pressure_update`); names that are not keys are kept."""

    def full(m: re.Match) -> str:
        name = m.group(1)
        return f"`{_FULL_NAMES.get(name, name)}`"

    return re.sub(r"`([A-Za-z_][A-Za-z0-9_]*)`", full, message)


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
        main = _MAIN_KEY.get(section)
        if main is not None and (section not in cfg or cfg[section].get(main) is None):
            continue  # an object that is off: its section absent
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
        default = ("absent" if k.optional else "derived") if k.default is None else toml_value(k.default)
        rows.append(f"| `{k.full}` | {k.allowed()} | `{default}` | {k.doc} |")
    return "\n".join(rows) + "\n"


def column_case(cfg: Config) -> ColumnCase:
    """The ``ColumnCase`` of a resolved configuration: the scene's keys, and one object per
    section of its physics."""
    c, r = cfg["case"], cfg["rheology"]
    case = ColumnCase(
        geometry=ColumnGeometry(**cfg["geometry"]),
        grains=Grains(**cfg["grains"]),
        fluidisation=Fluidisation(**cfg["fluidisation"]),
        back_wall=c["back_wall"],
        ny=cfg["grid"]["ny"],
        t_end=cfg["time"]["t_end"],
        rest=RestCriterion(**cfg["rest"]),
        model=c["model"],
        depth_averaged=DepthAveraged(**cfg["depth_averaged"]),
        base=CoulombWall(cfg["base"]["friction_angle"]),
        pore_pressure=PorePressure(**cfg["pore_pressure"]),
        time=TimeStepping(**{k: v for k, v in cfg["time"].items() if k != "t_end"}),
        numerics=Numerics(**{k: v for k, v in cfg["numerics"].items() if k != "threads"}),
        interface=Interface(**cfg["interface"]),
        threads=cfg["numerics"]["threads"],
    )
    projection = BiProjection(**cfg["bi_projection"])
    if r["law"] == "mu-i":
        case.rheology = jop_mu_i(
            r["friction_angle"],
            grain_diameter=case.grains.diameter,
            grain_density=case.grains.density,
            viscosity=r["viscosity"],
            projection=projection,
        )
    else:
        case.rheology = DruckerPrager(r["friction_angle"], viscosity=r["viscosity"], projection=projection)
    walls = cfg["side_walls"]
    if walls["width"] is not None:
        angle = walls["friction_angle"] if walls["friction_angle"] is not None else case.base.friction_angle
        case.side_walls = SideWalls(walls["width"], 0.0 if angle is None else angle)  # a frictionless base: 0
    if cfg["active_region"]["band"] is not None:
        case.active_region = ActiveRegion(**cfg["active_region"])
    return case
