"""Parameter sweeps of a run file on dask.distributed: the cartesian product of swept keys.

    result = run_sweep("examples/paper_fluidised.toml",
                       ["time.cfl=0.3:0.5:3", "pore_pressure.diffusivity=0.01,0.035"], workers=2)
    result.table        # list of dicts, one per member (also sweep.csv)
    result.dataset      # xarray.Dataset over the swept keys (also sweep.nc)

A parameter is ``key=a:b:n`` (n values from a to b, linear) or ``key=v1,v2,...`` (TOML
scalars). Every member's configuration is resolved and validated before any member runs; a
member is a deterministic function of that configuration (its thread count is explicit in
numerics.threads, its output folder is ``<out>/member-NNN``). Each member runs in its own child
process of the dask worker, so a member that dies (killed by the system for its memory, or an
abort) takes neither the worker nor the sweep with it. A member that fails or dies is reported
(status "failed", the error text, what it computed before failing) and the others are kept;
sweep.csv is rewritten after every finished member (status "pending" for those still to come).
The sweep folder must be new or empty unless ``overwrite``.
By default the members run on a LocalCluster of ``workers`` processes with one thread each;
``scheduler`` gives the address of an existing dask scheduler instead. Needs ``granrs[io]``.
"""

from __future__ import annotations

import csv
import itertools
import json
import logging
import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Union

import numpy as np

from ._granrs import ParameterError
from .cases.column import PAPER_RUNOUT_EXP, PAPER_RUNOUT_SIM
from .config import Config, dumps, full_key_message, key as config_key, load_config, parse_scalar, resolve, set_value
from .io.outputs import (
    atomic_write,
    commit_output_dir,
    control_character,
    lock_holder,
    plan_output_dir,
    record,
    release_output_dir,
)
from .io.provenance import provenance
from .runner import check_output_volume, preflight, run_config
from .simulation import raise_terminated

RECORD_KEYS = ("status", "runout_m", "t_end_s", "steps", "stop_reason", "wall_s", "mass_rel_error", "error")


def parse_param(text: str) -> tuple[str, list]:
    """``key=a:b:n`` (linear, n values) or ``key=v1,v2`` into (key, values); values are checked
    against the key's type later, when the members are resolved."""
    if "=" not in text:
        raise ParameterError(f"invalid parameter `--param {text}`: allowed key=a:b:n or key=v1,v2,...")
    bad = control_character(text)
    if bad is not None:
        raise ParameterError(
            f"invalid parameter `--param {text!r}`: it holds a {bad}; allowed one line key=a:b:n or key=v1,v2,..."
        )
    name, spec = (s.strip() for s in text.split("=", 1))
    k = config_key(name)
    if name == "output.dir":
        raise ParameterError(
            f"invalid parameter `--param {text}`: output.dir is not swept (each member writes into "
            "<out>/member-NNN); allowed a key of the model or the run (granrs keys), and --out for the sweep's folder"
        )
    if spec.count(":") == 2 and "[" not in spec and '"' not in spec:
        a, b, n = (parse_scalar(s.strip()) for s in spec.split(":"))
        if (
            isinstance(n, bool)
            or not isinstance(n, int)
            or n < 1
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in (a, b))
        ):
            raise ParameterError(
                f"invalid parameter `--param {name}` = {spec!r}: allowed a:b:n with numbers a, b and an integer n >= 1"
            )
        values = [float(v) for v in np.linspace(a, b, n)]
        if k.kind == "int":
            if any(v != round(v) for v in values):
                raise ParameterError(
                    f"invalid parameter `--param {name}` = {spec!r}: {k.allowed()}, and {values} are not integers"
                )
            values = [int(round(v)) for v in values]
    else:
        values = [parse_scalar(s.strip()) for s in spec.split(",")]
    if len({json.dumps(v) for v in values}) != len(values):
        raise ParameterError(f"invalid parameter `--param {name}` = {spec!r}: allowed distinct values, got {values}")
    return name, values


#: The most members a sweep runs unless ``max_members`` (``--max-members``) says more.
MAX_MEMBERS = 1000


