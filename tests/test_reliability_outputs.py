"""Reliability of what granrs writes: it touches nothing it did not write (the manifest, the lock),
refuses before its first byte, writes what can be read back, and stops cleanly on the signals a
batch scheduler sends (docs/failures.md). Small grids (ny = 8-16)."""

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from granrs import Callback, ParameterError, Simulation, SimulationError
from granrs.cli import main
from granrs.config import load_config
from granrs.io import checkpoint as ckpt
from granrs.io.outputs import (
    LOCK,
    MANIFEST,
    OutputError,
    commit_output_dir,
    lock_output_dir,
    plan_output_dir,
    read_manifest,
    release_output_dir,
)
from granrs.io.vtk import read_pvd
from granrs.runner import run_config
from test_reliability import run_file  # the same small run file (tests/ is on the path)

netCDF4 = pytest.importorskip("netCDF4")


def cli(capsys, *argv):
    """(exit status, stderr) of ``granrs ARGV`` run in this process (argparse errors included)."""
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as err:
        rc = err.code
    return rc, capsys.readouterr().err


def tree(folder: Path) -> dict:
    """Every entry under ``folder`` (symbolic links not followed): a file's bytes, a link's target,
    'dir' for a folder."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(root) / name
            rel = str(p.relative_to(folder))
            if p.is_symlink():
                out[rel] = ("link", os.readlink(p))
            elif p.is_dir():
                out[rel] = ("dir",)
            else:
                out[rel] = ("file", p.read_bytes())
    return out


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished run (its run file, its folder): VTK and NetCDF snapshots and checkpoints every
    0.02 s up to 0.04 s. Tests work on copies (``copy_run``)."""
    base = tmp_path_factory.mktemp("finished")
    path = run_file(base, output={"checkpoint_every_s": 0.02, "formats": ["vtk", "netcdf"]}, time={"t_end": 0.04})
    assert main(["run", str(path), "--quiet"]) == 0
    return path, base / "out"


def copy_run(finished, dest: Path) -> Path:
    shutil.copytree(finished[1], dest, symlinks=True)
    return dest


# ---- the manifest and --overwrite --------------------------------------------------------------
def test_the_manifest_lists_every_file_the_run_wrote(finished):
    _, out = finished
    listed = read_manifest(out)
    files = {str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()} - {MANIFEST}
    assert files == {n for n in listed if not n.endswith("/")}
    assert {n for n in listed if n.endswith("/")} == {"fields/"}
    assert not (out / LOCK).exists()  # released at the run's end


def test_overwrite_refuses_a_folder_without_a_manifest_naming_a_file_not_granrs(tmp_path, capsys, finished):
    photos = tmp_path / "photos"
    photos.mkdir()
    (photos / "holiday.png").write_bytes(b"x")
    before = tree(photos)
    rc, err = cli(capsys, "run", finished[0], "--quiet", "--out", photos, "--overwrite")
    assert rc == 2 and "'holiday.png', a file that no granrs run recorded" in err and MANIFEST in err, err
    assert len(err.strip().splitlines()) == 1
    assert tree(photos) == before


def test_overwrite_never_follows_a_symbolic_link_out_of_the_folder(tmp_path, capsys, finished):
    other = tmp_path / "other"
    other.mkdir()
    (other / "fields_00000.vti").write_text("theirs")
    run = copy_run(finished, tmp_path / "run1")
    shutil.rmtree(run / "fields")
    (run / "fields").symlink_to("../other")
    before, before_other = tree(run), tree(other)
    rc, err = cli(capsys, "run", finished[0], "--quiet", "--out", run, "--overwrite")
    assert rc == 2 and "'fields', a symbolic link to '../other'" in err, err
    assert tree(run) == before and tree(other) == before_other


