"""A run's output folder: checked before any work, written atomically and incrementally.

    plan = plan_output_dir("out/run", overwrite=False)     # checks only: nothing is created
    ...                                                    # every other check of the run
    outputs = RunOutputs(plan)                             # creates the folder (or clears a run)
    outputs.write_json("summary.json", summary)            # temporary file + rename
    outputs.write_columns("front.csv", {"t_s": [...], "front_m": [...]})

Folder rules (``plan_output_dir``): a run writes into a new or empty folder; into a folder that
already holds files only with ``overwrite=True`` (the previous run's outputs are then deleted,
after every check has passed) or, for a restart, ``append=True`` (the run continues its own
outputs: nothing is deleted, front.csv and history.npz keep the rows before the restart time).
A folder path that is empty, a file, inside /proc, /sys or /dev, under a file, or on a
read-only or full file system is a ``ParameterError`` naming it. Missing parent folders are
created.

Every file is written to ``<name>.tmp`` in the same folder and renamed over ``<name>``, so a
file on disk is always complete: a write that fails (a full disk) removes its temporary file,
keeps the previous version of the file and raises ``OutputError`` naming the file.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np

from .._granrs import ParameterError, SimulationError

#: The files and patterns a run writes into its folder (what ``overwrite`` deletes).
RUN_FILES = (
    "summary.json",
    "front.csv",
    "profiles.csv",
    "history.npz",
    "energy.csv",
    "config.resolved.toml",
    "config.restart-*.toml",
    "fields.pvd",
    "fields.nc",
    "animation.gif",
    "checkpoint.npz",
    "*.png",
    "fields/fields_*.vti",
    "*.tmp",
)
#: Free space below which a folder counts as full (bytes): one snapshot of a ny = 32 run is ~0.3 MB.
MIN_FREE_BYTES = 1 << 20
_VIRTUAL = ("/proc", "/sys", "/dev")


class OutputError(SimulationError):
    """A run's output could not be written (a full or failing disk): the run stops, the files
    written before stay complete on disk."""


@dataclass
class OutputPlan:
    """What ``plan_output_dir`` decided: ``path``, ``mode`` ('fresh', 'overwrite' or 'append')
    and the names already in the folder."""

    path: Path
    mode: str
    existing: list = field(default_factory=list)


def _bad(name: str, path, why: str, allowed: str = "a writable folder on a disk") -> ParameterError:
    return ParameterError(f"invalid parameter `{name}` = {str(path)!r}: {why}; allowed {allowed}")


def plan_output_dir(path, *, overwrite: bool = False, append: bool = False, name: str = "--out") -> OutputPlan:
    """Checks that ``path`` can hold a run's outputs (see the module docstring) without creating
    or changing anything; ``name`` is the parameter the errors name."""
    text = "" if path is None else str(path)
    if not text.strip():
        raise _bad(name, text, "an empty path", "a folder path")
    p = Path(text).expanduser()
    absolute = Path(os.path.abspath(p))
    for special in _VIRTUAL:
        if absolute == Path(special) or Path(special) in absolute.parents:
            raise _bad(name, p, f"it is inside {special}, a virtual file system")
    if p.exists() and not p.is_dir():
        raise _bad(name, p, "it is a file, not a folder")
    ancestor = absolute
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise _bad(name, p, f"its parent {str(ancestor)!r} is a file, not a folder")
    try:
        st = os.statvfs(ancestor)
    except OSError as err:
        raise _bad(name, p, f"{str(ancestor)!r} cannot be inspected ({err.strerror})") from None
    if st.f_flag & os.ST_RDONLY:
        raise _bad(name, p, f"{str(ancestor)!r} is on a read-only file system")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise _bad(name, p, f"{str(ancestor)!r} is not writable by this user")
    free = st.f_bavail * st.f_frsize
    if free < MIN_FREE_BYTES:
        raise _bad(
            name,
            p,
            f"the file system of {str(ancestor)!r} is full ({free} bytes free, fewer than {MIN_FREE_BYTES} bytes)",
            "a folder with at least 1 MiB free",
        )
    existing = sorted(e.name for e in p.iterdir()) if p.is_dir() else []
    if not existing:
        return OutputPlan(p, "fresh")
    if append:
        return OutputPlan(p, "append", existing)
    if overwrite:
        return OutputPlan(p, "overwrite", existing)
    shown = ", ".join(existing[:5]) + (", ..." if len(existing) > 5 else "")
    raise _bad(
        name,
        p,
        f"the folder is not empty (it holds {shown}); nothing was changed",
        "a new or empty folder, --overwrite to replace the run there, or --restart from its checkpoint.npz "
        "to continue it",
    )


def clear_run(path: Path) -> None:
    """Deletes the files a run writes (``RUN_FILES``) from ``path``; other files are kept."""
    for pattern in RUN_FILES:
        for f in path.glob(pattern):
            if f.is_file():
                f.unlink()


def commit_output_dir(plan: OutputPlan) -> Path:
    """Creates the planned folder (or clears the previous run with mode 'overwrite') and proves it
    writable with a probe file. Call only once every check of the run has passed."""
    p = plan.path
    try:
        p.mkdir(parents=True, exist_ok=True)
        if plan.mode == "overwrite":
            clear_run(p)
        probe = p / ".granrs-write-test.tmp"
        probe.write_bytes(b"granrs")
        probe.unlink()
    except OSError as err:
        raise ParameterError(
            f"invalid parameter `--out` = {str(p)!r}: cannot write there ({err.strerror}); allowed a "
            "writable folder on a disk"
        ) from None
    return p


def atomic_write(path, write: Callable, binary: bool = False) -> Path:
    """Calls ``write(file)`` on ``<path>.tmp`` and renames it over ``path``. On an OSError the
    temporary file is removed, ``path`` keeps its previous content and ``OutputError`` is raised."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        text: dict[str, Any] = {} if binary else {"newline": "", "encoding": "utf-8"}
        with open(tmp, "wb" if binary else "w", **text) as f:
            write(f)
        os.replace(tmp, path)
    except OSError as err:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        raise OutputError(
            f"cannot write {path} ({err.strerror or err}); the files written before are kept in {path.parent}"
        ) from None
    return path


