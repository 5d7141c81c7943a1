"""A run's output folder: checked before any work, locked, written atomically and recorded.

    plan = plan_output_dir("out/run", overwrite=False)     # checks only: nothing is created
    ...                                                    # every other check of the run
    commit_output_dir(plan)                                # the folder, its lock, its manifest
    outputs = RunOutputs(plan.path)
    outputs.write_json("summary.json", summary)            # temporary file + rename, recorded
    release_output_dir(plan.path)                          # the lock removed (the run's end)

Folder rules (``plan_output_dir``): a run writes into a new or empty folder; into a folder that
already holds files only with ``overwrite=True`` or, for a restart, ``append=True`` (the run
continues its own outputs: nothing is deleted, front.csv and history.npz keep the rows before the
restart time). A folder path that is empty, a file, inside /proc, /sys or /dev, under a file,
too long for its file system, holding a control character, or on a read-only or full file
system is a ``ParameterError`` naming it. Missing parent folders are created.

The manifest (``granrs-manifest.txt``): every file and folder a run writes is recorded there,
one relative path a line, before it is written. ``overwrite`` removes exactly the manifest's
files (and their ``.tmp`` siblings) and then the manifest's folders left empty; it never
follows a symbolic link, and it refuses, before anything is changed, a folder without a manifest
(naming a file that is not granrs's), a manifest's entry that became a symbolic link, and a file
the manifest does not list where the run would write (its name is one a run writes). Files the
manifest does not list are never touched.

The lock (``granrs.lock``): the folder is locked (an exclusive ``flock`` on the lock file, which
holds the process id, host, start time and command line) before the first write and unlocked at
the run's end. A second run into a locked folder is refused, naming the folder and the process
that holds it. A lock whose process is gone (a run killed with ``kill -9``) is stale: a fresh run
is refused naming it, ``overwrite`` and a restart of the folder's own run clear it and say so.

Every file is written to ``<name>.tmp`` in the same folder and renamed over ``<name>``, so a
file on disk is always complete: a write that fails (a full disk) removes its temporary file,
keeps the previous version of the file and raises ``OutputError`` naming the file.
"""

from __future__ import annotations

import csv
import datetime as _dt
import errno
import fcntl
import fnmatch
import json
import os
import socket
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any, Optional

import numpy as np

from .._granrs import ParameterError, SimulationError
from .provenance import command_line

#: The manifest of an output folder: the relative paths of what its runs wrote, one a line.
MANIFEST = "granrs-manifest.txt"
#: The lock file of an output folder while a run writes there.
LOCK = "granrs.lock"
_MANIFEST_HEADER = (
    "# granrs manifest: the files and folders (ending in /) that granrs runs wrote in this folder, "
    "one relative path a line; granrs run --overwrite removes exactly these\n"
)
#: The names a run or a sweep writes in its folder (fnmatch patterns of relative paths): a file of
#: one of these names that the manifest does not list stops ``overwrite`` and ``append``.
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
    "front.png",
    "profiles.png",
    "energy.png",
    "fluidisation.png",
    "cavity.png",
    "fields",
    "fields/fields_*.vti",
    "sweep.csv",
    "sweep.nc",
    "sweep_runout.png",
    "member-*",
)
#: The longest path a run writes below its folder (a snapshot's temporary file in a sweep member).
LONGEST_INSIDE = "member-000000/fields/fields_000000.vti.tmp"
#: Free space below which a folder counts as full (bytes): one snapshot of a ny = 32 run is ~0.3 MB.
MIN_FREE_BYTES = 1 << 20
_VIRTUAL = ("/proc", "/sys", "/dev")


class OutputError(SimulationError):
    """A run's output could not be written (a full or failing disk): the run stops, the files
    written before stay complete on disk."""


def control_character(text: str) -> Optional[str]:
    """A description of the first control character in ``text`` ('newline at offset 9'), or None."""
    names = {"\n": "newline", "\r": "carriage return", "\t": "tab", "\x1b": "escape"}
    for k, ch in enumerate(text):
        if ord(ch) < 32 or 127 <= ord(ch) < 160 or ch in "\u2028\u2029":
            return f"{names.get(ch, f'control character U+{ord(ch):04X}')} at offset {k}"
    return None