def test_overwrite_removes_exactly_the_manifest_files(tmp_path, capsys, finished):
    run = copy_run(finished, tmp_path / "run")
    (run / "notes.txt").write_text("mine")
    (run / "fields" / "mine.txt").write_text("mine too")
    old = read_manifest(run)
    rc, err = cli(capsys, "run", finished[0], "--quiet", "--out", run, "--overwrite", "--set", "time.t_end=0.02")
    assert rc == 0, err
    assert (run / "notes.txt").read_text() == "mine" and (run / "fields" / "mine.txt").read_text() == "mine too"
    new = read_manifest(run)
    # the earlier run's last snapshot (t = 0.04 s) is gone with its manifest; the new run wrote up to 0.02 s
    assert "fields/fields_00002.vti" in old and "fields/fields_00002.vti" not in new
    assert not (run / "fields" / "fields_00002.vti").exists()
    files = {str(p.relative_to(run)) for p in run.rglob("*") if p.is_file()} - {MANIFEST}
    assert files - new == {"notes.txt", "fields/mine.txt"}


def test_a_file_the_manifest_does_not_list_where_the_run_writes_stops_overwrite(tmp_path, capsys, finished):
    run = copy_run(finished, tmp_path / "run")
    lines = (run / MANIFEST).read_text().splitlines()
    (run / MANIFEST).write_text("\n".join(line for line in lines if line != "front.png") + "\n")
    before = tree(run)
    rc, err = cli(capsys, "run", finished[0], "--quiet", "--out", run, "--overwrite")
    assert rc == 2 and "'front.png', a file that no granrs run recorded, where the run would write" in err, err
    assert tree(run) == before


# ---- the lock ------------------------------------------------------------------------------------
def test_a_run_into_a_locked_folder_is_refused_naming_the_folder_and_the_process(tmp_path, capsys, finished):
    run = copy_run(finished, tmp_path / "run")
    commit_output_dir(plan_output_dir(run, overwrite=True), command="another granrs run")
    try:
        before = tree(run)
        for extra in ([], ["--overwrite"]):
            rc, err = cli(capsys, "run", finished[0], "--quiet", "--out", run, *extra)
            assert rc == 2 and f"`--out` = '{run}'" in err, err
            assert f"locked by process {os.getpid()}" in err and "another granrs run" in err, err
            assert tree(run) == before
    finally:
        release_output_dir(run)
    assert not (run / LOCK).exists()


def test_animate_records_its_file_and_waits_for_no_run(tmp_path, capsys, finished):
    run = copy_run(finished, tmp_path / "run")
    lock_output_dir(run, command="a run")  # as a run writing there holds it
    try:
        rc, err = cli(capsys, "animate", run)
        assert rc == 2 and "`dir`" in err and f"locked by process {os.getpid()}" in err, err
        assert not (run / "animation.gif").exists()
    finally:
        release_output_dir(run)
    rc, err = cli(capsys, "animate", run)
    assert rc == 0, err
    # the manifest lists it: --overwrite removes it, and does not take it for the user's
    assert "animation.gif" in read_manifest(run) and not (run / LOCK).exists()


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_a_stale_lock_is_reported_and_cleared_by_overwrite(tmp_path, capsys, finished):
    run = copy_run(finished, tmp_path / "run")
    pid = _dead_pid()
    (run / LOCK).write_text(json.dumps({"pid": pid, "host": os.uname().nodename}))
    before = tree(run)
    rc, err = cli(capsys, "run", finished[0], "--quiet", "--out", run)
    assert rc == 2 and f"stale lock {LOCK} of process {pid}" in err and "--overwrite to clear it" in err, err
    assert tree(run) == before
    rc, err = cli(capsys, "run", finished[0], "--quiet", "--out", run, "--overwrite", "--set", "time.t_end=0.02")
    assert rc == 0 and f"granrs: cleared the stale lock of process {pid}" in err, err
    assert not (run / LOCK).exists()


def test_two_runs_started_together_into_one_folder_one_is_refused(tmp_path):
    path = run_file(tmp_path, time={"t_end": 0.1}, output={"fields_every_s": 0.01})
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "granrs.cli", "run", str(path), "--quiet"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    results = sorted((p.wait(timeout=120), p.communicate()[1]) for p in procs)
    (ok, _), (refused, err) = results
    assert ok == 0 and refused == 2, results
    assert ("locked by process" in err or "the folder is not empty" in err) and "nothing was changed" in err, err
    assert "Traceback" not in err
    out = tmp_path / "out"
    for _, f in read_pvd(out / "fields.pvd"):  # every snapshot the index lists is there
        assert f.is_file(), f


