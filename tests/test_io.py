"""Outputs: VTK .vti/.pvd, NetCDF (CF attributes, opens with xarray), animation, provenance,
checkpoint file format, and what an interrupted or failed run leaves behind."""

import json
import os
import signal
import xml.etree.ElementTree as ET
from types import SimpleNamespace

import numpy as np
import pytest

from granrs import Callback, ParameterError, Simulation, SimulationError
from granrs.cases.column import build_model
from granrs.config import column_case, load_config, resolve, tomllib
from granrs.io import (
    deferred_interrupt,
    load_checkpoint,
    read_pvd,
    read_vti,
    restore_checkpoint,
    save_checkpoint,
    write_vti,
)
from granrs.runner import run_config

xr = pytest.importorskip("xarray")
pytest.importorskip("netCDF4")

TIMES = [0.0, 0.02, 0.04, 0.06]


def tiny(out, **output) -> dict:
    return resolve(
        {
            "grid": {"ny": 16},
            "time": {"t_end": 0.06},
            "output": {"dir": str(out), "fields_every_s": 0.02, "formats": ["vtk", "netcdf"], **output},
        }
    )


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    cfg = tiny(out)
    summary = run_config(cfg, progress=False, command="granrs run tiny.toml")
    return SimpleNamespace(out=out, cfg=cfg, summary=summary)


def test_vti_parses_with_the_grid_dimensions_and_the_initial_values(run):
    files = sorted((run.out / "fields").glob("*.vti"))
    assert len(files) == len(TIMES)
    root = ET.parse(files[0]).getroot()
    assert root.get("type") == "ImageData"
    image = root.find("ImageData")
    grid = column_case(run.cfg).grid()
    assert grid.ny == 16 and image.get("WholeExtent") == f"0 {grid.nx} 0 16 0 0"
    names = {a.get("Name") for a in image.find("Piece/CellData")}
    assert names == {"phi", "p", "pf", "yielded", "velocity"}
    frame = read_vti(files[0])
    assert frame["time"] == 0.0 and frame["shape"] == (16, grid.nx)
    assert frame["spacing"][:2] == pytest.approx((grid.lx / grid.nx, 0.45 / 16))
    model = build_model(column_case(run.cfg))  # the same initial state, built again
    np.testing.assert_array_equal(frame["fields"]["phi"], model.phi)
    np.testing.assert_array_equal(frame["fields"]["pf"], model.pf)
    assert frame["fields"]["velocity"].shape == (16, grid.nx, 3)
    assert frame["provenance"]["command_line"] == "granrs run tiny.toml"


def test_pvd_indexes_every_snapshot_in_time_order(run):
    entries = read_pvd(run.out / "fields.pvd")
    assert [t for t, _ in entries] == pytest.approx(TIMES)
    assert all(p.exists() for _, p in entries)


def test_netcdf_opens_with_xarray_with_cf_attributes_and_the_vti_values(run):
    with xr.open_dataset(run.out / "fields.nc") as ds:
        assert ds.attrs["Conventions"].startswith("CF-")
        assert dict(ds.sizes) == {"time": 4, "y": 16, "x": column_case(run.cfg).grid().nx}
        assert ds["time"].values == pytest.approx(TIMES) and ds["time"].attrs["units"] == "s"
        assert ds["x"].attrs["units"] == "m" and ds["x"].attrs["axis"] == "X" and ds["y"].attrs["axis"] == "Y"
        units = {"phi": "m", "u": "m s-1", "v": "m s-1", "p": "Pa", "pf": "Pa", "yielded": "1"}
        for name, unit in units.items():
            assert ds[name].attrs["units"] == unit and ds[name].attrs["long_name"]
        assert set(np.unique(ds["yielded"].values)) <= {0, 1}
        last = read_vti(sorted((run.out / "fields").glob("*.vti"))[-1])
        np.testing.assert_array_equal(ds["phi"].values[-1], last["fields"]["phi"])
        np.testing.assert_array_equal(ds["u"].values[-1], last["fields"]["velocity"][..., 0])
        for key in ("granrs_version", "git_revision", "command_line", "created_utc", "history", "source"):
            assert key in ds.attrs
        assert resolve(tomllib.loads(ds.attrs["configuration"])) == run.cfg


