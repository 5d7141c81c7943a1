#!/usr/bin/env python3
"""Checks the floors of the Python package (python/granrs; stated in docs/architecture.md).

Every import statement of the package's code (parsed with ``ast``; a relative import resolved
against its module) that names a module of the package is an import of that module, or of a
package's ``__init__`` when it names a package or a name a package's ``__init__`` defines. A
module may import a module on a lower floor, or one on its own floor as long as the modules of
that floor import each other without a cycle (an import of ``a.b.c`` runs ``a.b``'s ``__init__``
too, which counts). No module imports the ``__init__`` of a package it
is part of (``granrs`` itself, its own subpackage): that ``__init__`` is the package's front,
which imports the modules, never the other way round. An import inside a function or a class
(a deferred import) of a module of the package is refused, and so is a private name (``_x``)
imported from a module of another package; one of a third-party module needs a
``# deferred: REASON`` comment on its line or on the comment lines directly above it (an optional
dependency, or pyplot loaded once the backend is chosen). Exits 1 naming each import that runs up
a floor, closes a cycle, imports a package's front from inside or is deferred without a reason;
prints the floors otherwise.

Usage: python3 scripts/check_python_layers.py [PACKAGE]   (PACKAGE: another copy of the package's
folder, default python/granrs)
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

from check_layers import cycles  # the same depth-first search as the Rust check (scripts/ is on the path)

# Bottom to top; docs/architecture.md states the same list. A module's floor is that of the
# longest dotted prefix listed here (``io`` holds ``io.writer``, ``cases`` holds ``cases.column.run``).
FLOORS = [
    ("errors and options", ["_granrs", "options"]),
    ("physics objects", ["grid", "materials", "shapes", "boundary", "rheology"]),
    ("model and simulation", ["model", "depth_averaged", "simulation", "observables"]),
    ("io", ["io"]),
    ("cases", ["cases", "validation"]),
    ("config, run, sweep", ["config", "runner", "sweep"]),
    ("cli", ["cli"]),
]
FLOOR = {name: k for k, (_, names) in enumerate(FLOORS) for name in names}
#: the package's top-level ``__init__``: imports any floor, imported by none of its modules
FRONT = ""
MARK = "# deferred:"

ROOT = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "python" / "granrs"
PACKAGE = "granrs"


def modules(root: Path) -> dict[str, Path]:
    """Dotted name (relative to the package, ``""`` for its ``__init__``) → file, for every module."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    for path in sorted(root.rglob("*.pyi")):  # a compiled module: its stub stands for it
        name = ".".join(path.relative_to(root).with_suffix("").parts)
        out.setdefault(name, path)
    return out


def floor_of(name: str) -> int | None:
    """The floor of a module (``None`` for a module on no floor)."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        prefix = ".".join(parts[:k])
        if prefix in FLOOR:
            return FLOOR[prefix]
    return None


def is_package(name: str, files: dict[str, Path]) -> bool:
    return files[name].name == "__init__.py"


def same_package(name: str, target: str, files: dict[str, Path]) -> bool:
    """Whether module ``target`` lies in the package of module ``name`` (or below it)."""
    package = name if is_package(name, files) else name.rpartition(".")[0]
    return not package or target == package or target.startswith(package + ".")


def targets(node: ast.Import | ast.ImportFrom, name: str, files: dict[str, Path]) -> list[str]:
    """The package's modules an import statement of module ``name`` imports (``""``: the front)."""
    package = name if is_package(name, files) else name.rpartition(".")[0]
    found: list[str] = []
    if isinstance(node, ast.Import):
        for alias in node.names:
            if alias.name == PACKAGE or alias.name.startswith(PACKAGE + "."):
                found.append(alias.name[len(PACKAGE) + 1 :])
        return found
    if node.level:
        base = package.split(".") if package else []
        up = node.level - 1
        if up > len(base):
            return []
        base = base[: len(base) - up]
        module = ".".join(base + ([node.module] if node.module else []))
    elif node.module == PACKAGE or (node.module or "").startswith(PACKAGE + "."):
        module = (node.module or "")[len(PACKAGE) + 1 :]
    else:
        return []
    for alias in node.names:
        sub = f"{module}.{alias.name}" if module else alias.name
        # ``from PACKAGE import submodule`` imports the submodule; any other name is the front's
        found.append(sub if sub in files else module)
    return found