# ---- every check before the first byte ---------------------------------------------------------
BEFORE_ANY_WRITE = [
    ({"bi_projection": {"plastic": "papanastasiou"}}, "`bi_projection.regularisation` = None"),
    ({"case": {"model": "granular"}, "numerics": {"pressure_update": "rotational"}}, "`numerics.pressure_update`"),
    (
        {"case": {"model": "granular"}, "active_region": {"band": 8, "sides": "open-right-top"}},
        "`active_region.sides` = open-right-top",
    ),
    (
        {"numerics": {"pressure_gauge": "mean"}, "active_region": {"band": 8, "sides": "open-right"}},
        "`numerics.pressure_gauge` = 'mean': not allowed with `active_region.band`",
    ),
    (
        {
            "case": {"model": "depth-averaged"},
            "side_walls": {"width": 0.1},
            "output": {"fields_every_s": None, "animation": None},
        },
        "`side_walls.width` = 0.1 with the depth-averaged model",
    ),
    (
        {
            "case": {"model": "depth-averaged"},
            "active_region": {"band": 8},
            "output": {"fields_every_s": None, "animation": None},
        },
        "`active_region.band` = 8 with the depth-averaged model",
    ),
    (
        {"case": {"model": "depth-averaged"}, "output": {"animation": None}},
        "`output.fields_every_s` = 0.02 with the depth-averaged model",
    ),
    ({"bi_projection": {"regularisation": 0.01}}, "`bi_projection.regularisation` = 0.01: not used"),
    ({"time": {"dt": 1e-4, "cfl_light": 0.5}}, "`time.cfl_light` = 0.5: not used"),
    ({"time": {"dt": 1e-4, "cfl": 0.3}}, "`time.cfl` = 0.3: not used; allowed only with the adaptive step"),
    ({"time": {"dt": 1e-4, "max_dt": 1e-3}}, "`time.max_dt` = 0.001: not used"),
    ({"case": {"model": "granular"}, "time": {"cfl_light": 0.9}}, "allowed only with the two-phase model"),
    ({"output": {"fields_every_s": 1e-6}, "time": {"t_end": 1e4}}, "GB of field snapshots"),
]


@pytest.mark.parametrize("sections, message", BEFORE_ANY_WRITE)
def test_every_check_is_done_before_the_first_byte(tmp_path, capsys, sections, message):
    path = run_file(tmp_path, **sections)
    rc, err = cli(capsys, "run", path, "--quiet")
    assert rc == 2 and message in err and str(path) in err, err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()  # a refused run writes nothing


def test_the_volume_refusal_names_the_estimate_and_the_free_disk(tmp_path, capsys):
    path = run_file(tmp_path, output={"fields_every_s": 1e-6}, time={"t_end": 1e4})
    rc, err = cli(capsys, "run", path, "--quiet")
    # ny = 8: 64 x 8 cells, 65 bytes a cell in a .vti: 33 kB a snapshot, 1e10 snapshots
    assert rc == 2 and "about 3.35e+05 GB of field snapshots" in err and "GB free on the file system of" in err, err