def check_path_text(name: str, path) -> None:
    """ParameterError naming ``name`` when ``path`` holds a control character (a newline would
    break the provenance and the files that record the path)."""
    bad = control_character(str(path))
    if bad is not None:
        raise ParameterError(
            f"invalid parameter `{name}` = {str(path)!r}: it holds a {bad}; allowed a path without control characters"
        )


def check_path_length(name: str, path, inside: str = "") -> None:
    """ParameterError naming ``name`` when ``path`` (with ``inside``, the longest path a run
    writes below it) is too long for the file system that would hold it: a component longer than
    its NAME_MAX, or the whole longer than its PATH_MAX."""
    absolute = Path(os.path.abspath(Path(str(path)).expanduser()))
    name_max, path_max = 255, 4096
    ancestor = absolute
    try:
        while not ancestor.exists() and ancestor != ancestor.parent:
            ancestor = ancestor.parent
        probe = ancestor if ancestor.is_dir() else ancestor.parent
        name_max = os.pathconf(probe, "PC_NAME_MAX")
        path_max = os.pathconf(probe, "PC_PATH_MAX")
    except (OSError, ValueError):
        pass  # a name too long to look up: the defaults of Linux file systems judge it below
    full = absolute / inside if inside else absolute
    for part in full.parts:
        if len(os.fsencode(part)) > name_max:
            raise ParameterError(
                f"invalid parameter `{name}` = {str(path)!r}: too long for the file system: the name "
                f"{part[:40]!r}... has {len(os.fsencode(part))} bytes, more than its {name_max}; allowed "
                f"names of at most {name_max} bytes"
            )
    if len(os.fsencode(str(full))) >= path_max:
        raise ParameterError(
            f"invalid parameter `{name}` = {str(path)[:60]!r}...: too long for the file system: "
            f"{len(os.fsencode(str(full)))} bytes with the files written inside, more than its "
            f"{path_max}; allowed a shorter path"
        )


# ---- the manifest --------------------------------------------------------------------------------
def _safe_relative(line: str) -> Optional[str]:
    """A manifest line as a relative path inside the folder ('fields/' for a folder), or None for
    a comment, a blank line or a path that would leave the folder (absolute, '..')."""
    text = line.rstrip("\n")
    if not text or text.startswith("#"):
        return None
    p = PurePosixPath(text)
    if p.is_absolute() or ".." in p.parts or not p.parts:
        return None
    return str(p) + ("/" if text.endswith("/") else "")


def read_manifest(folder) -> Optional[set]:
    """The relative paths a folder's manifest lists (folders end in '/'), None without one."""
    path = Path(folder) / MANIFEST
    if path.is_symlink() or not path.is_file():
        return None
    with open(path, encoding="utf-8", errors="replace") as f:
        return {r for r in map(_safe_relative, f) if r is not None}


class Manifest:
    """The manifest of one output folder while a run writes there: ``add(path)`` records a path
    (and the folders above it inside the folder) before it is written."""

    def __init__(self, folder: Path, names: Optional[set] = None):
        self.folder = Path(os.path.abspath(folder))
        self.names: set = set(names or ())
        self.path = self.folder / MANIFEST
        if not self.path.is_file() or self.path.is_symlink():
            self._append([], header=True)

    def _append(self, lines: list, header: bool = False) -> None:
        try:
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o644)
            with open(fd, "a", encoding="utf-8") as f:
                if header:
                    f.write(_MANIFEST_HEADER)
                f.writelines(line + "\n" for line in lines)
        except OSError as err:
            raise OutputError(
                f"cannot write {self.path} ({err.strerror or err}); the files written before are kept in {self.folder}"
            ) from None

    def add(self, path, folder: bool = False) -> None:
        rel = os.path.relpath(os.path.abspath(path), self.folder)
        if rel == "." or rel.startswith(".."):
            return
        parts = PurePosixPath(*Path(rel).parts).parts
        new = []
        for k in range(1, len(parts)):
            d = "/".join(parts[:k]) + "/"
            if d not in self.names:
                new.append(d)
        last = "/".join(parts) + ("/" if folder else "")
        if last not in self.names:
            new.append(last)
        if new:
            self._append(new)
            self.names.update(new)