def test_summary_resolved_config_and_animation(run):
    summary = json.loads((run.out / "summary.json").read_text())
    assert summary["stop_reason"] == "stop_time" and summary["config"] == run.cfg
    assert summary["provenance"]["granrs_version"] and "command_line" in summary["provenance"]
    assert load_config(run.out / "config.resolved.toml") == run.cfg
    from PIL import Image

    with Image.open(run.out / "animation.gif") as gif:
        assert gif.n_frames == len(TIMES)


def test_yielded_mask_is_trial_norm_above_one_inside_the_granular_phase(tmp_path):
    from granrs.io import snapshot

    model = build_model(column_case(resolve({"grid": {"ny": 16}, "fluidisation": {"fluidised": False}})))
    Simulation(model, stop_time=0.05).run()
    fields = snapshot(model)
    tn, granular = np.asarray(model.trial_norm), model.phi > 0
    np.testing.assert_array_equal(fields["yielded"], (tn > 1) & granular)
    assert fields["yielded"].dtype == np.uint8 and "pf" not in fields
    assert not fields["yielded"][~granular].any()  # the air (no yield stress) is never marked


def test_vti_reads_with_the_vtk_package(run):
    # read back with VTK's own XML image-data reader, values compared exactly
    vtk = pytest.importorskip("vtk")
    from vtk.util.numpy_support import vtk_to_numpy

    path = sorted((run.out / "fields").glob("*.vti"))[-1]
    reader = vtk.vtkXMLImageDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    image = reader.GetOutput()
    grid = column_case(run.cfg).grid()
    assert image.GetDimensions() == (grid.nx + 1, grid.ny + 1, 1)
    ours = read_vti(path)["fields"]
    for name in ("phi", "p", "pf"):
        data = vtk_to_numpy(image.GetCellData().GetArray(name)).reshape(grid.ny, grid.nx)
        np.testing.assert_array_equal(data, ours[name])
    vel = vtk_to_numpy(image.GetCellData().GetArray("velocity")).reshape(grid.ny, grid.nx, 3)
    np.testing.assert_array_equal(vel, ours["velocity"])


def test_vti_round_trip_of_arbitrary_fields(tmp_path):
    rng = np.random.default_rng(1)
    fields = {
        "phi": rng.normal(size=(3, 5)),
        "u": rng.normal(size=(3, 5)),
        "v": rng.normal(size=(3, 5)),
        "yielded": rng.integers(0, 2, size=(3, 5)).astype(np.uint8),
    }
    write_vti(tmp_path / "a.vti", fields, (0.5, 0.25), 1.25, {"command_line": "a -- b --- c"})
    back = read_vti(tmp_path / "a.vti")
    assert back["time"] == 1.25 and back["spacing"] == (0.5, 0.25, 0.5)
    np.testing.assert_array_equal(back["fields"]["phi"], fields["phi"])
    np.testing.assert_array_equal(back["fields"]["yielded"], fields["yielded"])
    np.testing.assert_array_equal(back["fields"]["velocity"][..., 1], fields["v"])
    assert back["provenance"]["command_line"] == "a -- b --- c"  # '--' survives the XML comment


def test_a_vti_without_its_image_data_is_refused_naming_the_element(tmp_path):
    write_vti(tmp_path / "a.vti", {"phi": np.zeros((2, 3))}, (1.0, 1.0), 0.0, {})
    (tmp_path / "b.vti").write_text((tmp_path / "a.vti").read_text().replace("ImageData", "PolyData"))
    with pytest.raises(ValueError, match="no <ImageData>"):
        read_vti(tmp_path / "b.vti")