@pytest.mark.parametrize(
    "region, change, message",
    [
        (False, ["fluidisation.fluidised=false"], "(fluidisation.fluidised: True -> False)"),
        (True, [], "(active_region.band: 8 -> None)"),
    ],
)
def test_a_restart_whose_state_does_not_fit_the_changed_model_is_refused_before_any_write(
    tmp_path, capsys, finished, region, change, message
):
    path, out = finished
    if region:  # a checkpoint of a run on an active region, restarted on the whole domain
        assert (
            main(["run", str(path), "--quiet", "--out", str(tmp_path / "region"), "--set", "active_region.band=8"]) == 0
        )
        out = tmp_path / "region"
    sets = [a for item in change + ["time.t_end=0.06"] for a in ("--set", item)]
    restart = ["--restart", out / "checkpoint.npz", "--allow-changes", "--out", tmp_path / "changed"]
    rc, err = cli(capsys, "run", path, "--quiet", *restart, *sets)
    assert rc == 2 and f"the checkpoint's state does not fit the changed configuration {message}" in err, err
    assert "`object`" not in err and not (tmp_path / "changed").exists()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--out", "{tmp}/" + "x" * 300], "too long for the file system"),
        (["--out", "{tmp}/a\nb"], "holds a newline at offset"),
        (["--set", "time.t_end=0.01\n[grid]\nny=4"], "holds a newline at offset 15"),
        (["--set", 'output.formats=["vtk"]', "--set", 'case.model="two\tphase"'], "holds a tab"),
    ],
)
def test_paths_and_values_are_checked_before_any_work(tmp_path, capsys, finished, argv, message):
    rc, err = cli(capsys, "run", finished[0], "--quiet", *(a.replace("{tmp}", str(tmp_path)) for a in argv))
    assert rc == 2 and message in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_validate_json_is_checked_before_the_case_runs(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    rc, err = cli(capsys, "validate", "hydrostatic", "--json", tmp_path / "file" / "record.json")
    assert rc == 2 and "`--json`" in err and "is not a writable folder" in err, err


def test_compare_with_files_are_checked_before_any_work(tmp_path, capsys):
    other = tmp_path / "other"
    other.mkdir()
    (other / "summary.json").write_text("{not json")
    (other / "front.csv").write_text("t_s,front_m\n0,0\n")
    rc, err = cli(capsys, "run", "column", "--ny", "8", "--out", tmp_path / "out", "--compare-with", other)
    assert rc == 2 and "`--compare-with`" in err and "summary.json" in err, err
    assert not (tmp_path / "out").exists()


# ---- sweeps ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "argv, message",
    [
        (["--param", "time.cfl=0.3,0.4", "--param", "time.cfl=0.5,0.6"], "time.cfl is already swept"),
        (["--param", "time.cfl=0.3,0.4", "--set", "time.cfl=0.5"], "both swept and fixed"),
        (["--param", 'output.dir="a","b"'], "output.dir is not swept"),
        (["--param", "time.cfl=0.1:0.5:100000", "--param", "time.t_end=0.1:0.5:100000"], "10000000000 members"),
        (["--param", "time.cfl=0.3,0.4,0.5", "--max-members", "2"], "3 members (3 time.cfl), more than the limit of 2"),
        (
            ["--param", "numerics.pressure_update=standard,rotational", "--set", 'case.model="granular"'],
            "sweep member 1 ({'numerics.pressure_update': 'rotational'}): invalid parameter `numerics.pressure_update`",
        ),
    ],
)
def test_a_sweep_is_refused_before_its_first_member_runs(tmp_path, capsys, argv, message):
    path = run_file(tmp_path)
    rc, err = cli(capsys, "sweep", path, "--out", tmp_path / "sweep", *argv)
    assert rc == 2 and message in err, err
    assert not (tmp_path / "sweep").exists()


# ---- what granrs writes can be read back -------------------------------------------------------
def test_every_written_configuration_loads_and_reproduces_the_run(tmp_path, capsys):
    odd = tmp_path / 'a "quoted" #not-a-comment --dashes é'
    path = run_file(tmp_path, time={"t_end": 0.02})
    rc, err = cli(capsys, "run", path, "--quiet", "--out", odd, "--set", "time.cfl=0.25")
    assert rc == 0, err
    written = odd / "config.resolved.toml"
    cfg = load_config(written)
    assert cfg == load_config(path, ["time.cfl=0.25", f"output.dir={json.dumps(str(odd))}"])
    rc, err = cli(capsys, "run", written, "--quiet", "--out", tmp_path / "again")
    assert rc == 0, err
    first, again = (json.loads((d / "summary.json").read_text()) for d in (odd, tmp_path / "again"))
    assert (first["runout_m"], first["steps"]) == (again["runout_m"], again["steps"])  # the same run, to the bit
    assert load_config(tmp_path / "again" / "config.resolved.toml")["time"] == cfg["time"]