#: The manifests of the folders this process writes into (absolute path → Manifest).
_MANIFESTS: dict[str, Manifest] = {}


def open_manifest(folder) -> Manifest:
    """The manifest of ``folder`` for this process's writes (created, or continued with its lines)."""
    key = os.path.abspath(folder)
    if key not in _MANIFESTS:
        _MANIFESTS[key] = Manifest(Path(key), read_manifest(key))
    return _MANIFESTS[key]


def close_manifest(folder) -> None:
    _MANIFESTS.pop(os.path.abspath(folder), None)


def record(path, folder: bool = False) -> None:
    """Records ``path`` in the manifest of the output folder it lies in (nothing outside one)."""
    if not _MANIFESTS:
        return
    p = os.path.abspath(path)
    d = p if folder else os.path.dirname(p)
    while True:
        m = _MANIFESTS.get(d)
        if m is not None:
            m.add(p, folder=folder)
            return
        parent = os.path.dirname(d)
        if parent == d:
            return
        d = parent


def _matches_run_file(rel: str) -> bool:
    rel = rel.rstrip("/")
    base = rel[: -len(".tmp")] if rel.endswith(".tmp") else rel
    return any(fnmatch.fnmatchcase(base, pattern) for pattern in RUN_FILES)


def _survey(folder: Path, owned: Optional[set], prefix: str = "") -> tuple[list, list]:
    """(owned files, foreign entries) below ``folder``, walked without following a symbolic
    link: an entry is owned when ``owned`` (the manifest's paths) lists it, or it is the
    ``.tmp`` sibling of a listed file, the manifest or the lock; a folder is descended only when
    listed (a listed folder holding a manifest of its own, a sweep's member, by that one)."""
    files: list[str] = []
    foreign: list[tuple[str, str]] = []
    try:
        entries = sorted(os.scandir(folder), key=lambda e: e.name)
    except OSError:
        return files, foreign
    for e in entries:
        rel = prefix + e.name
        if not prefix and e.name in (MANIFEST, LOCK):
            continue
        if e.is_symlink():
            foreign.append((rel, f"a symbolic link to {os.readlink(e.path)!r}, which granrs does not make"))
            continue
        if e.is_dir():
            if owned is not None and rel + "/" in owned:
                inner = read_manifest(e.path)
                if inner is not None:
                    sub_files, sub_foreign = _survey(Path(e.path), inner)
                    files += [rel + "/" + f for f in sub_files] + [rel + "/" + n for n in (MANIFEST, LOCK)]
                    foreign += [(rel + "/" + f, why) for f, why in sub_foreign]
                else:
                    sub_files, sub_foreign = _survey(Path(e.path), owned, rel + "/")
                    files += sub_files
                    foreign += sub_foreign
            else:
                foreign.append((rel + "/", "a folder that no granrs run recorded"))
            continue
        listed = owned is not None and (rel in owned or (rel.endswith(".tmp") and rel[:-4] in owned))
        if listed:
            files.append(rel)
        else:
            foreign.append((rel, "a file that no granrs run recorded"))
    return files, foreign


# ---- the lock ------------------------------------------------------------------------------------
def lock_holder(folder) -> Optional[tuple[str, dict]]:
    """('held', info) when a live process holds the folder's lock, ('stale', info) when the lock
    file is there but its process is gone, None without a lock file. ``info``: pid, host,
    started, command (as far as the file could be read)."""
    path = Path(folder) / LOCK
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except FileNotFoundError:
        return None
    except OSError:
        return "held", {}
    try:
        try:
            info = json.loads(os.read(fd, 65536).decode("utf-8", "replace") or "{}")
        except ValueError:
            info = {}
        info = info if isinstance(info, dict) else {}
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError as err:
            if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                return "held", info
            raise
        fcntl.flock(fd, fcntl.LOCK_UN)
        return "stale", info
    finally:
        os.close(fd)


def _holder_words(info: dict) -> str:
    pid = info.get("pid", "?")
    host = info.get("host")
    where = f" on {host}" if host and host != socket.gethostname() else ""
    started = f", started {info['started']}" if info.get("started") else ""
    command = f": {info['command']}" if info.get("command") else ""
    return f"process {pid}{where}{started}{command}"


