"""Provenance stamped on every output: granrs version, git revision, command line, configuration.

``provenance(config_text, command)`` returns a flat dict of strings, so that it fits NetCDF global
attributes, JSON, XML comments and npz metadata alike.
"""

from __future__ import annotations

import datetime as _dt
import functools
import json
import shlex
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Optional

from .._granrs import __version__

_SOURCE = Path(__file__).resolve().parents[3]  # the repository root of an editable install


@functools.lru_cache(maxsize=1)
def git_revision() -> Optional[str]:
    """The git commit of the source tree ("<sha>" or "<sha>-dirty"), or None when unknown (an
    installed wheel, no git): failures are ignored."""
    try:
        sha = subprocess.run(
            ["git", "-C", str(_SOURCE), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10
        )
        if sha.returncode != 0:
            return None
        dirty = subprocess.run(
            ["git", "-C", str(_SOURCE), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        return sha.stdout.strip() + ("-dirty" if dirty.returncode == 0 and dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None


def command_line(argv: Optional[Sequence[str]] = None) -> str:
    """The command line of this process, shell-quoted (the program as its base name)."""
    argv = list(sys.argv if argv is None else argv)
    if argv:
        argv[0] = Path(argv[0]).name or argv[0]
    return shlex.join(argv)


def provenance(config_text: str = "", command: Optional[str] = None) -> dict:
    """granrs_version, git_revision ('' when unknown), command_line, created_utc, configuration."""
    return {
        "granrs_version": __version__,
        "git_revision": git_revision() or "",
        "command_line": command if command is not None else command_line(),
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "configuration": config_text,
    }


def one_line(text: str) -> str:
    """``text`` with every control character written as its escape (a newline as ``\\n``), so
    that it stays on one line of a comment."""
    return "".join(
        ch.encode("unicode_escape").decode("ascii")
        if ord(ch) < 32 or 127 <= ord(ch) < 160 or ch in "\u2028\u2029"
        else ch
        for ch in text
    )


def header_lines(prov: dict) -> list[str]:
    """Provenance as comment lines (for the resolved TOML file), each on one line."""
    return [
        one_line(f"granrs {prov['granrs_version']}, git {prov['git_revision'] or 'unknown'}, {prov['created_utc']}"),
        one_line(f"command: {prov['command_line']}"),
    ]


def xml_comment(prov: dict) -> str:
    """Provenance as an XML comment holding JSON; '--' (not allowed in comments) is written as the
    JSON escape '-\\u002d', so the JSON decodes back to the same strings."""
    text = json.dumps(prov, ensure_ascii=False)
    while "--" in text:
        text = text.replace("--", "-\\u002d")
    return f"<!-- granrs-provenance {text} -->"


def from_xml(text: str) -> Optional[dict]:
    """The provenance dict of a file written with ``xml_comment``, or None."""
    start = text.find("<!-- granrs-provenance ")
    if start < 0:
        return None
    end = text.find(" -->", start)
    return json.loads(text[start + len("<!-- granrs-provenance ") : end])