# ---- restarts into a damaged folder ------------------------------------------------------------
def _truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


DAMAGE = {
    "history.npz": _truncate,
    "front.csv": lambda p: p.write_bytes(b"\x00garbage,\xff\n1,2,3\n"),
    "fields.nc": _truncate,
    "fields.pvd": lambda p: p.write_text("<VTKFile><Collection><DataSet timestep='x'"),
}


@pytest.mark.parametrize("name", sorted(DAMAGE))
def test_a_restart_into_a_damaged_folder_is_refused_naming_the_file(tmp_path, capsys, finished, name):
    run = copy_run(finished, tmp_path / "run")
    DAMAGE[name](run / name)
    before = tree(run)
    rc, err = cli(
        capsys,
        "run",
        finished[0],
        "--quiet",
        "--out",
        run,
        "--restart",
        run / "checkpoint.npz",
        "--set",
        "time.t_end=0.06",
    )
    assert rc == 2 and f"{run / name} cannot be read" in err and "nothing was changed" in err, err
    assert tree(run) == before


def test_a_restart_writes_no_snapshot_twice(tmp_path, capsys, finished):
    run = copy_run(finished, tmp_path / "run")
    args = ("--out", run, "--restart", run / "checkpoint.npz", "--set", "time.t_end=0.06")
    rc, err = cli(capsys, "run", finished[0], "--quiet", *args)
    assert rc == 0, err
    times = [t for t, _ in read_pvd(run / "fields.pvd")]
    assert times == pytest.approx([0.0, 0.02, 0.04, 0.06]) and len(set(times)) == len(times)
    with netCDF4.Dataset(run / "fields.nc") as ds:
        assert np.asarray(ds["time"][:]) == pytest.approx([0.0, 0.02, 0.04, 0.06])
    (restart_config,) = run.glob("config.restart-*.toml")  # written by the restart, and readable
    assert restart_config.relative_to(run).as_posix() in read_manifest(run)
    assert load_config(restart_config) == load_config(
        finished[0], ["time.t_end=0.06", f"output.dir={json.dumps(str(run))}"]
    )


# ---- the signals of a batch scheduler ----------------------------------------------------------
def _rows(out: Path) -> int:
    try:
        return len((out / "front.csv").read_text().splitlines()) - 1
    except OSError:
        return 0


def _wait_for(predicate, timeout=120.0):
    t0 = time.time()
    while not predicate():
        if time.time() - t0 > timeout:
            raise AssertionError("timed out")
        time.sleep(0.05)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_stop_a_run_as_ctrl_c_does(tmp_path, signum):
    # ny = 16 up to 30 s and no stop at rest: far longer than the 10 records the test waits for
    # (it still runs after 6 s of wall time), so that the signal reaches a running simulation
    path = run_file(
        tmp_path, grid={"ny": 16}, time={"t_end": 30.0}, rest={"speed": 1e-9}, output={"checkpoint_every_s": 1.0}
    )
    out = tmp_path / "out"
    # the child starts with the default disposition: under nohup (SIGHUP ignored, which granrs
    # respects) the test would otherwise see a run that goes on
    proc = subprocess.Popen(
        [sys.executable, "-m", "granrs.cli", "run", str(path), "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signum, signal.SIG_DFL),
    )
    _wait_for(lambda: _rows(out) >= 10)
    proc.send_signal(signum)
    _, stderr = proc.communicate(timeout=120)
    name = signal.Signals(signum).name
    assert proc.returncode == 128 + signum, stderr
    lines = stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"granrs: terminated by {name}") and str(out) in lines[0], stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stop_reason"] == f"terminated by {name}"
    # the checkpoint holds the state the run stopped at, not the last scheduled one (t = 0 s)
    assert ckpt.load_checkpoint(out / "checkpoint.npz").meta["time"] == pytest.approx(summary["t_end_s"])
    # the tenth row is written at t = 0.09 s; the signal can stop the run before its next step
    assert summary["t_end_s"] >= 0.09 - 1e-12 and not (out / LOCK).exists()