def write_json(path, obj) -> Path:
    return atomic_write(path, lambda f: f.write(json.dumps(obj, indent=2) + "\n"))


def write_columns(path, columns: dict, prefix: Optional[dict] = None) -> Path:
    """A CSV file with one column per entry of ``columns`` (name → sequence of numbers, all the
    same length), values written with 6 significant digits; ``prefix``: rows (same column names)
    written first (a restart appending to its own run)."""
    names = list(columns)
    rows = list(zip(*columns.values())) if names else []

    def write(f):
        w = csv.writer(f)
        w.writerow(names)
        if prefix and list(prefix) == names:
            w.writerows(zip(*prefix.values()))
        w.writerows([f"{v:.6g}" for v in row] for row in rows)

    return atomic_write(path, write)


def read_columns(path) -> dict:
    """The columns of a CSV file written by ``write_columns`` (name → list of floats)."""
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        names = next(reader, [])
        data = [[float(v) for v in row] for row in reader if row]
    return {n: [row[k] for row in data] for k, n in enumerate(names)}


def write_npz(path, arrays: dict, prefix: Optional[dict] = None) -> Path:
    """``np.savez`` of ``arrays``, each preceded by ``prefix[name]`` when given."""
    if prefix:
        arrays = {
            k: np.concatenate([np.asarray(prefix[k]), np.asarray(v)]) if k in prefix else v for k, v in arrays.items()
        }
    return atomic_write(path, lambda f: np.savez(f, **arrays), binary=True)


class RunOutputs:
    """The output folder of one run (after ``commit_output_dir``): what a restart appends to
    (``front_prefix``, ``history_prefix``: the rows before its start) and where its mass balance
    starts (``start_area``: the dense area at the run's original start, None: the model's own)."""

    def __init__(
        self,
        path,
        front_prefix: Optional[dict] = None,
        history_prefix: Optional[dict] = None,
        start_area: Optional[float] = None,
    ):
        self.path = Path(path)
        self.front_prefix = front_prefix
        self.history_prefix = history_prefix
        self.start_area = start_area

    def write_json(self, name: str, obj) -> Path:
        return write_json(self.path / name, obj)

    def write_columns(self, name: str, columns: dict) -> Path:
        return write_columns(self.path / name, columns, self.front_prefix if name == "front.csv" else None)

    def write_history(self, arrays: dict) -> Path:
        return write_npz(self.path / "history.npz", arrays, self.history_prefix)


def resume_outputs(path: Path, t_start: float) -> tuple[Optional[dict], Optional[dict]]:
    """The front.csv rows and history.npz entries of a run in ``path`` before ``t_start`` (what a
    restart at ``t_start`` appends to); (None, None) where the files are missing or unreadable."""
    front = history = None
    try:
        cols = read_columns(path / "front.csv")
        keep = [k for k, t in enumerate(cols.get("t_s", [])) if t < t_start - 1e-12]
        front = {n: [v[k] for k in keep] for n, v in cols.items()}
    except (OSError, ValueError, StopIteration):
        front = None
    try:
        with np.load(path / "history.npz") as z:
            hist = {k: z[k] for k in z.files}
        if "time" in hist:
            keep = hist["time"] <= t_start * (1 + 1e-12)
            history = {k: v[keep] for k, v in hist.items() if v.shape == hist["time"].shape}
    except (OSError, ValueError, KeyError):
        history = None
    return front, history
