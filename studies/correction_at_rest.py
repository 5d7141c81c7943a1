"""Does the global mass correction move a deposit at rest? The same arrested state, continued with
and without it (and without the redistancing, with a tighter Picard tolerance, or with Φ moved by
the grains' velocity where they rest).

    python studies/correction_at_rest.py --ny 16 [--dry] [--t-end 3] [--out out/correction-at-rest]
        [--continuations with_correction without_correction without_redistancing without_either
         tighter_picard extended_at_rest extended_at_rest_without_correction]
        [--option mass_correction_film=0.5] [--continuation-option picard_tol=1e-5]

The column (``granrs.cases.column``) runs with the options of docs/howto/deposit-at-rest.md (20
proximal restarts, Anderson mixing of depth 5, redistancing at every step, detached pieces of at
most 4 cells turned to air), and any ``--option`` besides, until its rest criterion holds
(``RestCriterion``: the largest granular speed below ``rest.speed`` for ``rest.duration``). Its
whole state is then taken
(``Model.state``) and continued to ``--t-end`` from that same state, in
each of ``--continuations``: ``with_correction``, the run itself with the global mass correction
(``levelset::Interface::correct_mass``, a uniform shift of Φ); ``without_correction``,
``without_redistancing`` and ``without_either``, models built with ``mass_correction = False``,
``redistance_every = 0`` or both, into which the state is restored; ``tighter_picard``, a model
whose Picard tolerance (``picard_tol``) is the run's over ``TIGHTER`` (100);
``extended_at_rest`` and ``extended_at_rest_without_correction``, models whose level set is
moved by the dense phase's velocity extended along the normal where the grains move slower than
the column's rest speed (``interface_velocity = "extended"``, ``extension_rest_speed`` =
``RestCriterion().speed``, 5 mm/s), with and without the correction. Any
``--continuation-option`` applies to the continuations only (``with_correction`` is then
continued in a model built with it). The records every 0.01 s (at
the run's own times) give, for each continuation, the range of the front on the lowest row of
cells, its last value, the largest granular speed, and the speed in each layer of the granular
phase by depth below its surface (``DEPTH_LAYERS``: 0 < Φ ≤ h, the cells of the smoothed band and
of films one cell thick; h < Φ ≤ 2h; 2h < Φ ≤ 4h; Φ > 4h, the bulk), the largest over the
continuation and the largest at its last record, each with its cell, the correction's shifts (the sum of |δ| over the steps), the dense area's relative change,
and the largest change of the surface and of the volume profile since the restart, with the
column of the surface's, and the time from which the surface stays within ``STILL`` (1e-6 m) of
its last profile (``surface_still_from_s``; the last record's time if it moved until then);
and, at the end, the tip on the base (``tip_on_the_base``: the slip of the lowest row's last
granular cells, the share of its bound that the base's friction takes
there, and their trial norm). Writes ``OUT/<state>-<ny>.json`` and prints it. On one thread
(2-core VM, 2026-12-05, four runs sharing the two cores): the run to its arrest 6 s at ny = 16
and 20–28 s at ny = 32, each continuation 1–3 s and 2–6 s.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from granrs.cases.column import (
    ColumnCase,
    Fluidisation,
    RestCriterion,
    RestWatch,
    build_model,
    front_cell,
    front_position,
    granular_speed,
    surface_profile,
)
from granrs.config import parse_options
from granrs.observables import volume_profile

#: the options of docs/howto/deposit-at-rest.md
AT_REST = {"proximal_restarts": 20, "anderson_depth": 5, "redistance_every": 1, "piece_removal_cells": 4}
#: record interval (s), as the column's runs
EVERY = 0.01
#: a surface that changes by less than this is still (m): the 1e-6 m of a deposit at rest
STILL = 1e-6
#: the layers of the granular phase by depth below its surface, in cells of Φ: (name, Φ/h above,
#: Φ/h at most)
DEPTH_LAYERS = (("film", 0.0, 1.0), ("1-2", 1.0, 2.0), ("2-4", 2.0, 4.0), ("bulk", 4.0, math.inf))


def speeds_by_depth(phi: np.ndarray, speed: np.ndarray, h: float) -> dict:
    """The largest of ``speed`` (cell centres) over each layer of ``DEPTH_LAYERS`` of the cells
    with Φ > 0, with its cell (i, j); a layer without cells is left out."""
    out = {}
    for name, lo, hi in DEPTH_LAYERS:
        sel = (phi > lo * h) & (phi <= hi * h)
        if sel.any():
            k = int(np.argmax(np.where(sel, speed, -1.0)))
            j, i = divmod(k, phi.shape[1])
            out[name] = {"speed_m_s": float(speed[j, i]), "cell": [i, j]}
    return out


def run_to_rest(model, case: ColumnCase) -> float:
    """Advances ``model`` record by record until the column's rest criterion holds; returns the
    start of the quiet window (the run's ``arrest_time_s``). Refuses a run that does not come to
    rest by ``case.t_end``."""
    rest = RestWatch(case.rest)
    k = 0
    while model.time < case.t_end - 1e-12:
        k += 1
        model.advance(min(case.t_end, k * EVERY))
        if rest.update(model.time, granular_speed(model)):
            assert rest.since is not None
            return rest.since
    raise SystemExit(f"the column did not come to rest by t = {case.t_end} s: nothing to continue")


#: the cells of the lowest row behind the front that ``tip_on_the_base`` looks at
TIP_CELLS = 4


def tip_on_the_base(model) -> dict:
    """The last ``TIP_CELLS`` granular cells of the lowest row, up to the front's own
    (``front_cell``): the largest |u| on their
    x-faces (the slip along the base, which the Coulomb wall's friction s τ_b opposes), the
    largest share |s| of its bound that the friction takes on those faces (below 1: the face is
    stuck), the largest trial norm of the plastic projection in those cells (at most 1: rigid),
    and their Φ/h."""
    phi = np.asarray(model.phi)
    last = front_cell(phi)
    if last is None:
        return {}
    cells = np.arange(max(last - TIP_CELLS + 1, 0), last + 1)
    faces = np.arange(cells[0], last + 2)
    s, tau_b = (np.asarray(a) for a in model.wall_friction("bottom"))
    share = np.abs(s[faces])[tau_b[faces] > 0]
    return {
        "front_cell": last,
        "phi_over_h": [float(v) for v in phi[0, cells] / model.grid.dy],
        "slip_m_s": float(np.max(np.abs(np.asarray(model.u)[0, faces]))),
        "friction_share": float(share.max()) if share.size else 0.0,
        "trial_norm": float(np.max(np.asarray(model.trial_norm)[0, cells])),
    }


def continue_to(model, t_start: float, t_end: float, front0: float, area0: float, lc: float) -> dict:
    """Advances ``model`` from ``t_start`` to ``t_end``, one record every EVERY s."""
    g = model.grid
    t0 = time.perf_counter()
    fronts, speeds, shifts, layers, surfaces, times = [], [], 0.0, {}, [], []
    k = 0
    while model.time < t_end - 1e-12:
        k += 1
        log = model.advance(min(t_end, (round(t_start / EVERY) + k) * EVERY))  # the run's own record times
        shifts += float(sum(abs(d) for d in log["mass_shift"]))
        phi = np.asarray(model.phi)
        fronts.append(front_position(phi, g.dx) - lc)
        surfaces.append(surface_profile(phi, g.dy))
        times.append(model.time)
        uc, vc = model.centre_velocity()
        by_depth = speeds_by_depth(phi, np.hypot(uc, vc), g.dy)
        # the layers cover every cell with Φ > 0: their largest is granular_speed(model)
        speeds.append(max((r["speed_m_s"] for r in by_depth.values()), default=0.0))
        for name, r in by_depth.items():
            layer = layers.setdefault(name, {"largest_m_s": -1.0})
            if r["speed_m_s"] > layer["largest_m_s"]:
                layer.update(largest_m_s=r["speed_m_s"], largest_cell=r["cell"], largest_t_s=model.time)
            layer.update(end_m_s=r["speed_m_s"], end_cell=r["cell"], end_t_s=model.time)
    # the earliest record from which the surface stays within STILL of its last profile
    off = [float(np.max(np.abs(sp - surfaces[-1]))) for sp in surfaces]
    still = len(off) - next((i for i, d in enumerate(reversed(off)) if d > STILL), len(off))
    return {
        "surface_still_from_s": times[still],
        "front_end_m": fronts[-1],
        "front_range_cells": (max(fronts) - min(fronts)) / g.dx,
        "front_end_minus_arrest_cells": (fronts[-1] - front0) / g.dx,
        "granular_speed_max_m_s": max(speeds),
        "granular_speed_by_depth": layers,
        "tip_on_the_base_at_end": tip_on_the_base(model),
        "mass_shift_abs_sum_m": shifts,
        "area_rel_change": model.dense_area() / area0 - 1.0,
        "wall_s": time.perf_counter() - t0,
    }


#: ``tighter_picard`` divides the run's Picard tolerance by this
TIGHTER = 100.0
#: Φ moved by the dense phase's velocity extended where the grains move slower than the column's
#: rest speed
EXTENDED_AT_REST = {"interface_velocity": "extended", "extension_rest_speed": RestCriterion().speed}
#: the continuations from the arrested state: the run itself, and models built with these
#: options changed, into which the state is restored
CONTINUATIONS = {
    "with_correction": {},
    "without_correction": {"mass_correction": False},
    "without_redistancing": {"redistance_every": 0},
    "without_either": {"mass_correction": False, "redistance_every": 0},
    "extended_at_rest": EXTENDED_AT_REST,
    "extended_at_rest_without_correction": {**EXTENDED_AT_REST, "mass_correction": False},
    "tighter_picard": {},  # picard_tol: the run's over TIGHTER (set in main)
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ny", type=int, default=16)
    ap.add_argument("--dry", action="store_true")
    ap.add_argument("--t-end", type=float, default=3.0, help="end of the continuations (s)")
    ap.add_argument(
        "--continuations",
        nargs="+",
        default=["with_correction", "without_correction"],
        choices=list(CONTINUATIONS),
        help="what to continue the arrested state with (with_correction: the run itself)",
    )
    ap.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a model option of the run besides the four (a schema key of `granrs keys`), e.g. "
        "--option mass_correction_film=0.5 (repeat)",
    )
    ap.add_argument(
        "--continuation-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a model option of the continuations only, after the arrest (repeat); "
        "with_correction is then continued in a model built with it",
    )
    ap.add_argument("--out", default="out/correction-at-rest")
    args = ap.parse_args()
    case = ColumnCase(ny=args.ny, fluidisation=Fluidisation(fluidised=not args.dry))
    run_options = {**AT_REST, **parse_options(args.option)}
    after = parse_options(args.continuation_option, flag="--continuation-option")
    run_case = case.with_options(**run_options)
    tighter = {"picard_tol": run_case.rheology.projection.tolerance / TIGHTER}
    cases = {
        name: case.with_options(
            **{**run_options, **after, **CONTINUATIONS[name], **(tighter if name == "tighter_picard" else {})}
        )
        for name in args.continuations
    }  # checked first
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    model = build_model(run_case)
    g, lc = model.grid, case.geometry.width
    arrest = run_to_rest(model, run_case)
    t_restart = model.time
    state = model.state()
    phi0 = np.array(model.phi)
    front0, area0 = front_position(phi0, g.dx) - lc, model.dense_area()
    surface0, volume0 = surface_profile(phi0, g.dy), volume_profile(phi0, g.dy)

    result = {"ny": args.ny, "state": "dry" if args.dry else "fluidised", "cell_m": g.dx, "options": run_options}
    result["continuation_options"] = after
    result.update({"arrest_time_s": arrest, "restart_time_s": t_restart, "front_at_restart_m": front0})
    for name in args.continuations:
        if name == "with_correction" and not after:
            m = model  # the run itself, continued
        else:
            m = build_model(cases[name])
            m.restore(state)
        r = continue_to(m, t_restart, args.t_end, front0, area0, lc)
        phi = np.array(m.phi)
        ds = np.abs(surface_profile(phi, g.dy) - surface0)
        r["surface_change_m"] = float(np.max(ds))
        r["surface_change_column"] = int(np.argmax(ds))
        r["volume_change_m"] = float(np.max(np.abs(volume_profile(phi, g.dy) - volume0)))
        result[name] = r
    path = out / f"{result['state']}-{args.ny}.json"
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
