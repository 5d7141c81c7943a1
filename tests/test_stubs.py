"""The hand-written stubs of granrs._granrs list exactly what the extension exports."""

import ast
from pathlib import Path

import granrs._granrs as ext


def test_stub_names_match_the_extension():
    tree = ast.parse((Path(__file__).parents[1] / "python/granrs/_granrs.pyi").read_text())
    stub = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
    stub |= {t.id for n in tree.body if isinstance(n, ast.AnnAssign) for t in [n.target]}
    exported = {k for k in dir(ext) if not k.startswith("__") or k == "__version__"}
    exported.discard("__version__")
    stub.discard("__version__")
    assert stub == exported, (stub ^ exported)
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "RustModel")
    methods = {n.name for n in cls.body if isinstance(n, ast.FunctionDef)} - {"__init__"}
    assert methods == {k for k in dir(ext.RustModel) if not k.startswith("_")}
