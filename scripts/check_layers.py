#!/usr/bin/env python3
"""Checks the floors of the Rust core (rust/granrs-core/src; stated in its lib.rs).

Every `crate::ROOM` path in the code (comments and doc comments left out, `use crate::{a, b}`
groups included) is an import of ROOM by the room of the file it is in (the folder under src/, or
the file for the top-level modules). A room may import a room on a lower floor, or one on its own
floor as long as the rooms of that floor import each other without a cycle. Inside a room, the
files import each other without a cycle either: a file's `super::NAME` and `crate::ROOM::NAME`
paths name the room's file NAME.rs, or the file that defines the item NAME the room's mod.rs
re-exports (`pub use file::NAME`), or mod.rs itself for the items it defines. mod.rs is the room's
front (its declarations, configuration and re-exports, which name its files' items for the room's
users): it is a target of its files' imports, never a source, so no cycle passes through it. Exits 1 naming each import that runs up a floor or
closes a cycle; prints the import graph otherwise.

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
    ["levelset", "properties", "plasticity", "pore_pressure", "projection", "walls", "rheology", "diagnostics"],
    ["time_stepping"],
    ["models"],
]
FLOOR = {room: k for k, rooms in enumerate(FLOORS) for room in rooms}

SRC = (
    Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "rust" / "granrs-core" / "src"
)


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


def file_edges(room_dir: Path) -> dict[str, set[str]]:
    """The file-level import graph inside one room's folder: file stem -> stems it imports."""
    files = {p.stem: p for p in sorted(room_dir.glob("*.rs"))}
    room = room_dir.name
    mod_code = strip_comments(files["mod"].read_text(encoding="utf-8")) if "mod" in files else ""
    # items the room's mod.rs re-exports from its files: `pub use file::{A, B}` / `pub use file::A`
    item_file: dict[str, str] = {}
    for name, group in re.findall(
        r"\bpub(?:\([a-z]+\))?\s+use\s+(?:self::)?([a-z_][a-z0-9_]*)::(\{[^}]*\}|[A-Za-z_][A-Za-z0-9_]*)", mod_code
    ):
        if name in files:
            for item in re.findall(r"[A-Za-z_][A-Za-z0-9_]*", group):
                if item != "self":
                    item_file[item] = name

    def target(name: str) -> str:
        if name in files and name != "mod":
            return name
        return item_file.get(name, "mod")

    edges: dict[str, set[str]] = {}
    for stem, path in files.items():
        code = strip_comments(path.read_text(encoding="utf-8"))
        found: set[str] = set()
        if stem != "mod":
            prefixes = [r"\bsuper::", rf"\bcrate::{room}::"]
            for pre in prefixes:
                for name in re.findall(pre + r"([A-Za-z_][A-Za-z0-9_]*)", code):
                    found.add(target(name))
                for group in re.findall(pre + r"\{([^}]*)\}", code, flags=re.S):
                    for name in re.findall(r"(?:^|,)\s*([A-Za-z_][A-Za-z0-9_]*)", group):
                        found.add(target(name))
        found.discard(stem)
        edges[stem] = found
    return edges


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The cycles a depth-first search meets in a graph (one per back edge)."""
    state: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for t in sorted(edges.get(node, ())):
            if state.get(t) == 1:
                out.append(stack[stack.index(t) :] + [t])
            elif t not in state:
                visit(t)
        stack.pop()
        state[node] = 2

    for node in sorted(edges):
        if node not in state:
            visit(node)
    return out


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
                problems.append(
                    f"{room} (floor {FLOOR[room]}) imports {target} (floor {FLOOR[target]}), a floor up: {', '.join(sorted(set(files)))}"
                )
    # cycles among the rooms (depth-first search on the room graph)
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(room: str) -> None:
        state[room] = 1
        stack.append(room)
        for target in sorted(edges.get(room, {})):
            if state.get(target) == 1:
                cycle = stack[stack.index(target) :] + [target]
                problems.append("import cycle: " + " -> ".join(cycle))
            elif target not in state:
                visit(target)
        stack.pop()
        state[room] = 2

    for room in sorted(FLOOR):
        if room not in state:
            visit(room)
    # cycles among the files of each room
    inner: dict[str, dict[str, set[str]]] = {}
    for room_dir in sorted(p for p in SRC.iterdir() if p.is_dir() and (p / "mod.rs").exists()):
        inner[room_dir.name] = file_edges(room_dir)
        for cycle in cycles(inner[room_dir.name]):
            problems.append(f"file import cycle in {room_dir.name}/: " + " -> ".join(f"{c}.rs" for c in cycle))
    if problems:
        print("check_layers: the core's floors are broken:", file=sys.stderr)
        for p in problems:
            print("  " + p, file=sys.stderr)
        return 1
    for k in reversed(range(len(FLOORS))):
        for room in FLOORS[k]:
            print(f"floor {k} {room:14s} -> {', '.join(sorted(edges.get(room, {}))) or '-'}")
    for room, edges in inner.items():
        for stem in sorted(edges):
            if edges[stem]:
                print(f"  {room}/{stem}.rs -> {', '.join(f'{t}.rs' for t in sorted(edges[stem]))}")
    print("check_layers: no import runs up a floor, no cycle between rooms or between the files of a room")
    return 0


if __name__ == "__main__":
    sys.exit(main())
