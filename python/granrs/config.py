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
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Optional, Union

if sys.version_info >= (3, 11):
    import tomllib
else:  # the same parser, before it joined the standard library
    import tomli as tomllib

from ._granrs import ParameterError
from .cases.column import ColumnCase
from .model import ACTIVE_REGION_SIDES, SIGMA_LOCATIONS
from .rheology import FRICTION_ANGLE_RANGE


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

    @property
    def full(self) -> str:
        return f"{self.section}.{self.name}"

    def allowed(self) -> str:
        """The allowed values, in words (used in error messages and in ``granrs keys``)."""
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

KEYS: tuple[Key, ...] = (
    Key("case", "name", "choice", "column", "", "the case to run", choices=("column",)),
    Key("case", "aspect_ratio", "float", _D["aspect_ratio"], "1", "a = H_c / L_c, column height over width", 0.1, 20.0),
    Key("case", "width", "float", _D["width"], "m", "L_c, width of the reservoir (gate at x = L_c)", 1e-3, 10.0),
    Key("case", "fluidised", "bool", _D["fluidised"], "", "pore gas pressure on (initial p_f and basal air supply)"),
    Key("case", "pore_pressure_ratio", "float", _D["pore_pressure_ratio"], "1", "β: initial and supplied pore pressure over the lithostatic one", 0.0, 1.0),
    Key("case", "rheology", "choice", _D["rheology"], "", "granular rheology", choices=("drucker-prager", "mu-i")),
    Key("case", "channel_width", "float", 0.0, "m",
        "friction of a channel's side walls this far apart (not in the paper's 2D model; the experiment's: 0.1), at the "
        "base's friction angle; 0: none", 0.0, 1000.0),
    Key("grid", "ny", "int", _D["ny"], "cells", "cells over the domain height (256 is the paper's grid)", 8, 4096),
    Key("grid", "length", "float", None, "m", f"channel length; default from the column case ({_PAPER_LENGTH:g} m for the paper's column)", 0.01, 1000.0),
    Key("materials", "solid_fraction", "float", _D["solid_fraction"], "1", "φ, solid volume fraction of the column", 0.01, 0.74),
    Key("materials", "grain_density", "float", _D["grain_density"], "kg m-3", "ρ_s, density of the grains", 1.0, 25000.0),
    Key("materials", "grain_diameter", "float", _D["grain_diameter"], "m", "d_s, grain diameter (used by mu-i)", 1e-7, 0.1),
    Key("materials", "friction_angle", "float", _D["friction_angle"], "degree", "α, internal friction angle",
        *FRICTION_ANGLE_RANGE, lo_open=True),
    Key("materials", "wall_friction_angle", "float", _D["wall_friction_angle"], "degree", "α_b, friction angle of the base and back wall", 0.0, 89.0),
    Key("materials", "granular_viscosity", "float", _D["granular_viscosity"], "Pa s", "η_s, viscosity of the granular phase", 1e-8, 1e6),
    Key("materials", "diffusivity", "float", _D["diffusivity"], "m2 s-1", "κ_f, pore pressure diffusivity", 1e-12, 1e6),
    Key("numerics", "pore_formulation", "choice", _D["pore_formulation"], "",
        "pore pressure outside the grains: p_f = 0 on the surface (granular-only), κ_∞ in the air with a sharp "
        "interface, or the paper's smoothed κ(Φ) = κ_f H_ε + κ_∞(1 − H_ε)",
        choices=("granular-only", "kappa-infinity", "kappa-infinity-smoothed")),
    Key("numerics", "kappa_air", "float", _D["kappa_air"], "m2 s-1", "κ_∞ of the kappa-infinity formulations", 1.0, 1e16),
    Key("numerics", "cfl", "float", _D["cfl"], "1", "CFL number of the adaptive time step", 1e-3, 1.0),
    Key("numerics", "t_end", "float", _D["t_end"], "s", "end of the simulated time (the run stops earlier at rest)", 1e-6, 1e4),
    Key("numerics", "threads", "int", _D["threads"], "threads", "size of the Rust thread pool (results are identical for any value)", 1, 1024),
    Key("numerics", "picard_tol", "float", _D["picard_tol"], "1", "tolerance of the Picard iteration of the plastic projection", 1e-14, 1.0),
    Key("numerics", "theta", "float", _D["theta"], "1", "θ, pseudo-relaxation of the Picard iteration", 0.0, 1.0, hi_open=True),
    Key("numerics", "r_neighbourhood", "int", _D["r_neighbourhood"], "cells",
        "half-width of the neighbourhood of the plastic projection's local r: within it the relaxed fixed point of "
        "eq. (12) is as soft as the air's faces make it (0: the cell's own faces, δt-independent run-out)", 0, 4),
    Key("numerics", "sigma_location", "choice", _D["sigma_location"], "",
        "where the plastic tensor lives: staggered (Σ_xx at centres, Σ_xy at nodes) or the paper's Figure 3, both at centres",
        choices=SIGMA_LOCATIONS),
    Key("numerics", "interface_yield", "choice", _D["interface_yield"], "",
        "where the smoothed jump of the yield stress and basal friction sits: the paper's H_ε(Φ), H_ε(Φ + ε) or H_ε(Φ + 2ε)",
        choices=("paper", "granular-side", "density-support")),
    Key("numerics", "active_region", "int", 0, "cells",
        "run each step on a window around the granular phase with this many (≥ 2) cells of air; 0: the whole domain", 0, 100000),
    Key("numerics", "active_region_sides", "choice", _D["active_region_sides"], "",
        "the active window's sides: walls; its right side open (outflow at the air's hydrostatic pressure); or "
        "its right and top sides open with backflow stabilisation",
        choices=ACTIVE_REGION_SIDES),
    Key("numerics", "wall_normal_stress", "choice", _D["wall_normal_stress"], "",
        "normal stress of the Coulomb base and back wall: the pressure p, or the paper's total stress p − T_nn",
        choices=("pressure", "total")),
    Key("numerics", "yield_pressure", "choice", _D["yield_pressure"], "",
        "pressure of the yield stress and the walls' normal stress: the paper's p, or p minus the mean air pressure on the surface",
        choices=("absolute", "surface-air")),
    Key("numerics", "step_retries", "int", _D["step_retries"], "1",
        "rejections of a step whose Picard iteration does not converge (retaken with δt halved); 0: stop at once", 0, 20),
    Key("numerics", "mass_correction", "bool", _D["mass_correction"], "",
        "global mass correction of the level set (dense area kept at its initial value)"),
    Key("output", "dir", "str", "out/run", "path", "output folder, relative to the current directory"),
    Key("output", "fields_every_s", "float", 0.05, "s", "simulated time between field snapshots; 0: none", 0.0, 1e4),
    Key("output", "formats", "list", ["vtk"], "", "field formats: 'vtk' (.vti + .pvd), 'netcdf' (fields.nc)", choices=("vtk", "netcdf")),
    Key("output", "animation", "bool", True, "", "write animation.gif from the saved fields at the end"),
    Key("output", "checkpoint_every_s", "float", 0.0, "s", "simulated time between checkpoints; 0: none", 0.0, 1e4),
)
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
        if not math.isfinite(number) or too_low or too_high:
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
        if (not isinstance(value, list) or not all(isinstance(v, str) and v in key.choices for v in value)
                or len(set(value)) != len(value)):
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
            raise ParameterError(f"invalid parameter `{section}`: unknown section; allowed sections "
                                 + ", ".join(f"[{s}]" for s in SECTIONS))
        if not isinstance(table, dict):
            raise ParameterError(f"invalid parameter `{section}` = {table!r}: allowed a table [{section}]")
        for name in table:
            if f"{section}.{name}" not in _BY_NAME:
                names = ", ".join(k.name for k in KEYS if k.section == section)
                raise ParameterError(f"invalid parameter `{section}.{name}`: unknown key in [{section}]; allowed keys {names}")
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
        raise ParameterError(f"invalid parameter `grid.length` = {grid['length']!r}: allowed a length (m) greater than "
                             f"case.width = {case['width']!r} m (the gate)")
    if out["animation"] and not (out["fields_every_s"] > 0 and out["formats"]):
        if ("output", "animation") in given:
            raise ParameterError(f"invalid parameter `output.animation` = true: allowed only with output.fields_every_s "
                                 f"> 0 and a non-empty output.formats (the animation is made from the saved fields)")
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
        raise ParameterError(f"invalid parameter `{dotted}`: unknown key; allowed keys "
                             + ", ".join(k.full for k in KEYS))
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
        raise ParameterError(f"invalid run file `{path}`: not UTF-8 text (byte {err.object[err.start]:#04x} at offset "
                             f"{err.start}); allowed a TOML file in UTF-8") from None
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
    c, g, m, n = cfg["case"], cfg["grid"], cfg["materials"], cfg["numerics"]
    return ColumnCase(aspect_ratio=c["aspect_ratio"], width=c["width"], fluidised=c["fluidised"],
                      channel_width=c["channel_width"] or None,
                      pore_pressure_ratio=c["pore_pressure_ratio"], rheology=c["rheology"], ny=g["ny"],
                      length=g["length"], t_end=n["t_end"], cfl=n["cfl"], threads=n["threads"],
                      picard_tol=n["picard_tol"], theta=n["theta"], r_neighbourhood=n["r_neighbourhood"],
                      sigma_location=n["sigma_location"],
                      mass_correction=n["mass_correction"],
                      interface_yield=n["interface_yield"], wall_normal_stress=n["wall_normal_stress"],
                      yield_pressure=n["yield_pressure"], pore_formulation=n["pore_formulation"],
                      kappa_air=n["kappa_air"], active_region=n["active_region"] or None,
                      active_region_sides=n["active_region_sides"],
                      step_retries=n["step_retries"], **m)