#: The locks this process holds (absolute folder path → file descriptor).
_LOCKS: dict[str, int] = {}


def _acquire_lock(folder: Path, name: str, command: Optional[str]) -> None:
    path = folder / LOCK
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
    except FileExistsError:
        state = lock_holder(folder)
        raise _bad(
            name,
            folder,
            f"another granrs run writes there: the folder is locked by {_holder_words(state[1] if state else {})}"
            "; nothing was changed",
            "one run per folder: wait for it to end, or another --out",
        ) from None
    except OSError as err:
        raise _bad(name, folder, f"cannot write there ({err.strerror})") from None
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    info = {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "command": command if command is not None else command_line(),
    }
    os.write(fd, (json.dumps(info) + "\n").encode("utf-8"))
    _LOCKS[os.path.abspath(folder)] = fd


def lock_output_dir(folder, name: str = "dir", command: Optional[str] = None) -> None:
    """Locks an existing output folder for a write into the run there (``granrs animate``): a
    folder another run writes into is refused (``ParameterError`` naming ``name``); a stale lock
    is cleared; the folder's manifest, where it has one, records what is written.
    ``release_output_dir`` ends it."""
    folder = Path(folder)
    check_path_text(name, folder)
    holder = lock_holder(folder)
    if holder is not None and holder[0] == "held":
        raise _bad(
            name,
            folder,
            f"another granrs run writes there: the folder is locked by {_holder_words(holder[1])}; nothing was changed",
            "a folder no run writes into",
        )
    if holder is not None:
        (folder / LOCK).unlink(missing_ok=True)
    _acquire_lock(folder, name, command)
    if read_manifest(folder) is not None:
        open_manifest(folder)


def release_output_dir(folder) -> None:
    """Ends this process's writing into ``folder``: its manifest closed, its lock removed."""
    key = os.path.abspath(folder)
    close_manifest(key)
    fd = _LOCKS.pop(key, None)
    if fd is None:
        return
    try:
        os.unlink(os.path.join(key, LOCK))
    except OSError:
        pass
    os.close(fd)


# ---- planning and committing a folder ------------------------------------------------------------
@dataclass
class OutputPlan:
    """What ``plan_output_dir`` decided: ``path``, ``mode`` ('fresh', 'overwrite' or 'append'),
    the names already in the folder, the files ``overwrite`` removes (``owned``, relative) and a
    stale lock to clear (``stale``, its holder); ``notes``: what ``commit_output_dir`` did that the
    user should hear of (one line each)."""

    path: Path
    mode: str
    existing: list = field(default_factory=list)
    name: str = "--out"
    owned: list = field(default_factory=list)
    stale: Optional[dict] = None
    notes: list = field(default_factory=list)


def _bad(name: str, path, why: str, allowed: str = "a writable folder on a disk") -> ParameterError:
    return ParameterError(f"invalid parameter `{name}` = {str(path)!r}: {why}; allowed {allowed}")


