"""Checkpoint and restart: the whole model state in one .npz file, with metadata.

The Rust core owns the state (fields, the BDF2 history, the plastic tensor, the clock), so the
export is its job, through this interface (not yet in the core; see docs/ecosystem.md):

    model._rust.checkpoint_state() -> dict[str, numpy.ndarray | float | int]
    model._rust.restore_state(state: dict) -> None     # same keys and shapes as exported

File format (``.npz``, format "granrs-checkpoint" version 1):
  ``state/<name>``   each array of ``checkpoint_state()``, unchanged (dtype and shape);
  ``fields/<name>``  the public cell-centred fields (``granrs.io.fields.snapshot``), for inspection;
  ``meta``           a 0-d string array holding JSON: format, format_version, time, step_count,
                     grid (nx, ny, lx, ly), scalars (the float/int entries of the state, exact
                     through JSON's shortest round-trip repr) and provenance (granrs version, git
                     revision, command line, resolved configuration).
The file is written to ``<path>.tmp`` and renamed, so a checkpoint on disk is always complete.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from .._granrs import ParameterError
from .fields import snapshot
from .outputs import atomic_write

FORMAT, FORMAT_VERSION = "granrs-checkpoint", 1


@dataclass
class Checkpoint:
    meta: dict
    state: dict
    fields: dict


def save_checkpoint(model, path, provenance: Optional[dict] = None) -> Path:
    """Writes the model's state to ``path`` (.npz)."""
    path = Path(path)
    state = model._rust.checkpoint_state()
    arrays = {f"state/{k}": np.asarray(v) for k, v in state.items() if isinstance(v, np.ndarray)}
    scalars = {k: v for k, v in state.items() if not isinstance(v, np.ndarray)}
    for k, v in scalars.items():
        if not isinstance(v, (bool, int, float)):
            raise ParameterError(f"invalid checkpoint state entry `{k}` = {v!r}: allowed an array, float or int")
    arrays.update({f"fields/{k}": v for k, v in snapshot(model).items()})
    g = model.grid
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "time": model.time,
        "step_count": model.step_count,
        "grid": {"nx": g.nx, "ny": g.ny, "lx": g.lx, "ly": g.ly},
        "scalars": scalars,
        "scalar_types": {k: type(v).__name__ for k, v in scalars.items()},
        "provenance": provenance or {},
    }
    # numpy's stub lets **kwargs reach savez's allow_pickle flag: the keys here are field names
    return atomic_write(
        path,
        lambda f: np.savez(f, meta=np.array(json.dumps(meta)), **arrays),  # type: ignore[arg-type]
        binary=True,
    )


def load_checkpoint(path) -> Checkpoint:
    """Reads a checkpoint file (no model needed). A file that is missing, empty, truncated,
    corrupted, of another format or holding non-finite values is a ParameterError naming it."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as err:
        raise ParameterError(
            f"invalid checkpoint `{path}`: cannot be read ({err.strerror}); allowed a checkpoint.npz written by granrs"
        ) from None
    if size == 0:
        raise ParameterError(
            f"invalid checkpoint `{path}`: the file is empty; allowed a checkpoint.npz written by granrs"
        )
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"][()]))
            arrays = {k: z[k] for k in z.files if k != "meta"}
        casts = {"bool": bool, "int": int, "float": float}
        if meta.get("format") == FORMAT and meta.get("format_version") == FORMAT_VERSION:
            scalars = {k: casts[meta["scalar_types"][k]](v) for k, v in meta["scalars"].items()}
    except Exception as err:  # noqa: BLE001 - zipfile, zlib, EOF, JSON, KeyError...: all "not a checkpoint"
        raise ParameterError(
            f"invalid checkpoint `{path}`: truncated or corrupted, cannot be read as a granrs checkpoint "
            f"({type(err).__name__}: {err}); allowed a checkpoint.npz written by granrs"
        ) from None
    if meta.get("format") != FORMAT or meta.get("format_version") != FORMAT_VERSION:
        raise ParameterError(
            f"invalid checkpoint `{path}`: allowed format {FORMAT} version {FORMAT_VERSION}, "
            f"found {meta.get('format')} version {meta.get('format_version')}"
        )
    state = {k[len("state/") :]: v for k, v in arrays.items() if k.startswith("state/")}
    for name, v in state.items():
        finite = np.isfinite(v) if v.dtype.kind == "f" else np.ones(v.shape, bool)
        if name == "dt_prev":  # NaN: no step before the checkpoint (the core's encoding of None)
            finite = finite | np.isnan(v)
        if not np.all(finite):
            k = int(np.argmin(finite.ravel()))
            raise ParameterError(
                f"invalid checkpoint `{path}`: entry `{name}` holds a non-finite value "
                f"({float(v.ravel()[k])!r} at index {k}); allowed finite numbers"
            )
    state.update(scalars)
    fields = {k[len("fields/") :]: v for k, v in arrays.items() if k.startswith("fields/")}
    return Checkpoint(meta, state, fields)


def restore_checkpoint(model, checkpoint) -> Checkpoint:
    """Restores ``model`` (built from the same configuration) from a checkpoint file or object."""
    ck = checkpoint if isinstance(checkpoint, Checkpoint) else load_checkpoint(checkpoint)
    g, want = model.grid, ck.meta["grid"]
    if (g.nx, g.ny) != (want["nx"], want["ny"]) or not np.allclose((g.lx, g.ly), (want["lx"], want["ly"]), rtol=1e-12):
        raise ParameterError(
            f"invalid checkpoint: its grid {want} differs from the model's (nx={g.nx}, ny={g.ny}, lx={g.lx}, ly={g.ly})"
        )
    try:
        model._rust.restore_state(dict(ck.state))
    except ParameterError as err:
        raise ParameterError(
            f"invalid checkpoint `{checkpoint if not isinstance(checkpoint, Checkpoint) else 'object'}`: {err}"
        ) from None
    return ck