def test_netcdf_fields_without_a_given_provenance_carry_this_process_provenance(tmp_path):
    import netCDF4

    import granrs
    from granrs.io import FieldWriter

    model = granrs.Model(granrs.Grid(8, 8, 1.0, 1.0), granrs.Material(1.0, 1.0))
    FieldWriter(tmp_path, model.grid, formats=["netcdf"]).write(model)
    with netCDF4.Dataset(tmp_path / "fields.nc") as ds:
        assert ds.granrs_version == granrs.__version__ and ds["time"].size == 1


def _stop_at(t_stop, exc):
    def func(sim):
        if sim.model.time >= t_stop:
            raise exc

    return Callback(func, every_time=0.01)


def test_an_interrupted_run_leaves_readable_outputs_and_a_stop_reason(tmp_path):
    cfg = tiny(tmp_path)
    with pytest.raises(KeyboardInterrupt):
        run_config(cfg, progress=False, extra_callbacks=[_stop_at(0.03, KeyboardInterrupt())])
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["stop_reason"] == "interrupted: KeyboardInterrupt" and 0.03 <= summary["t_end_s"] < 0.06
    with xr.open_dataset(tmp_path / "fields.nc") as ds:
        assert ds["time"].values == pytest.approx([0.0, 0.02])
    assert [t for t, _ in read_pvd(tmp_path / "fields.pvd")] == pytest.approx([0.0, 0.02])
    assert (tmp_path / "front.csv").read_text().count("\n") >= 4 and (tmp_path / "history.npz").exists()


def test_a_failed_run_is_data_outputs_summary_and_animation(tmp_path):
    cfg = tiny(tmp_path)
    with pytest.raises(SimulationError, match="injected"):
        run_config(cfg, progress=False, extra_callbacks=[_stop_at(0.03, SimulationError("injected failure"))])
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["stop_reason"].startswith("error: injected failure")
    assert (tmp_path / "animation.gif").exists() and (tmp_path / "front.png").exists()


def test_a_state_saving_callback_finds_front_and_history_written_up_to_its_time(tmp_path):
    # A checkpoint taken between two progress flushes would let a restart append to a front.csv
    # and history.npz that stop short of it: the driver flushes them before every such callback.
    seen = []

    def check(sim):
        t = sim.model.time
        front = np.genfromtxt(tmp_path / "front.csv", delimiter=",", names=True)["t_s"]
        with np.load(tmp_path / "history.npz") as z:  # no step yet at t = 0: no entries
            step_t = float(z["time"][-1]) if "time" in z.files else 0.0
        seen.append((t, float(np.atleast_1d(front)[-1]), step_t))

    run_config(tiny(tmp_path), progress=False, extra_callbacks=[Callback(check, every_time=0.03, saves_state=True)])
    assert [round(t, 9) for t, _, _ in seen] == [0.0, 0.03, 0.06]
    for t, front_t, step_t in seen:  # records every 0.01 s (6 digits in front.csv); steps land on t
        assert front_t == pytest.approx(t, abs=1e-6) and step_t == pytest.approx(t, abs=1e-12)


def test_saves_state_must_be_a_bool():
    with pytest.raises(ParameterError, match="saves_state"):
        Callback(lambda sim: None, every_time=0.1, saves_state="yes")  # type: ignore[arg-type]


def test_a_real_failure_domain_too_short_is_reported(tmp_path):
    cfg = resolve({**tiny(tmp_path), "grid": {"ny": 16}, "geometry": {"length": 0.25}})
    with pytest.raises(SimulationError, match="far end"):
        run_config(cfg, progress=False)
    assert "far end" in json.loads((tmp_path / "summary.json").read_text())["stop_reason"]


def test_a_ctrl_c_during_a_write_is_held_until_the_write_ends():
    done = []
    # SIGINT raising KeyboardInterrupt, as in a terminal, whatever the test runner inherited
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            with deferred_interrupt():
                os.kill(os.getpid(), signal.SIGINT)
                done.append("write finished")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert done == ["write finished"]


