"""The Python package's floors (docs/architecture.md): scripts/check_python_layers.py passes on the
package and fails on each kind of broken import, written into a copy of it."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "check_python_layers.py"
PACKAGE = ROOT / "python" / "granrs"


def check(package: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), str(package)], capture_output=True, text=True, check=False)


@pytest.fixture
def copy(tmp_path):
    """A copy of the package's sources (no compiled module: the checker reads its stub)."""
    dest = tmp_path / "granrs"
    shutil.copytree(PACKAGE, dest, ignore=shutil.ignore_patterns("*.so", "*.pyd", "__pycache__", "data"))
    return dest


def test_the_package_passes():
    run = check(PACKAGE)
    assert run.returncode == 0, run.stderr
    assert "no import runs up a floor" in run.stdout


def test_the_copy_passes_before_it_is_broken(copy):
    run = check(copy)
    assert run.returncode == 0, run.stderr


def append(path: Path, text: str) -> None:
    path.write_text(path.read_text(encoding="utf-8") + text, encoding="utf-8")


@pytest.mark.parametrize(
    ("module", "code", "message"),
    [
        # physics objects (floor 1) importing the model (floor 2)
        ("grid.py", "\nfrom .model import Model\n", "granrs.grid (floor 1, physics objects) imports granrs.model"),
        # io (floor 3) importing the run files (floor 5): the io <-> config loop
        ("io/checkpoint.py", "\nfrom ..config import resolve\n", "imports granrs.config (floor 5"),
        # a module taking a name from the package's __init__ (a loop that works by line order)
        ("io/provenance.py", "\nfrom .. import __version__\n", "imports the __init__ of its own package granrs"),
        # a subpackage's module importing its own subpackage's __init__
        ("cases/column/measures.py", "\nfrom . import ColumnCase\n", "its own package granrs.cases.column"),
        # a private name of another package's module
        ("cases/cavity.py", "\nfrom ..validation.navier_stokes import _as_list\n", "imports the private _as_list"),
        # a deferred import of the package's own module
        ("model.py", "\n\ndef later():\n    from .shapes import Shape\n\n    return Shape\n", "deferred import of"),
        # a deferred import of a third-party module without its reason
        ("io/netcdf.py", "\n\ndef later():\n    import xarray\n\n    return xarray\n", "without a `# deferred:"),
        # two modules of one floor importing each other
        ("materials.py", "\nfrom .grid import Grid\n", "import cycle"),
        # a cycle through a package's __init__, which runs before the module imported from it:
        # cases -> cases.cavity -> validation.navier_stokes (validation's __init__ -> peer) -> cases.column
        ("cases/__init__.py", "\nfrom .cavity import run_cavity_case\n", "import cycle: granrs.cases -> "),
    ],
)
def test_a_broken_import_fails_naming_it(copy, module, code, message):
    if message == "import cycle":  # the other half of the cycle
        append(copy / "grid.py", "\nfrom .materials import Material\n")
    append(copy / module, code)
    run = check(copy)
    assert run.returncode == 1
    assert message in run.stderr, run.stderr


def test_a_deferred_import_with_its_reason_passes(copy):
    append(
        copy / "io/netcdf.py",
        "\n\ndef later():\n    import xarray  # deferred: optional dependency\n\n    return xarray\n",
    )
    run = check(copy)
    assert run.returncode == 0, run.stderr
