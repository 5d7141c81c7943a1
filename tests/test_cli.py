"""The `granrs` command line."""

import json
import subprocess
import sys


def run(*args):
    return subprocess.run([sys.executable, "-m", "granrs.cli", *args], capture_output=True, text=True)


def test_validate_writes_the_json_record(tmp_path):
    out = tmp_path / "h.json"
    r = run("validate", "hydrostatic", "--steps", "50", "--n", "16", "--json", str(out))
    assert r.returncode == 0, r.stderr
    rec = json.loads(out.read_text())
    assert set(rec) == {"case", "kind", "params", "metrics", "reference", "passed", "wall_s"}
    assert rec["case"] == "hydrostatic" and rec["passed"] is True


def test_bad_parameter_exits_with_a_clear_message():
    r = run("validate", "cavity", "--n", "-3")
    assert r.returncode == 2
    assert (
        "invalid parameter `--n` = '-3': allowed an integer in [2, 65536]" in r.stderr and "Traceback" not in r.stderr
    )


def test_unknown_case_is_rejected():
    r = run("validate", "no-such-case")
    assert r.returncode == 2 and "allowed one of" in r.stderr


def test_run_cavity_writes_plot_and_summary(tmp_path):
    r = run("run", "cavity", "--n", "16", "--re", "10", "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "cavity.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "summary.json").read_text())["n"] == 16


def test_validate_exit_status_follows_the_verdict():
    # one grid gives the Taylor-Green case no order to judge: passed is null, which is no failure
    r = run("validate", "taylor-green", "--n", "16")
    rec = json.loads(r.stdout)
    assert rec["passed"] is None
    assert r.returncode == 0 and "not judged" in r.stderr