def _params(params, max_members: int = MAX_MEMBERS) -> dict[str, list]:
    """The swept keys and their values; a key given twice, ``output.dir`` and a product of more
    than ``max_members`` members are refused."""
    if isinstance(params, Mapping):
        out = {}
        for name, values in params.items():
            config_key(name)
            if name == "output.dir":
                raise ParameterError("invalid parameter `params` key 'output.dir': allowed a key other than output.dir")
            out[name] = list(values)
    else:
        out = {}
        for p in params:
            name, values = parse_param(p)
            if name in out:
                raise ParameterError(
                    f"invalid parameter `--param {p}`: {name} is already swept by another --param; allowed "
                    "each key once (its values in one --param: key=v1,v2,...)"
                )
            out[name] = values
    if not out or any(len(v) == 0 for v in out.values()):
        raise ParameterError("invalid parameter `params`: allowed at least one key with at least one value")
    if isinstance(max_members, bool) or not isinstance(max_members, int) or max_members < 1:
        raise ParameterError(f"invalid parameter `max_members` = {max_members!r}: allowed an integer >= 1")
    count = math.prod(len(v) for v in out.values())
    if count > max_members:
        raise ParameterError(
            f"invalid parameter `--param`: the sweep has {count} members "
            f"({' x '.join(f'{len(v)} {k}' for k, v in out.items())}), more than the limit of {max_members}; "
            "allowed at most that many, or --max-members N (max_members=N) to raise the limit"
        )
    return out


@dataclass
class Member:
    index: int
    values: dict
    config: Config


def members(
    config: Union[str, Path, Config],
    params,
    out: Optional[Union[str, Path]] = None,
    max_members: int = MAX_MEMBERS,
    fixed: tuple = (),
) -> list[Member]:
    """The resolved configuration of every member (validated now: a bad value fails here, before
    any run). ``out`` (default: the base output.dir) holds member-NNN folders; ``fixed``: keys
    the base was given on the command line (--set), which a swept key may not be."""
    base = load_config(config) if isinstance(config, (str, Path)) else resolve(config)
    params = _params(params, max_members)
    both = sorted(set(params) & set(fixed))
    if both:
        raise ParameterError(
            f"invalid parameter `--param {both[0]}=...` with `--set {both[0]}=...`: the key is both swept and "
            "fixed; allowed one of them"
        )
    out = Path(out) if out is not None else Path(base["output"]["dir"])
    result = []
    for i, combo in enumerate(itertools.product(*params.values())):
        raw = {s: dict(t) for s, t in base.items()}
        values = dict(zip(params, combo))
        for name, v in values.items():
            set_value(raw, name, v)
        set_value(raw, "output.dir", str(out / f"member-{i:03d}"))
        try:
            cfg = resolve(raw)
        except ParameterError as err:
            raise ParameterError(f"sweep member {i} ({values}): {err}") from None
        values = {name: cfg[name.split(".")[0]][name.split(".")[1]] for name in params}  # as resolved (ints to floats)
        result.append(Member(i, values, cfg))
    return result


def _summary_of(folder) -> dict:
    """The row entries of a member from its summary.json as it is on disk (none without one)."""
    summary = _read_summary({"output": {"dir": folder}})
    return {k: summary[k] for k in ("runout_m", "t_end_s", "steps", "stop_reason", "mass_rel_error") if k in summary}


def _stop_members(configs: list, wait: float = 60.0) -> None:
    """Sends SIGTERM to the member processes running on this host (the process each member's
    folder lock names) and waits up to ``wait`` seconds for their locks to go: each writes its
    outputs and stops as a run stopped by SIGTERM does."""
    running = []
    for cfg in configs:
        holder = lock_holder(cfg["output"]["dir"])
        if holder is None or holder[0] != "held":
            continue
        info = holder[1]
        if info.get("host") == socket.gethostname() and isinstance(info.get("pid"), int):
            try:
                os.kill(info["pid"], signal.SIGTERM)
                running.append(cfg["output"]["dir"])
            except OSError:
                pass
    t0 = time.perf_counter()
    while running and time.perf_counter() - t0 < wait:
        running = [d for d in running if (h := lock_holder(d)) is not None and h[0] == "held"]
        time.sleep(0.05)


