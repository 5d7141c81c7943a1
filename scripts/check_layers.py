#!/usr/bin/env python3
"""Checks the floors of the Rust core (rust/granrs-core/src; stated in its lib.rs).

Every `crate::ROOM` path in the code (comments and doc comments left out, `use crate::{a, b}`
groups included) is an import of ROOM by the room of the file it is in (the folder under src/, or
the file for the top-level modules). A room may import a room on a lower floor, or one on its own
floor as long as the rooms of that floor import each other without a cycle. Exits 1 naming each
import that runs up a floor or closes a cycle; prints the import graph otherwise.

Usage: python3 scripts/check_layers.py [SRC]   (SRC: another source tree, default the core's)
"""

import re
import sys
from pathlib import Path

# Bottom to top; lib.rs states the same list.
FLOORS = [
    ["error", "exec", "options"],
    ["grid"],
    ["operators", "solvers"],
    ["levelset", "plasticity", "pore_pressure", "projection", "walls", "rheology", "diagnostics"],
    ["time_stepping"],
    ["models"],
]
FLOOR = {room: k for k, rooms in enumerate(FLOORS) for room in rooms}

SRC = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "rust" / "granrs-core" / "src"


def strip_comments(text: str) -> str:
    """The code of a Rust file without // comments (doc comments included) and /* */ blocks."""
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    out = []
    for line in text.splitlines():
        # a // inside a string literal is rare in this crate's paths; cut at the first // that
        # is not inside double quotes
        in_str, cut = False, len(line)
        for k, ch in enumerate(line):
            if ch == '"' and (k == 0 or line[k - 1] != "\\"):
                in_str = not in_str
            elif not in_str and line.startswith("//", k):
                cut = k
                break
        out.append(line[:cut])
    return "\n".join(out)


def imports(code: str) -> set[str]:
    """The rooms a file's code names through `crate::`."""
    found = set(re.findall(r"\bcrate::([a-z_][a-z0-9_]*)", code))
    for group in re.findall(r"\bcrate::\{([^}]*)\}", code, flags=re.S):
        found.update(re.findall(r"(?:^|,)\s*([a-z_][a-z0-9_]*)", group))
    return found


def room_of(path: Path) -> str | None:
    rel = path.relative_to(SRC)
    if len(rel.parts) == 1:
        return None if rel.stem == "lib" else rel.stem
    return rel.parts[0]


def main() -> int:
    edges: dict[str, dict[str, list[str]]] = {}
    unknown = []
    for path in sorted(SRC.rglob("*.rs")):
        room = room_of(path)
        if room is None:
            continue
        if room not in FLOOR:
            unknown.append(f"{path.relative_to(SRC)}: room `{room}` is on no floor")
            continue
        for target in imports(strip_comments(path.read_text(encoding="utf-8"))):
            if target in ("self", "super") or target == room:
                continue
            if target not in FLOOR:
                # a crate-root item (Error, Result, VERSION, the re-exported grid types)
                continue
            edges.setdefault(room, {}).setdefault(target, []).append(str(path.relative_to(SRC)))
    problems = list(unknown)
    for room, targets in sorted(edges.items()):
        for target, files in sorted(targets.items()):
            if FLOOR[target] > FLOOR[room]:
                problems.append(f"{room} (floor {FLOOR[room]}) imports {target} (floor {FLOOR[target]}), a floor up: {', '.join(sorted(set(files)))}")
    # cycles among the rooms (depth-first search on the room graph)
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(room: str) -> None:
        state[room] = 1
        stack.append(room)
        for target in sorted(edges.get(room, {})):
            if state.get(target) == 1:
                cycle = stack[stack.index(target):] + [target]
                problems.append("import cycle: " + " -> ".join(cycle))
            elif target not in state:
                visit(target)
        stack.pop()
        state[room] = 2

    for room in sorted(FLOOR):
        if room not in state:
            visit(room)
    if problems:
        print("check_layers: the core's floors are broken:", file=sys.stderr)
        for p in problems:
            print("  " + p, file=sys.stderr)
        return 1
    for k in reversed(range(len(FLOORS))):
        for room in FLOORS[k]:
            print(f"floor {k} {room:14s} -> {', '.join(sorted(edges.get(room, {}))) or '-'}")
    print("check_layers: no import runs up a floor, no cycle")
    return 0


if __name__ == "__main__":
    sys.exit(main())