def plan_output_dir(
    path, *, overwrite: bool = False, append: bool = False, name: str = "--out", _locked: bool = False
) -> OutputPlan:
    """Checks that ``path`` can hold a run's outputs (see the module docstring) without creating
    or changing anything; ``name`` is the parameter the errors name."""
    text = "" if path is None else str(path)
    if not text.strip():
        raise _bad(name, text, "an empty path", "a folder path")
    check_path_text(name, text)
    check_path_length(name, text, LONGEST_INSIDE)
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
    if not p.is_dir():
        return OutputPlan(p, "fresh", name=name)
    for own in (MANIFEST, LOCK):
        if (p / own).is_symlink():
            raise _bad(
                name,
                p,
                f"its {own} is a symbolic link (to {os.readlink(p / own)!r}), which granrs does not make; nothing "
                "was changed",
                f"a folder whose {own} is granrs's own file",
            )
    stale = None
    holder = None if _locked else lock_holder(p)
    if holder is not None and holder[0] == "held":
        raise _bad(
            name,
            p,
            f"another granrs run writes there: the folder is locked by {_holder_words(holder[1])}; nothing was changed",
            "one run per folder: wait for it to end, or another --out",
        )
    if holder is not None:
        if not (overwrite or append):
            raise _bad(
                name,
                p,
                f"it holds the stale lock {LOCK} of {_holder_words(holder[1])}, which is no longer running (a run "
                "stopped before its end); nothing was changed",
                "--overwrite to clear it and replace that run, --restart from its checkpoint.npz to continue it, "
                "or another --out",
            )
        stale = holder[1]
    existing = sorted(e.name for e in p.iterdir() if e.name not in (LOCK, MANIFEST))
    if not existing:
        return OutputPlan(p, "fresh", name=name, stale=stale)
    owned = read_manifest(p)
    files, foreign = _survey(p, owned)
    clobber = [(rel, why) for rel, why in foreign if _matches_run_file(rel)]
    if overwrite or append:
        if owned is None and overwrite:
            rel, why = foreign[0]
            raise _bad(
                name,
                p,
                f"the folder holds {rel!r}, {why}: it has no {MANIFEST}, the list of what a granrs run wrote "
                "there, so --overwrite would remove nothing that is known to be granrs's; nothing was changed",
                "a new or empty folder, or the folder of a granrs run (--overwrite removes exactly the files its "
                f"{MANIFEST} lists)",
            )
        if clobber:
            rel, why = clobber[0]
            raise _bad(
                name,
                p,
                f"the folder holds {rel!r}, {why}, where the run would write; nothing was changed",
                f"a folder whose {MANIFEST} lists every file of a run's names there (move {rel!r} away)",
            )
        return OutputPlan(p, "append" if append else "overwrite", existing, name, files, stale)
    shown = ", ".join(existing[:5]) + (", ..." if len(existing) > 5 else "")
    raise _bad(
        name,
        p,
        f"the folder is not empty (it holds {shown}); nothing was changed",
        "a new or empty folder, --overwrite to replace the run there, or --restart from its checkpoint.npz "
        "to continue it",
    )


def _remove_owned(folder: Path, files: list) -> None:
    """Removes the listed files (relative paths) of ``folder`` that are still regular files
    reached through real folders, then the folders they were in that are left empty."""
    folders: set = set()
    for rel in files:
        parts = PurePosixPath(rel).parts
        d, real = folder, True
        for part in parts[:-1]:
            d = d / part
            if d.is_symlink() or not d.is_dir():
                real = False
                break
            folders.add(d)
        if not real:
            continue
        target = folder.joinpath(*parts)
        try:
            if target.is_symlink() or not target.is_file():
                continue
            target.unlink()
        except FileNotFoundError:
            continue
    for d in sorted(folders, key=lambda x: len(x.parts), reverse=True):
        try:
            if not d.is_symlink():
                d.rmdir()
        except OSError:
            pass  # not empty: it holds files that are not granrs's


def commit_output_dir(plan: OutputPlan, command: Optional[str] = None) -> Path:
    """Creates the planned folder, locks it, clears a stale lock and, with mode 'overwrite',
    removes the files of its manifest (checked again under the lock), then opens its manifest.
    Call only once every check of the run has passed; ``release_output_dir`` ends it."""
    p, name = plan.path, plan.name
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise _bad(name, p, f"cannot write there ({err.strerror})") from None
    if plan.stale is not None:
        holder = lock_holder(p)
        if holder is not None and holder[0] == "stale":
            (p / LOCK).unlink(missing_ok=True)
            plan.notes.append(f"cleared the stale lock of {_holder_words(holder[1])}, no longer running, in {str(p)!r}")
    _acquire_lock(p, name, command)
    try:
        # under the lock: what another run may have written since the plan counts
        again = plan_output_dir(
            p, overwrite=plan.mode == "overwrite", append=plan.mode == "append", name=name, _locked=True
        )
        if again.mode == "overwrite":
            try:
                _remove_owned(p, again.owned)
                (p / MANIFEST).unlink(missing_ok=True)
            except OSError as err:
                raise OutputError(f"cannot remove the previous run's files in {p} ({err.strerror or err})") from None
        open_manifest(p)
    except BaseException:
        release_output_dir(p)
        raise
    return p


def atomic_write(path, write: Callable, binary: bool = False) -> Path:
    """Calls ``write(file)`` on ``<path>.tmp`` and renames it over ``path``. On an OSError the
    temporary file is removed, ``path`` keeps its previous content and ``OutputError`` is raised."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    record(path)
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
