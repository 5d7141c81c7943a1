"""Sweeps: parameter parsing, validation before any run, dask results equal to one-by-one runs,
failing members reported while the others are kept, the CSV / Dataset / plot, the CLI."""

import csv
import subprocess
import sys
from pathlib import Path

import pytest

from granrs import ParameterError
from granrs.config import resolve
from granrs.sweep import members, parse_param, run_member, run_sweep

pytest.importorskip("dask.distributed")
pytest.importorskip("xarray")

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def base(out) -> dict:
    return resolve(
        {
            "grid": {"ny": 16},
            "time": {"t_end": 0.05},
            "numerics": {"threads": 1},
            "output": {"dir": str(out), "fields_every_s": 0.0, "animation": False},
        }
    )


def test_parse_linear_ranges_and_lists():
    assert parse_param("time.cfl=0.3:0.5:3") == ("time.cfl", pytest.approx([0.3, 0.4, 0.5]))
    assert parse_param("pore_pressure.diffusivity=0.01,0.035") == ("pore_pressure.diffusivity", [0.01, 0.035])
    assert parse_param("grid.ny=16:32:3") == ("grid.ny", [16, 24, 32])
    assert parse_param("rheology.law=drucker-prager,mu-i") == ("rheology.law", ["drucker-prager", "mu-i"])
    assert parse_param("fluidisation.fluidised=true,false") == ("fluidisation.fluidised", [True, False])


@pytest.mark.parametrize(
    "bad,match",
    [
        ("numerics.cfll=0.3", "`numerics.cfll`"),
        ("time.cfl", "key=a:b:n"),
        ("time.cfl=0.3:0.5:0", "integer n >= 1"),
        ("grid.ny=16:21:3", "not integers"),
        ("time.cfl=0.3,0.3", "distinct"),
    ],
)
def test_bad_parameters_are_rejected(bad, match):
    with pytest.raises(ParameterError, match=match):
        parse_param(bad)


def test_every_member_is_validated_before_any_run(tmp_path):
    with pytest.raises(ParameterError, match=r"sweep member 1 .*`time.cfl` = 2.5"):
        members(base(tmp_path), ["time.cfl=0.5,2.5"])
    with pytest.raises(ParameterError, match="`time.cfl`"):
        run_sweep(base(tmp_path / "s"), ["time.cfl=0.5:2.5:2"])
    assert not (tmp_path / "s").exists()


def test_sweep_on_a_local_cluster_equals_the_runs_one_by_one(tmp_path):
    params = ["time.cfl=0.3:0.5:2", "pore_pressure.diffusivity=0.01,0.035"]
    result = run_sweep(base(tmp_path / "dask"), params, workers=2)
    assert len(result.table) == 4 and all(r["status"] == "ok" for r in result.table)
    for row, m in zip(result.table, members(base(tmp_path / "serial"), params)):
        alone = run_member(m.config)
        assert row["time.cfl"] == m.values["time.cfl"]
        for key in ("runout_m", "t_end_s", "steps", "mass_rel_error", "stop_reason"):
            assert row[key] == alone[key], key
    assert result.table[0]["runout_m"] > 0
    ds = result.dataset
    assert dict(ds.sizes) == {"time.cfl": 2, "pore_pressure.diffusivity": 2}
    assert (
        float(ds["runout_m"].sel({"time.cfl": 0.5, "pore_pressure.diffusivity": 0.035})) == result.table[3]["runout_m"]
    )
    assert ds["runout_m"].attrs["units"] == "m" and "granrs_version" in ds.attrs
    rows = list(csv.DictReader(open(result.files["csv"])))
    assert len(rows) == 4 and float(rows[2]["runout_m"]) == pytest.approx(result.table[2]["runout_m"], rel=1e-12)
    assert result.files["png"].stat().st_size > 10_000 and result.files["nc"].exists()
    assert (tmp_path / "dask" / "member-003" / "summary.json").exists()


def test_a_failing_member_is_reported_and_the_others_kept(tmp_path):
    from dask.distributed import LocalCluster

    # geometry.length = 0.25 m passes validation but the column already touches the far end: a run-time error
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        result = run_sweep(base(tmp_path), ["geometry.length=0.25,2.25"], scheduler=cluster.scheduler_address)
    failed, ok = result.table
    assert failed["status"] == "failed" and "SimulationError" in failed["error"] and "far end" in failed["error"]
    assert failed["stop_reason"].startswith("error:")
    assert ok["status"] == "ok" and ok["runout_m"] > 0 and ok["error"] == ""
    assert list(result.dataset["status"].values) == ["failed", "ok"]


def test_cli_sweep_rejects_a_bad_parameter_before_any_work(tmp_path):
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "granrs.cli",
            "sweep",
            str(EXAMPLES / "paper_dry.toml"),
            "--param",
            "rheology.friction_angle=20,95",
            "--out",
            str(tmp_path / "s"),
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2 and "`rheology.friction_angle` = 95" in r.stderr
    assert not (tmp_path / "s").exists()
