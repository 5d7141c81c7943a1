"""The options of a model, read from the schema the Rust core declares (``granrs._granrs.schema()``).

Each option is declared once, in Rust, beside the field of the configuration struct that uses it,
with its default, range, unit, one line of doc, its room (the object that holds it) and its group
(``common``, or ``variant`` for a numerical variant kept for study; docs/models.md, "Variants").
This module turns that schema into the Python objects of the options: each room is a frozen
dataclass whose fields, defaults and docs are the schema's, and whose values are checked in Rust
(``granrs._granrs.check_option``) when it is made. A variant is a field of its room's object,
an enumerated choice or a number with its range, as any other option of that room.

=================  ============================================================================
object             the options it holds (its room in the schema)
=================  ============================================================================
``TimeStepping``   the simulation's clock: ``cfl``, ``dt``, ``max_dt``, ``max_growth``, ... ("time")
``BiProjection``   the yield stress's numerics: ``solver``, ``theta``, ``tolerance``, where Σ lives,
                   the local r, the proximal restarts, the walls' normal stress ("bi_projection")
``Interface``      the interface Φ = 0: its ``transport``, ``width``, redistancing, mass correction,
                   the velocity that moves it ("interface")
``ActiveRegion``   a window around the granular phase: ``band``, ``align``, ``sides``
``Numerics``       the flat form: every option of the model by its key (a model's ``options``)
=================  ============================================================================

A new option declared in Rust appears in ``Numerics``, in its room's object, in the run files'
section of that object ([time], [bi_projection], [interface], [active_region]) or else
[numerics], in ``granrs keys`` and in the docs' key reference, with nothing written for it here
(tests/test_options.py shows it). An option set both in ``Numerics`` and in the object that
holds it is refused (:func:`merge`).
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Optional

if sys.version_info >= (3, 11):
    import tomllib
else:  # the same parser, before it joined the standard library
    import tomli as tomllib

from . import _granrs
from ._granrs import ParameterError


@dataclass(frozen=True)
class OptionInfo:
    """One option of the schema (see ``granrs._granrs.schema``)."""

    key: str
    room: str
    kind: str
    default: Any
    optional: bool
    required: bool
    unit: str
    doc: str
    group: str
    allowed: str
    lo: Optional[float]
    hi: Optional[float]
    lo_open: bool
    hi_open: bool
    choices: tuple
    object: bool

    def check(self, value, name: Optional[str] = None):
        """``value`` converted to the option's kind, checked in Rust; ParameterError naming
        ``name`` (default: the key) and the allowed values otherwise."""
        return _granrs.check_option(self.key, value, room=self.room, name=name or self.key)


#: Every option, in the order of the Rust tables (the model's flat options, then the objects').
SCHEMA: tuple[OptionInfo, ...] = tuple(OptionInfo(**d) for d in _granrs.schema())
#: The model's flat options by key.
FLAT: dict[str, OptionInfo] = {s.key: s for s in SCHEMA if not s.object}


def spec(key: str, room: Optional[str] = None) -> OptionInfo:
    """The option ``key`` (of ``room``, for an object's option); ParameterError if unknown."""
    for s in SCHEMA:
        if s.key == key and (room is None and not s.object or s.room == room):
            return s
    raise ParameterError(f"invalid parameter `{key}`: not an option; allowed one of " + ", ".join(FLAT))


def room(name: str) -> tuple[OptionInfo, ...]:
    """The options of a room, in the order of its Rust table."""
    return tuple(s for s in SCHEMA if s.room == name)


def _doc(title: str, fields: list[tuple[str, OptionInfo]]) -> str:
    """The docstring of a room's object: its title, then one item per field (its doc, allowed
    values and default), a list in ``help()`` and in the API reference."""
    lines = [title, ""]
    for name, s in fields:
        default = "required" if s.required else repr(s.default)
        lines.append(f"- ``{name}``: {s.doc}; {s.allowed}; default {default}.")
    return "\n".join(lines)


def _options_class(
    cls_name: str,
    title: str,
    fields: list[tuple[str, OptionInfo]],
    module: str = __name__,
    room_name: Optional[str] = None,
    prefix: str = "",
):
    """A frozen dataclass whose fields are ``fields`` (name, option), with the schema's defaults,
    each value checked in Rust on construction (ParameterError names ``prefix`` + the field), and
    with ``room_name`` the values checked together by the rules of that room's Rust struct
    (``granrs._granrs.check_room``)."""
    specs = dict(fields)
    ordered = sorted(fields, key=lambda f: f[1].required, reverse=True)  # required ones first

    def __post_init__(self):
        for name, s in specs.items():
            value = getattr(self, name)
            object.__setattr__(self, name, s.check(value, prefix + name))
        if room_name is not None:
            _granrs.check_room(room_name, {specs[n].key: getattr(self, n) for n in specs})

    def options(self) -> dict:
        """The values by their schema keys."""
        return {specs[n].key: getattr(self, n) for n in specs}

    ns = {
        "__post_init__": __post_init__,
        "options": options,
        "__doc__": _doc(title, fields),
        "__module__": module,
        "FIELDS": specs,
    }
    cls = dataclasses.make_dataclass(
        cls_name,
        [(n, Any) if s.required else (n, Any, dataclasses.field(default=s.default)) for n, s in ordered],
        namespace=ns,
        frozen=True,
    )
    return cls


def _strip(prefix: str, key: str) -> str:
    return key[len(prefix) :] if key.startswith(prefix) and key != prefix.rstrip("_") else key


#: The simulation's clock (room "time"): CFL number, a fixed δt, caps and step retries.
TimeStepping: Any = _options_class(
    "TimeStepping",
    "The simulation's clock: how δt is chosen (Rust TimeConfig).",
    [(s.key, s) for s in room("time")],
    "granrs",
    room_name="time",
)

#: The numerics of the bi-projection (paper eq. 12) and of how the yield stress is imposed.
_BP_NAMES = {
    "picard_tol": "tolerance",
    "picard_max_iterations": "max_iterations",
    "picard_solve_max_iterations": "solve_max_iterations",
}
BiProjection: Any = _options_class(
    "BiProjection",
    "The bi-projection Σ = P(Σ + r D(u)) and its Picard iteration (paper eq. 11–12; Rust RheologyConfig).",
    [(_BP_NAMES.get(s.key, s.key), s) for s in room("bi_projection")],
    "granrs",
)

#: The active window around the granular phase (docs/models.md, "Active region").
ActiveRegion: Any = _options_class(
    "ActiveRegion",
    "Each step on a window around the granular phase (Rust ActiveRegion; docs/models.md).",
    [("band" if s.key == "active_region" else _strip("active_region_", s.key), s) for s in room("active_region")],
    "granrs",
)

#: The interface Φ = 0 (docs/models.md, "Interface"): how it moves, its smoothed width, the
#: redistancing of Φ and the mass correction.
_INTERFACE_NAMES = {"interface_width": "width", "interface_transport": "transport", "interface_velocity": "velocity"}
Interface: Any = _options_class(
    "Interface",
    "The interface Φ = 0: its transport, width, redistancing and mass correction (Rust ModelConfig, RedistanceSettings).",
    [(_INTERFACE_NAMES.get(s.key, s.key), s) for s in room("interface")],
    "granrs",
    prefix="interface.",
)

#: The rooms whose options an object of their own holds (``ROOM_OBJECTS[room]``): their run-file
#: section is the room's name; the other flat options are the run files' [numerics].
ROOM_OBJECTS: dict = {
    "time": TimeStepping,
    "bi_projection": BiProjection,
    "interface": Interface,
    "active_region": ActiveRegion,
}


def merge(numerics, objects: dict) -> dict:
    """The flat options by key: those of ``numerics`` (a ``Numerics``), then those of each object
    of ``objects`` (name → a room's object: ``TimeStepping``, ``BiProjection``, ...), which hold
    their own options. An option that ``numerics`` sets away from its default and an object sets
    to another value is a ParameterError naming both: each option is set in one place."""
    opts = numerics.options()
    for name, obj in objects.items():
        for field, s in obj.FIELDS.items():
            v, flat = getattr(obj, field), opts[s.key]
            if flat != s.default and v != flat:
                raise ParameterError(
                    f"invalid parameter `numerics.{s.key}` = {flat!r}: also set by `{name}.{field}` = {v!r}; "
                    f"allowed in one place, `{name}.{field}`"
                )
            opts[s.key] = v
    return opts


#: Keys of the flat options that are arguments of ``Model`` itself rather than numerics.
MODEL_ARGUMENTS = ("threads", "air")

#: The flat form of every option of a model by its key (``Model(numerics=...)``).
Numerics: Any = _options_class(
    "Numerics",
    "Every numerical option of a model by its schema key (the rooms' objects hold the same options).",
    [(s.key, s) for s in SCHEMA if not s.object and s.key not in MODEL_ARGUMENTS],
    "granrs",
)


def parse_scalar(text: str):
    """A value given on the command line, parsed as a TOML value (``0.3``, ``true``, ``"a"``,
    ``["vtk"]``); text that is not valid TOML is taken as a bare string (``mu-i``)."""
    try:
        parsed = tomllib.loads(f"v = {text}")
    except tomllib.TOMLDecodeError:
        return text
    return parsed["v"] if list(parsed) == ["v"] else text  # one value, never a table more


def parse_options(items: Iterable[str], flag: str = "--option") -> dict:
    """``KEY=VALUE`` items of a command line (``flag`` names them in an error) as a dict of model
    options by their schema keys (``ColumnCase.with_options``), each value parsed by
    ``parse_scalar``. An item without ``=`` raises ``ParameterError`` before any work."""
    options = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ParameterError(f"invalid parameter `{flag}` = {item!r}: allowed KEY=VALUE, e.g. proximal_restarts=20")
        options[key.strip()] = parse_scalar(value.strip())
    return options