def test_a_sweep_interrupted_by_ctrl_c_prints_one_line_and_marks_its_member(tmp_path):
    path = run_file(tmp_path, grid={"ny": 16}, time={"t_end": 3.0}, output={"fields_every_s": 0.0})
    sweep = tmp_path / "sweep"
    script = (
        "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        "from granrs.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", script, "sweep", str(path), "--out", str(sweep), "--workers", "1"]
        + ["--param", "time.cfl=0.3,0.4"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    _wait_for(lambda: _rows(sweep / "member-000") >= 10, timeout=240)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("granrs: interrupted (Ctrl-C)") and "Traceback" not in stderr, stderr
    rows = list(__import__("csv").DictReader((sweep / "sweep.csv").open()))
    # the member that was running is "interrupted", and so is any other that had started (a loaded
    # machine can see dask hand member 1 out before member 0 ends); one that never started is "pending"
    assert rows[0]["status"] == "interrupted", rows
    for r in rows[1:]:
        assert r["status"] == ("interrupted" if (sweep / f"member-{int(r['member']):03d}").exists() else "pending"), (
            rows
        )
    summary = json.loads((sweep / "member-000" / "summary.json").read_text())
    assert summary["stop_reason"] == "terminated by SIGTERM"  # the sweep stops its members with SIGTERM
    assert not (sweep / LOCK).exists() and not (sweep / "member-000" / LOCK).exists()


# ---- a disk full during a NetCDF append --------------------------------------------------------
def test_a_netcdf_append_that_fails_is_an_output_error_of_one_line(tmp_path, monkeypatch):
    import granrs.io.netcdf as nc

    real = netCDF4.Dataset

    def dataset(path, mode="r", **kw):
        if mode == "a":  # the second record on: what HDF5 reports on a full disk
            raise RuntimeError("NetCDF: HDF error")
        return real(path, mode, **kw)

    monkeypatch.setattr(nc.netCDF4 if hasattr(nc, "netCDF4") else netCDF4, "Dataset", dataset)
    cfg = load_config(run_file(tmp_path, output={"formats": ["netcdf"]}))
    with pytest.raises(OutputError) as info:
        run_config(cfg, progress=False)
    message = str(info.value)
    assert f"cannot write {tmp_path / 'out' / 'fields.nc'} (NetCDF: HDF error)" in message and "\n" not in message
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["stop_reason"].startswith("error: cannot write")


# ---- the Python API --------------------------------------------------------------------------------
def _model():
    import granrs

    return granrs.Model(granrs.Grid(8, 8, 1.0, 1.0), granrs.Material(1000.0, 1e-3), gravity=(0.0, -9.81))


@pytest.mark.parametrize(
    "make, name",
    [
        (lambda: Simulation(None, stop_time=1.0), "`model` = None"),
        (lambda: Simulation(_model(), stop_time=1.0, callbacks=Callback(print, every_time=0.1)), "`callbacks`"),
        (lambda: Callback(5, every_time=0.1), "`func` = 5"),
    ],
)
def test_the_python_api_names_the_argument(make, name):
    with pytest.raises(ParameterError, match=name.replace("(", r"\(")):
        make()


def test_a_model_run_from_two_threads_is_refused_naming_it():
    model = _model()
    started, go = threading.Event(), threading.Event()

    def hold(sim):
        started.set()
        go.wait(10)

    first = Simulation(model, stop_time=0.05, callbacks=[Callback(hold, every_steps=1)])
    worker = threading.Thread(target=first.run)
    worker.start()
    try:
        started.wait(10)
        with pytest.raises(ParameterError, match=r"`model` = <Model 8 x 8 cells at 0x[0-9a-f]+>: it is running"):
            Simulation(model, stop_time=0.05).run()
    finally:
        go.set()
        worker.join(30)


def test_a_callback_that_raises_stops_the_run_chained_with_its_outputs_kept(tmp_path):
    def broken(sim):
        if sim.model.time > 0.015:
            raise ValueError("the user's callback failed")

    cfg = load_config(run_file(tmp_path, time={"t_end": 0.04}))
    with pytest.raises(SimulationError) as info:
        run_config(cfg, progress=False, extra_callbacks=[Callback(broken, every_time=0.01)])
    chain, err = [], info.value
    while err is not None:
        chain.append(err)
        err = err.__cause__
    assert any(isinstance(e, ValueError) and str(e) == "the user's callback failed" for e in chain), chain
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["stop_reason"].startswith("error: the callback") and "ValueError" in summary["stop_reason"]
    assert (tmp_path / "out" / "front.csv").exists() and not (tmp_path / "out" / LOCK).exists()


# ---- the property: outside the manifest, nothing changes ---------------------------------------
hypothesis = pytest.importorskip("hypothesis")
st = hypothesis.strategies


def _owned(rel: str, manifest: set) -> bool:
    """Whether a path of the folder is the manifest's (listed, a listed file's .tmp, the manifest, the lock)."""
    base = rel[:-4] if rel.endswith(".tmp") else rel
    return rel in (MANIFEST, LOCK) or base in manifest or base + "/" in manifest


@hypothesis.settings(
    max_examples=15,
    deadline=None,
    suppress_health_check=[hypothesis.HealthCheck.function_scoped_fixture],
)
@hypothesis.given(
    earlier=st.booleans(),
    foreign=st.lists(
        st.sampled_from(
            ["notes.txt", "holiday.png", "front.png", "summary.json", "fields/mine.txt", "fields/fields_00009.vti"]
        ),
        unique=True,
        max_size=3,
    ),
    links=st.lists(st.sampled_from(["fields", "link.png", "elsewhere", MANIFEST]), unique=True, max_size=2),
    drop=st.sampled_from([None, "front.png", "fields/fields_00001.vti"]),
    action=st.sampled_from(["overwrite", "plain", "refused"]),
)
def test_outside_the_manifest_nothing_changes(
    tmp_path_factory, capsys, finished, earlier, foreign, links, drop, action
):
    base = tmp_path_factory.mktemp("property")
    other = base / "other"
    other.mkdir()
    (other / "fields_00000.vti").write_text("theirs")
    (other / "x.png").write_text("theirs")
    run = copy_run(finished, base / "run") if earlier else base / "run"
    run.mkdir(exist_ok=True)
    for name in links:  # symbolic links out of the folder (fields/ replaced by one, as a user might)
        target = run / name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        elif target.exists():
            target.unlink()
        target.symlink_to(other if name in ("fields", "elsewhere") else other / "x.png")
    for name in foreign:
        path = run / name
        if any(p.is_symlink() for p in [path, *path.parents][: len(Path(name).parts)]):
            continue  # not through a link: the files out of the folder are the link's target's
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(f"the user's {name}")
    if earlier and drop is not None:
        lines = (run / MANIFEST).read_text().splitlines()
        (run / MANIFEST).write_text("\n".join(line for line in lines if line != drop) + "\n")
    manifest = read_manifest(run) or set()
    before, before_other = tree(run), tree(other)
    kept = {rel: v for rel, v in before.items() if not _owned(rel, manifest)}
    argv = {
        "overwrite": ["--overwrite", "--set", "time.t_end=0.02"],
        "plain": ["--set", "time.t_end=0.02"],
        "refused": ["--overwrite", "--set", "time.cfl=5"],
    }[action]
    rc, err = cli(capsys, "run", finished[0], "--quiet", "--out", run, *argv)
    hypothesis.event(f"exit status {rc}")
    after = tree(run)
    assert tree(other) == before_other  # nothing out of the folder is ever touched
    for rel, value in kept.items():  # nothing the manifest did not list changed
        assert after.get(rel) == value, (rel, rc, err)
    if rc != 0:
        assert rc == 2 and after == before, err  # a refused run writes nothing
    else:
        new = read_manifest(run)
        assert all(_owned(rel, new) or rel in kept for rel in after), (sorted(after), sorted(new))
