"""The hand-written stubs of granrs._granrs against the compiled extension: the names it exports,
and (mypy.stubtest) every function's and method's parameters, their kinds and their defaults."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import granrs._granrs as ext

STUB = Path(__file__).parents[1] / "python/granrs/_granrs.pyi"


def _stubtest(stub_dir: Path | None, cwd: Path) -> subprocess.CompletedProcess:
    """mypy.stubtest of granrs._granrs against the installed stubs, or against the package stubs
    in ``stub_dir`` (MYPYPATH is searched before the installed package)."""
    env = dict(os.environ)
    env.pop("MYPYPATH", None)
    if stub_dir is not None:
        env["MYPYPATH"] = str(stub_dir)
    return subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "--concise", "granrs._granrs"],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_stub_names_match_the_extension():
    tree = ast.parse(STUB.read_text())
    stub = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
    stub |= {t.id for n in tree.body if isinstance(n, ast.AnnAssign) for t in [n.target]}
    exported = {k for k in dir(ext) if not k.startswith("__") or k == "__version__"}
    exported.discard("__version__")
    stub.discard("__version__")
    assert stub == exported, stub ^ exported
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "RustModel")
    methods = {n.name for n in cls.body if isinstance(n, ast.FunctionDef)} - {"__new__"}
    assert methods == {k for k in dir(ext.RustModel) if not k.startswith("_")}


def test_stubtest_finds_the_stubs_consistent_with_the_extension(tmp_path):
    # every signature and default of the .pyi against the compiled module's __text_signature__
    r = _stubtest(None, tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr


def _defaulted(fn: ast.FunctionDef, literal_only: bool = True) -> list[tuple[ast.arg, ast.expr]]:
    """(parameter, default) pairs of ``fn`` whose default is a plain literal (not ``...``, not None;
    with ``literal_only=False``, None too)."""
    args = fn.args.posonlyargs + fn.args.args
    pairs = list(zip(args[len(args) - len(fn.args.defaults) :], fn.args.defaults))
    pairs += [(a, d) for a, d in zip(fn.args.kwonlyargs, fn.args.kw_defaults) if d is not None]
    skip = (None, Ellipsis) if literal_only else (Ellipsis,)
    return [(a, d) for a, d in pairs if isinstance(d, ast.Constant) and d.value not in skip]


def test_stubtest_fails_on_a_wrong_default_and_on_a_missing_parameter(tmp_path):
    """The check can fail: a copy of the stubs with one literal default changed (a number + 1, a
    flag flipped, a string altered) in one function and one parameter deleted from another makes
    stubtest report both."""
    tree = ast.parse(STUB.read_text())
    functions = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)]
    literal = [n for n in functions if _defaulted(n)]
    assert literal, "the stubs hold no function with a literal default"
    (arg, default) = _defaulted(literal[0])[0]
    removed_from = next(n for n in functions if n is not literal[0] and _defaulted(n, literal_only=False))
    v = default.value
    default.value = (not v) if isinstance(v, bool) else v + 1 if isinstance(v, (int, float)) else str(v) + "-x"
    victim = next(a for a, _ in reversed(_defaulted(removed_from, literal_only=False)) if a.arg != arg.arg)
    a = removed_from.args
    if victim in a.kwonlyargs:
        k = a.kwonlyargs.index(victim)
        del a.kwonlyargs[k], a.kw_defaults[k]
    else:
        params = a.posonlyargs + a.args
        k = params.index(victim)
        del a.defaults[k - (len(params) - len(a.defaults))]
        (a.posonlyargs if victim in a.posonlyargs else a.args).remove(victim)
    pkg = tmp_path / "stubs" / "granrs"
    pkg.mkdir(parents=True)
    (pkg / "__init__.pyi").write_text("")
    (pkg / "_granrs.pyi").write_text(ast.unparse(tree))
    r = _stubtest(tmp_path / "stubs", tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode != 0, out
    assert f'runtime parameter "{arg.arg}" has a default value of {v!r}' in out, out
    # a keyword-only parameter is reported missing; a positional one also shifts those after it
    assert any(
        "is inconsistent" in line and f'"{victim.arg}"' in line and f".{removed_from.name} " in line
        for line in out.splitlines()
    ), out