def test_a_process_that_ignores_ctrl_c_ignores_it_inside_a_held_block_too():
    # a run started in the background by a shell without job control has SIGINT ignored: a held
    # block must not turn it on for its duration (a Ctrl-C would then stop the run or not
    # depending on where it lands)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with deferred_interrupt():
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            os.kill(os.getpid(), signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)


# ---- checkpoints ---------------------------------------------------------------------------------
class _FakeCore:
    """A stand-in for the core's state export, to test the file format without it."""

    def __init__(self, rust):
        self._rust, self.restored = rust, None

    def __getattr__(self, name):
        return getattr(self._rust, name)

    def checkpoint_state(self):
        return {
            "u": np.arange(6.0).reshape(2, 3),
            "history": np.ones((2, 2), dtype=np.int32),
            "time": 0.125,
            "step_count": 7,
            "dt_previous": 1 / 3,
        }

    def restore_state(self, state):
        self.restored = state


def test_checkpoint_file_format_round_trip(tmp_path):
    model = build_model(column_case(tiny(tmp_path)))
    model._rust = _FakeCore(model._rust)
    path = save_checkpoint(model, tmp_path / "ck.npz", provenance={"granrs_version": "x"})
    ck = load_checkpoint(path)
    assert ck.meta["format"] == "granrs-checkpoint" and ck.meta["grid"]["nx"] == model.grid.nx and ck.meta["provenance"]
    np.testing.assert_array_equal(ck.state["u"], np.arange(6.0).reshape(2, 3))
    assert ck.state["history"].dtype == np.int32
    assert ck.state["dt_previous"] == 1 / 3 and type(ck.state["step_count"]) is int
    np.testing.assert_array_equal(ck.fields["phi"], model.phi)
    restore_checkpoint(model, path)
    assert model._rust.restored["time"] == 0.125
    (tmp_path / "not.npz").write_bytes(b"nope")
    with pytest.raises(ParameterError, match="checkpoint"):
        load_checkpoint(tmp_path / "not.npz")


def test_restart_is_bit_identical(tmp_path):
    case = column_case(tiny(tmp_path))
    a = build_model(case)
    Simulation(a, stop_time=0.03).run()
    save_checkpoint(a, tmp_path / "ck.npz")
    Simulation(a, stop_time=0.06).run()
    b = build_model(case)
    restore_checkpoint(b, tmp_path / "ck.npz")
    assert b.time == 0.03
    Simulation(b, stop_time=0.06).run()
    for name in ("u", "v", "p", "phi", "pf", "sigma_xx", "sigma_xy"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name))
    assert b.step_count == a.step_count


def test_restart_with_an_active_window_is_bit_identical(tmp_path):
    """The reference case's configuration (the open window), on a dry column whose window has
    shrunk and grown before the checkpoint at 0.8 s: the window's size is part of the state (its
    hysteresis keeps a size that the dense phase's extent alone does not give), so the restored
    model rebuilds the window the run had and continues as the uninterrupted run. (Values
    compared: the sign of a zero may differ on the domain's boundary faces outside the window,
    which the window never reads.)"""
    from granrs import ActiveRegion
    from granrs.cases.column import ColumnCase, Fluidisation

    case = ColumnCase(
        ny=16,
        fluidisation=Fluidisation(fluidised=False),
        threads=1,
        active_region=ActiveRegion(2, sides="open-right-top"),
    )
    a = build_model(case)
    a.advance(t_end=0.8)
    assert a.active_window is not None and a.active_window[0] < a.grid.nx
    save_checkpoint(a, tmp_path / "ck.npz")
    a.advance(t_end=0.9)
    b = build_model(case)
    restore_checkpoint(b, tmp_path / "ck.npz")
    b.advance(t_end=0.9)
    assert b.active_window == a.active_window
    for name in ("u", "v", "p", "phi", "sigma_xx", "sigma_xy"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name))
    assert b.step_count == a.step_count
