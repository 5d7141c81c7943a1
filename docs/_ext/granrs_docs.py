"""Pages generated from the code at build time: the command line (from granrs.cli's argparse
parser) and the run-file keys (from granrs.config.KEYS)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path


class _Captured(Exception):
    def __init__(self, parser):
        self.parser = parser


def cli_parser() -> argparse.ArgumentParser:
    """The parser that ``granrs.cli.main`` builds, captured when it parses (nothing is run)."""
    from granrs import cli

    original = argparse.ArgumentParser.parse_args

    def capture(self, *args, **kwargs):
        raise _Captured(self)

    argparse.ArgumentParser.parse_args = capture
    try:
        cli.main(["info"])
    except _Captured as cap:
        return cap.parser
    finally:
        argparse.ArgumentParser.parse_args = original
    raise RuntimeError("granrs.cli.main did not parse its arguments")


def cli_markdown() -> str:
    parser = cli_parser()
    parser.formatter_class = lambda prog: argparse.HelpFormatter(prog, width=84)
    out = ["# Command line", "",
           "Generated from the argument parser of `granrs.cli` when the documentation is built.", "",
           "```text", parser.format_help().rstrip(), "```", ""]
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    for action in subs:
        for name, sub in action.choices.items():
            sub.formatter_class = lambda prog: argparse.HelpFormatter(prog, width=84)
            out += [f"## `granrs {name}`", "", "```text", sub.format_help().rstrip(), "```", ""]
    return "\n".join(out)


def keys_markdown() -> str:
    from granrs import config

    out = ["# Run-file keys", "",
           "Generated from `granrs.config.KEYS` when the documentation is built; `granrs keys` prints the",
           "same table. A run file is TOML with the sections "
           + ", ".join(f"`[{s}]`" for s in config.SECTIONS)
           + ". Every key is checked before any work: a bad key or value raises `granrs.ParameterError`",
           "naming the full key, its allowed range and its unit. A key whose default is `absent` is off",
           "(None) while it is absent: TOML has no null.", ""]
    for section in config.SECTIONS:
        out += [f"## `[{section}]`", "", "| key | allowed | default | meaning |", "|---|---|---|---|"]
        for k in config.KEYS:
            if k.section != section:
                continue
            default = ("absent" if k.optional else "derived") if k.default is None else config.toml_value(k.default)
            doc = k.doc.replace("|", "\\|")
            allowed = k.allowed().replace("|", "\\|")
            out.append(f"| `{k.full}` | {allowed} | `{default}` | {doc} |")
        out.append("")
    return "\n".join(out)


def options_markdown() -> str:
    """The reference of every option of the Rust schema, room by room, each variant in its room;
    each room with the object and the run-file section that hold it, each option with its field
    in that object where the name differs from the key."""
    from granrs import config, options

    out = ["# Options", "",
           "Generated from the Rust schema (`granrs._granrs.schema()`, the `OPTIONS` tables beside the",
           "configuration structs of `rust/granrs-core`) when the documentation is built. Each option is",
           "declared once there, with its default, range, unit and doc; `granrs.Numerics`, the room objects",
           "(`TimeStepping`, `BiProjection`, `Interface`, `ActiveRegion`, `PorePressure`, the rheologies,",
           "`CoulombWall`, `SideWalls`), the run-file keys and `granrs keys` are made from it.",
           "The group `variant` marks the numerical variants kept for study, each in the room of the object",
           "that owns it ([Variants](../models.md#variants)). The key is the option's name in",
           "`granrs.Numerics`, `ColumnCase.with_options` and the studies' `--option KEY=VALUE`; where the",
           "object's field is named otherwise, the field follows it (`picard_tol`, `BiProjection.tolerance`).",
           ""]
    import granrs

    objects = {"bingham": "Bingham", "drucker-prager": "DruckerPrager", "mu-i": "MuI",
               "pore_pressure": "PorePressure", "coulomb": "CoulombWall", "side_walls": "SideWalls"}
    holders = {room: f"`granrs.{name}`" for room, name in objects.items() if hasattr(granrs, name)}
    holders |= {room: f"`granrs.{cls.__name__}`" for room, cls in options.ROOM_OBJECTS.items()}
    fields = {(s.room, s.key): f"{cls.__name__}.{name}"
              for cls in options.ROOM_OBJECTS.values() for name, s in cls.FIELDS.items() if name != s.key}
    sections: dict = {}
    for k in config.KEYS:
        if k.option is not None:
            sections.setdefault(k.option.room, {})[k.section] = None
    rooms = list(dict.fromkeys(s.room for s in options.SCHEMA))
    for room in rooms:
        held = [holders.get(room) or ("`granrs.Numerics`" if not options.room(room)[0].object else "")]
        held += [f"run files' `[{s}]`" for s in sections.get(room, {})]
        held = [h for h in held if h]
        out += [f"## `{room}`", ""] + ([f"Held by {', '.join(held)}.", ""] if held else [])
        out += ["| key | allowed | default | group | meaning |", "|---|---|---|---|---|"]
        for s in options.room(room):
            default = "required" if s.required else repr(s.default)
            key = f"`{s.key}`" + (f" (`{fields[s.room, s.key]}`)" if (s.room, s.key) in fields else "")
            out.append(f"| {key} | {s.allowed.replace('|', chr(92) + '|')} | `{default}` | {s.group} | "
                       f"{s.doc.replace('|', chr(92) + '|')} |")
        out.append("")
    return "\n".join(out)


def _write_if_changed(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def generate(app) -> None:
    ref = Path(app.srcdir) / "reference"
    _write_if_changed(ref / "cli.md", cli_markdown())
    _write_if_changed(ref / "keys.md", keys_markdown())
    _write_if_changed(ref / "options.md", options_markdown())


_SECTION = re.compile(r"^(Parameters|Returns|Raises|Examples|Notes|Attributes|Yields|See Also)\s*$")


def plain_docstring(app, what, name, obj, options, lines) -> None:
    """Makes granrs's plain-text docstrings valid reStructuredText before numpydoc reads them.

    granrs writes |x| for magnitudes and continues an item (``name: text``) on indented lines;
    in reST the first is a substitution and the second an unexpected indentation. Numpydoc
    docstrings (with section headers) keep their layout; only the bars are escaped there."""
    if not name.startswith("granrs"):
        return
    text = "\n".join(lines)
    structured = any(_SECTION.match(l.strip()) for l in lines)
    text = re.sub(r"(?<!\\)\|", r"\\|", text)
    text = re.sub(r"``[^`\n]+``(?=(\w?))", lambda m: m.group(0) + ("\\ " if m.group(1) else ""), text)
    out = text.split("\n")
    if not structured:
        merged: list[str] = []
        literal = False
        for line in out:
            stripped = line.strip()
            indent = len(line) - len(line.lstrip())
            if merged and merged[-1].rstrip().endswith("::"):
                literal = True
            if literal and stripped and indent == 0:
                literal = False
            if (not literal and stripped and merged and merged[-1].strip()
                    and indent > len(merged[-1]) - len(merged[-1].lstrip())):
                merged[-1] = merged[-1].rstrip() + " " + stripped
            else:
                merged.append(line)
        out = merged
    lines[:] = out


def summary_within_parentheses(doc: list, settings, extract) -> str:
    """autosummary's first sentence of a docstring, where a period inside parentheses ends no
    sentence: granrs's "(paper eq. 8–9)" and "(J. Fluid Mech.)" cut the API tables' summaries
    at "eq." otherwise. The periods inside are marked with a word joiner, which is then removed;
    ``extract`` is autosummary's own ``extract_summary``."""
    depth, marked = 0, []
    for line in doc:
        chars = []
        for c in line:
            depth = max(0, depth + (c == "(") - (c == ")"))
            chars.append(c + ("\u2060" if c == "." and depth else ""))
        marked.append("".join(chars))
    return extract(marked, settings).replace("\u2060", "")


def setup(app):
    from sphinx.ext import autosummary  # here: the tests import this module without the docs' requirements

    extract = autosummary.extract_summary
    autosummary.extract_summary = lambda doc, settings: summary_within_parentheses(doc, settings, extract)
    app.connect("builder-inited", generate)
    app.connect("autodoc-process-docstring", plain_docstring, priority=400)
    return {"version": "1", "parallel_read_safe": True}
