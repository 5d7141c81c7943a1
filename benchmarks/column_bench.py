"""The column model the step benchmarks time (stage_profile.py, step_cost.py, thread_curve.py):
built from their common command-line arguments and advanced past its first steps, and the digest
of its state that they compare between builds or thread counts.

granrs is imported inside the function, so that step_cost.py's worker times the build its
environment names (its ``--base``)."""

from __future__ import annotations

import argparse


def warm_column_model(args: argparse.Namespace):
    """The column's Rust model of ``args`` (ny, threads, model, dry, active_region, sides, and
    ``option``: KEY=VALUE model options by their schema keys),
    restored from ``args.restart`` (a run's checkpoint.npz of the same case, if given: the
    steps then start at a late state of the collapse, with its larger window and iteration
    counts), or advanced to ``args.at_time`` (a checkpoint of that state is kept in
    ``args.cache`` and restored by the next call with the same case and time), then advanced by
    ``args.warmup`` steps. Refuses a debug build."""
    import granrs
    from granrs import ActiveRegion
    from granrs.cases.column import ColumnCase, Fluidisation, build_model

    if granrs.build_info()["profile"] != "release":
        raise SystemExit("benchmarks need a release build (make install builds one)")
    from granrs.config import parse_options

    kw = dict(ny=args.ny, threads=args.threads, model=args.model, fluidised=not args.dry)
    if args.active_region is not None:
        kw.update(active_region=ActiveRegion(args.active_region, sides=args.sides))
    options = parse_options(getattr(args, "option", None) or [])
    scene = {k: v for k, v in kw.items() if k != "fluidised"}
    m = build_model(ColumnCase(fluidisation=Fluidisation(kw["fluidised"]), **scene).with_options(**options))
    kw.update(options)  # the cache's name holds them
    if getattr(args, "restart", None):
        from granrs.io import restore_checkpoint

        restore_checkpoint(m, args.restart)
    elif getattr(args, "at_time", None):
        at_time(m, kw, args)
    m.advance(max_steps=args.warmup)
    return m


def state_digest(m) -> str:
    """The first 16 hex digits of the SHA-256 of u, v, p, Φ and (where the model has it) p_f:
    equal digests mean the same state bit for bit."""
    import hashlib

    import numpy as np

    h = hashlib.sha256()
    for name in ("u", "v", "p", "phi", "pf"):
        try:
            a = getattr(m, name)
        except Exception:  # a field this model does not have (p_f of a dry column)
            continue
        if a is not None:
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def at_time(m, kw: dict, args: argparse.Namespace) -> None:
    """Advances ``m`` to ``args.at_time`` s, or restores it there from the checkpoint that an
    earlier call left in ``args.cache`` (a folder; none: always advance). The checkpoint's name
    holds the case's settings and the time; the thread count does not change the state."""
    from pathlib import Path

    from granrs.io import restore_checkpoint, save_checkpoint

    key = "_".join(f"{k}-{v.band if k == 'active_region' else v}" for k, v in sorted(kw.items()) if k != "threads")
    if "active_region" in kw:
        key += f"-{kw['active_region'].sides}"
    path = Path(args.cache) / f"column_{key}_t{args.at_time:g}.npz" if getattr(args, "cache", None) else None
    if path is not None and path.exists():
        restore_checkpoint(m, path)
        return
    m.advance(t_end=args.at_time)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        save_checkpoint(m, path)
        # start from the file as every later call does: a restored model may differ from the one
        # that wrote it by the sign of zeros outside an active window, which the digest sees
        restore_checkpoint(m, path)
