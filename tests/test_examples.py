"""The user examples of examples/ that the documentation's gallery does not run: each runs as
written, at a coarse grid, from the repository root (where its run file is found)."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_examples_folder_holds_only_user_examples():
    """examples/ holds the run files, the calibration and the gallery; the scripts behind the
    docs' study figures live in studies/ (studies/README.md)."""
    names = {p.name for p in (ROOT / "examples").iterdir()}
    assert names == {"paper_fluidised.toml", "paper_dry.toml", "calibrate_runout.py", "gallery"}, names
    assert all(p.name.startswith("plot_") or p.suffix == ".rst" for p in (ROOT / "examples" / "gallery").iterdir())


def test_the_calibration_example_sweeps_and_reports_its_closest_member(tmp_path):
    """examples/calibrate_runout.py on two members at ny = 8 to 0.2 s (one Dask worker): both
    finish, sweep.csv holds them, and the script names the member closest to the experiment's
    1.8443 m (at 0.2 s the fronts are at 0.26 m, so the note that it did not stop at rest follows)."""
    out = tmp_path / "calibration"
    r = subprocess.run(
        [sys.executable, "examples/calibrate_runout.py", "--ny", "8", "--t-end", "0.2", "--kappa", "0.035"]
        + ["--eta", "0.1,0.3", "--workers", "1", "--out", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    rows = list(csv.DictReader((out / "sweep.csv").open()))
    assert [(row["rheology.viscosity"], row["status"]) for row in rows] == [("0.1", "ok"), ("0.3", "ok")]
    assert "closest to the experiment (1.8443 m) among 2 finished members" in r.stdout
    assert "not at rest" in r.stdout


def test_every_study_and_benchmark_script_is_in_its_readme_table():
    """studies/README.md and benchmarks/README.md name each of their scripts in a table row (the
    figure or table it makes, where the docs show it, how long it runs)."""
    for folder in ("studies", "benchmarks"):
        readme = (ROOT / folder / "README.md").read_text()
        rows = {line.split("|")[1].strip().strip("`") for line in readme.splitlines() if line.startswith("| `")}
        scripts = {p.name for p in (ROOT / folder).glob("*.py")}
        assert scripts <= rows, (folder, sorted(scripts - rows))
        assert rows <= scripts, (folder, sorted(rows - scripts))