def _record(rec: dict, summary: dict, t0: float) -> dict:
    for k in ("runout_m", "t_end_s", "steps", "stop_reason", "mass_rel_error"):
        rec[k] = summary.get(k, math.nan if k != "stop_reason" else "")
    rec["wall_s"] = time.perf_counter() - t0
    return rec


def _read_summary(cfg: Config) -> dict:
    path = Path(cfg["output"]["dir"]) / "summary.json"
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def run_member_here(cfg: Config) -> dict:
    """Runs one member in this process; never raises: a failure becomes status 'failed' with its
    error text, plus what the run computed before failing (its summary.json, when written)."""
    t0 = time.perf_counter()
    rec = {"status": "ok", "error": ""}
    summary = {}
    try:
        summary = run_config(cfg, progress=False, command="granrs.sweep.run_member", overwrite=True)
    except Exception as err:  # a member's failure is data
        rec.update(status="failed", error=f"{type(err).__name__}: {err}")
        summary = _read_summary(cfg)
    return _record(rec, summary, t0)


def run_member(cfg: Config) -> dict:
    """Runs one member in a child process (``python -m granrs.sweep member DIR``, the
    configuration on stdin, the record on stdout); never raises. A child that dies (a signal:
    SIGKILL from the system's out-of-memory killer, SIGABRT) or exits without a record is a
    'failed' member naming how it ended, with what its summary.json held by then."""
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "granrs.sweep", "member", str(cfg["output"]["dir"])],
        input=json.dumps(cfg),
        capture_output=True,
        text=True,
    )
    lines = proc.stdout.strip().splitlines()
    if proc.returncode == 0 and lines:
        try:
            return json.loads(lines[-1])
        except ValueError:
            pass
    if proc.returncode < 0:
        name = signal.Signals(-proc.returncode).name if -proc.returncode in signal.Signals._value2member_map_ else "?"
        why = f"the member's process died from signal {name} ({-proc.returncode})" + (
            ": killed from outside or by the system's out-of-memory killer" if name == "SIGKILL" else ""
        )
    else:
        tail = proc.stderr.strip().splitlines()[-1:] or [""]
        why = f"the member's process exited with status {proc.returncode} without a result: {tail[0]}"
    summary = _read_summary(cfg)
    return _record({"status": "failed", "error": f"MemberDied: {why}"}, summary, t0)


def _member_main(out: str) -> int:
    for signum in (signal.SIGTERM, signal.SIGHUP):  # the sweep stops its members with SIGTERM
        signal.signal(signum, raise_terminated)
    cfg = json.loads(sys.stdin.read())
    if str(cfg["output"]["dir"]) != out:
        raise SystemExit(f"granrs.sweep member: the folder {out!r} is not the configuration's {cfg['output']['dir']!r}")
    t0 = time.perf_counter()
    try:
        rec = run_member_here(cfg)
    except KeyboardInterrupt as err:  # a Ctrl-C or the sweep's SIGTERM: the member's outputs are kept
        rec = _record(
            {"status": "interrupted", "error": f"interrupted: {err or 'KeyboardInterrupt'}"}, _read_summary(cfg), t0
        )
    print(json.dumps(rec))
    return 0


@dataclass
class SweepResult:
    """``table``: one dict per member (member, swept keys, RECORD_KEYS, dir); ``dataset``: the
    same as an xarray.Dataset over the swept keys; ``files``: csv, nc, png paths."""

    table: list
    dataset: object
    files: dict