def deferred_reason(lines: list[str], node: ast.stmt) -> bool:
    """Whether a deferred import carries ``# deferred: REASON`` on its line or just above it."""
    end = getattr(node, "end_lineno", None) or node.lineno
    for k in range(node.lineno - 1, end):
        if MARK in lines[k] and lines[k].split(MARK, 1)[1].strip():
            return True
    k = node.lineno - 2
    while k >= 0 and lines[k].strip().startswith("#"):
        if MARK in lines[k] and lines[k].split(MARK, 1)[1].strip():
            return True
        k -= 1
    return False


def scan(name: str, path: Path, files: dict[str, Path]) -> tuple[dict[str, list[int]], list[str]]:
    """The imports of one module (target → line numbers) and the problems of its deferred imports."""
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text, filename=str(path))
    lines = text.splitlines()
    edges: dict[str, list[int]] = {}
    problems: list[str] = []

    def visit(node: ast.AST, nested: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                own = sorted(set(targets(child, name, files)))
                for target in own:
                    edges.setdefault(target, []).append(child.lineno)
                if isinstance(child, ast.ImportFrom) and len(own) == 1 and not same_package(name, own[0], files):
                    private = [a.name for a in child.names if a.name.startswith("_") and not a.name.startswith("__")]
                    private = [n for n in private if own[0].rpartition(".")[2] != n]  # not a submodule
                    if private:
                        problems.append(
                            f"{path.relative_to(ROOT.parent)}:{child.lineno}: {label(name)} imports the private "
                            f"{', '.join(private)} of {label(own[0])}, another package's module"
                        )
                if nested:
                    where = f"{path.relative_to(ROOT.parent)}:{child.lineno}"
                    if own:
                        problems.append(f"{where}: deferred import of the package's own {', '.join(map(label, own))}")
                    elif not deferred_reason(lines, child):
                        problems.append(f"{where}: deferred import without a `{MARK} REASON` comment")
            inner = nested or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Lambda))
            visit(child, inner)

    visit(tree, False)
    return edges, problems


def label(name: str) -> str:
    return PACKAGE + (f".{name}" if name else "")


def check(root: Path) -> tuple[list[str], dict[str, set[str]]]:
    """The problems of the package in ``root`` and its import graph (module → modules)."""
    files = modules(root)
    problems: list[str] = []
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        if path.suffix == ".pyi":
            continue
        if name != FRONT and floor_of(name) is None:
            problems.append(f"{label(name)} ({path.relative_to(root.parent)}) is on no floor")
            continue
        edges, deferred = scan(name, path, files)
        problems += deferred
        graph[name] = set()
        for target, lines in sorted(edges.items()):
            if target == name:
                continue
            at = f"{path.relative_to(root.parent)}:{','.join(map(str, lines))}"
            if target not in files:
                problems.append(f"{at}: {label(name)} imports {label(target)}, which does not exist")
                continue
            if is_package(target, files) and (name + ".").startswith(target + "." if target else ""):
                problems.append(
                    f"{at}: {label(name)} imports the __init__ of its own package {label(target)} "
                    "(import the module that defines the name)"
                )
                continue
            graph[name].add(target)
            if name == FRONT:
                continue
            if target == FRONT:
                continue  # reported above: every module is inside the front's package
            f_from, f_to = floor_of(name), floor_of(target)
            if f_to is None:
                problems.append(f"{at}: {label(target)} is on no floor")
            elif f_from is not None and f_to > f_from:
                problems.append(
                    f"{at}: {label(name)} (floor {f_from}, {FLOORS[f_from][0]}) imports {label(target)} "
                    f"(floor {f_to}, {FLOORS[f_to][0]}), a floor up"
                )
    # importing a.b.c runs the __init__ of a.b first: a cycle may close through it
    run = {name: set(targets) for name, targets in graph.items()}
    for name, targets in graph.items():
        for target in targets:
            parts = target.split(".")
            for k in range(1, len(parts)):
                package = ".".join(parts[:k])
                if package in files and not (name + ".").startswith(package + "."):
                    run[name].add(package)
    for cycle in cycles(run):
        problems.append("import cycle: " + " -> ".join(label(c) for c in cycle))
    return problems, graph


def main() -> int:
    problems, graph = check(ROOT)
    if problems:
        print("check_python_layers: the package's floors are broken:", file=sys.stderr)
        for p in problems:
            print("  " + p, file=sys.stderr)
        return 1
    for k in reversed(range(len(FLOORS))):
        title, names = FLOORS[k]
        print(f"floor {k} ({title}): {', '.join(names)}")
    print(
        f"check_python_layers: {len(graph)} modules; no import runs up a floor or closes a cycle, none imports "
        "its package's __init__, every deferred import states its reason"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