def run_sweep(
    config: Union[str, Path, Config],
    params,
    scheduler: Optional[str] = None,
    workers: int = 2,
    out: Optional[Union[str, Path]] = None,
    plot: bool = True,
    overwrite: bool = False,
    max_members: int = MAX_MEMBERS,
    fixed: tuple = (),
    source: Optional[str] = None,
) -> SweepResult:
    """Runs every member on dask.distributed and gathers the results (see the module docstring).
    Writes ``<out>/sweep.csv`` (after every finished member), ``sweep.nc`` and ``sweep_runout.png``.
    ``max_members``: the most members allowed; ``fixed``: the keys --set gave; ``source``: the
    run file, named in the errors."""
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 256:
        raise ParameterError(f"invalid parameter `workers` = {workers!r}: allowed an integer in [1, 256]")
    base = load_config(config) if isinstance(config, (str, Path)) else resolve(config)
    out = Path(out) if out is not None else Path(base["output"]["dir"])
    plan = plan_output_dir(out, overwrite=overwrite, name="--out")
    mems = members(base, params, out, max_members, fixed)
    total = {"output": {"fields_every_s": 0.0}}  # the volume of all members together, below
    for m in mems:  # every check of a run, before any member runs
        try:
            preflight(m.config)
            check_output_volume(m.config, plan, total=total)
        except ParameterError as err:
            text = full_key_message(str(err))
            raise ParameterError(
                f"{source + ': ' if source else ''}sweep member {m.index} ({m.values}): {text}"
            ) from None
    commit_output_dir(plan)
    try:
        return _run_members(base, mems, out, scheduler, workers, plot)
    finally:
        release_output_dir(out)


def _run_members(base: Config, mems: list, out: Path, scheduler, workers: int, plot: bool) -> SweepResult:
    for m in mems:
        record(m.config["output"]["dir"], folder=True)
    table = [
        {
            "member": m.index,
            **m.values,
            **{k: ("pending" if k == "status" else None) for k in RECORD_KEYS},
            "dir": m.config["output"]["dir"],
        }
        for m in mems
    ]

    def finished(i: int, rec: dict) -> None:
        table[i].update({k: rec.get(k) for k in RECORD_KEYS})
        _write_csv(out / "sweep.csv", table)

    _write_csv(out / "sweep.csv", table)
    try:
        _run_on_dask([m.config for m in mems], scheduler, workers, finished)
    except KeyboardInterrupt:
        for row in table:  # the members that had started and not ended
            if row["status"] == "pending" and Path(row["dir"]).exists():
                row.update(
                    status="interrupted", error="interrupted: the sweep was interrupted", **_summary_of(row["dir"])
                )
        _write_csv(out / "sweep.csv", table)
        raise
    prov = provenance(dumps(base))
    files = {"csv": _write_csv(out / "sweep.csv", table)}
    ds = to_dataset(table, list(mems[0].values), prov)
    record(out / "sweep.nc")
    ds.to_netcdf(out / "sweep.nc")
    files["nc"] = out / "sweep.nc"
    if plot:
        record(out / "sweep_runout.png")
        files["png"] = plot_runout(table, list(mems[0].values), out / "sweep_runout.png")
    return SweepResult(table, ds, files)


def _run_on_dask(configs: list, scheduler: Optional[str], workers: int, finished) -> None:
    """Runs ``run_member`` on every configuration; ``finished(index, record)`` as each ends."""
    import dask  # deferred: optional dependency (the io extra)
    from dask.distributed import Client, LocalCluster, as_completed  # deferred: optional dependency (the io extra)

    cluster = None
    if scheduler is None:
        # the workers (and the members they start) ignore SIGINT: a Ctrl-C reaches this process, which
        # stops the members with SIGTERM (_stop_members), without a worker's traceback
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if _main_thread() else None
        try:
            with (
                dask.config.set({"distributed.scheduler.allowed-failures": 0}),  # a dead worker: report, not retry
                warnings.catch_warnings(),
            ):
                warnings.filterwarnings("ignore", message="Port .* is already in use")  # no dashboard is served
                cluster = LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address=None,
                    # the workers' own logs stay quiet: a member's failure is reported in its row, and
                    # a worker cut off by a Ctrl-C's teardown would log a heartbeat traceback
                    silence_logs=logging.CRITICAL,
                )
        finally:
            if previous is not None:
                signal.signal(signal.SIGINT, previous)
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        futures = client.map(run_member, configs, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for fut in as_completed(futures):
            i = index[fut.key]
            try:
                rec = fut.result()
            except Exception as err:  # the worker itself died: still a reported failure
                rec = _record(
                    {"status": "failed", "error": f"{type(err).__name__}: {err}"},
                    _read_summary(configs[i]),
                    time.perf_counter(),
                )
                rec["wall_s"] = math.nan
            finished(i, rec)
    except KeyboardInterrupt:
        _stop_members(configs)
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _write_csv(path: Path, table: list) -> Path:
    def write(f):
        w = csv.DictWriter(f, fieldnames=list(table[0]))
        w.writeheader()
        w.writerows(table)

    return atomic_write(path, write)


def to_dataset(table: list, keys: list, prov: Optional[dict] = None):
    """The table as an xarray.Dataset with one dimension per swept key (cartesian product)."""
    import xarray as xr  # deferred: optional dependency (the io extra)

    coords = {k: list(dict.fromkeys(row[k] for row in table)) for k in keys}
    shape = tuple(len(v) for v in coords.values())
    data = {}
    for name in ("member",) + RECORD_KEYS:
        values = [row[name] for row in table]
        numeric = name not in ("status", "stop_reason", "error")
        arr = np.array([np.nan if v is None else v for v in values], dtype=float if numeric else object)
        data[name] = (keys, arr.reshape(shape))
    ds = xr.Dataset(data, coords=coords)
    units = {"runout_m": "m", "t_end_s": "s", "wall_s": "s", "mass_rel_error": "1", "steps": "1"}
    for name, unit in units.items():
        ds[name].attrs["units"] = unit
    ds["runout_m"].attrs["long_name"] = "run-out: largest front position from the gate"
    ds["t_end_s"].attrs["long_name"] = "simulated time reached"
    for k in keys:
        ck = config_key(k)
        ds[k].attrs.update({"long_name": ck.doc, "units": ck.unit or "1"})
    ds.attrs.update({"title": "granrs sweep", "Conventions": "CF-1.10", **(prov or {})})
    return ds


def plot_runout(table: list, keys: list, path) -> Path:
    """Run-out against the first swept key, one line per combination of the others; failed
    members (stopped early: their run-out is a lower bound) are drawn as open markers."""
    import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after its backend is chosen

    first, rest = keys[0], keys[1:]
    groups: dict = {}
    for row in table:
        groups.setdefault(tuple(row[k] for k in rest), []).append(row)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for n, (combo, rows) in enumerate(groups.items()):
        rows = sorted(rows, key=lambda r: r[first])
        label = (
            ", ".join(f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}" for k, v in zip(rest, combo))
            or "run-out"
        )
        x = [r[first] for r in rows]
        y = [r["runout_m"] for r in rows]
        ok = [r["status"] == "ok" for r in rows]
        ax.plot(
            [a for a, o in zip(x, ok) if o],
            [b for b, o in zip(y, ok) if o],
            f"C{n}o-",
            label=label if any(ok) else None,
        )
        ax.plot(
            [a for a, o in zip(x, ok) if not o],
            [b for b, o in zip(y, ok) if not o],
            f"C{n}o",
            mfc="none",
            label=None if any(ok) else label,
        )
        for r, a, b, o in zip(rows, x, y, ok):
            if not o and math.isfinite(b):
                ax.annotate(
                    f"t={r['t_end_s']:.2f} s",
                    (a, b),
                    textcoords="offset points",
                    xytext=(4, 3),
                    fontsize=6,
                    color=f"C{n}",
                )
    ax.axhline(PAPER_RUNOUT_EXP, color="k", ls=":", lw=1.5, label=f"experiment: {PAPER_RUNOUT_EXP} m")
    ax.axhline(PAPER_RUNOUT_SIM, color="k", ls="--", lw=1, label=f"paper's simulation: {PAPER_RUNOUT_SIM} m")
    failed = sum(r["status"] != "ok" for r in table)
    xs = [r[first] for r in table if isinstance(r[first], (int, float))]
    if xs and min(xs) > 0 and max(xs) / min(xs) >= 10:
        ax.set_xscale("log")
    ax.set(
        xlabel=f"{first} ({config_key(first).unit_words})" if config_key(first).unit else first,
        ylabel="run-out from the gate (m)",
        title=f"sweep of {len(table)} members"
        + (
            f": {failed} stopped early\n(open markers: run-out at the time they stopped, a lower bound)"
            if failed
            else ""
        ),
    )
    ax.title.set_fontsize(9)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "member":
        sys.exit(_member_main(sys.argv[2]))
    sys.exit("usage: python -m granrs.sweep member DIR  (the member's configuration as JSON on stdin)")
