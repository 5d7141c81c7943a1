"""How still is a deposit once the column has come to rest? The column run past its rest
criterion to ``--t-end``, its volume profile and fronts recorded every 0.01 s.

    python studies/deposit_at_rest.py --ny 32 [--dry] [--solver newton]
        [--interface-transport clsvof] [--interface-yield density-support] [--t-end 3]
        [--out out/deposit-at-rest]

The column of the run files (``granrs.config.resolve`` with the options given; without
``--interface-transport level-set`` the interface is ``clsvof`` without the global mass
correction) is stepped by ``Model.advance`` to each record. The arrest is the time its rest
criterion (``RestCriterion``: the granular speed, :func:`granrs.cases.column.granular_speed`,
below ``rest.speed`` for ``rest.duration`` after ``rest.after``) first holds; a run would stop
there. From the arrest to ``--t-end`` the study reports the largest change of the volume
profile h_i (``granrs.observables.model_volume_profile``: Σ_j F_ij δy with the volume fraction),
the largest granular speed, and how far the lowest-row front (the end of the cells of the lowest
row with F > ``VOLUME_FRACTION_MIN``, or Φ > 0 with the level set) and the 1 mm front
(``granrs.observables.thickness_front``) lie behind their largest values over the whole run, in
cells, and the dense volume's relative change over the run (``Model.dense_volume``, with
``clsvof``). Writes ``OUT/<dry|fluidised>-<ny>-<yield>.json`` and prints it.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from granrs import observables as obs
from granrs._granrs import VOLUME_FRACTION_MIN
from granrs.cases.column import RestWatch, build_model, granular_speed
from granrs.config import column_case, resolve

#: the interval between records (s)
RECORD_EVERY = 0.01
#: the thickness of the front that reads the volume profile (m)
FRONT_THICKNESS = 1e-3


def lowest_row_front(model, dx: float) -> float:
    """The right edge of the last cell of the lowest row that holds granular material."""
    f = getattr(model, "volume_fraction", None)
    inside = f[0] > VOLUME_FRACTION_MIN if f is not None else model.phi[0] > 0
    cells = np.nonzero(inside)[0]
    return float((cells[-1] + 1) * dx) if cells.size else 0.0


def study(ny: int, dry: bool, solver: str, transport: str, interface_yield: str, t_end: float) -> dict:
    interface = {"transport": transport}
    if transport == "clsvof":
        interface["mass_correction"] = False
    cfg = resolve(
        {
            "grid": {"ny": ny},
            "time": {"t_end": t_end},
            "fluidisation": {"fluidised": not dry},
            "bi_projection": {"solver": solver, "interface_yield": interface_yield},
            "interface": interface,
        }
    )
    case = column_case(cfg)
    model = build_model(case)
    dx = model.grid.dx
    watch = RestWatch(case.rest)
    v0 = model.dense_volume()
    arrest, h_arrest = None, None
    best_low = best_mm = 0.0
    after = []  # (t, speed, |h − h_arrest|_max, lowest-row front, 1 mm front) from the arrest on
    n = int(round(t_end / RECORD_EVERY))
    for k in range(1, n + 1):
        t = k * RECORD_EVERY
        model.advance(t_end=t)
        speed = granular_speed(model)
        h = obs.model_volume_profile(model)
        low, mm = lowest_row_front(model, dx), obs.thickness_front(h, dx, FRONT_THICKNESS)
        best_low, best_mm = max(best_low, low), max(best_mm, mm)
        if arrest is None and watch.update(t, speed):
            arrest, h_arrest = t, h.copy()
        if arrest is not None:
            after.append((t, speed, float(np.max(np.abs(h - h_arrest))), low, mm))
    out = {
        "ny": ny,
        "column": "dry" if dry else "fluidised",
        "solver": solver,
        "interface_transport": transport,
        "interface_yield": interface_yield,
        "t_end_s": t_end,
        "cell_m": dx,
        "arrest_s": arrest,
        "speed_at_end_m_s": speed,
        "volume_rel_change": None if v0 is None else model.dense_volume() / v0 - 1.0,
    }
    if after:
        out.update(
            {
                "profile_change_after_arrest_m": max(a[2] for a in after),
                "speed_after_arrest_max_m_s": max(a[1] for a in after),
                "lowest_row_front_retreat_cells": (best_low - min(a[3] for a in after)) / dx,
                "front_1mm_retreat_cells": (best_mm - min(a[4] for a in after)) / dx,
                "lowest_row_front_m": after[-1][3],
                "front_1mm_m": after[-1][4],
            }
        )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ny", type=int, default=32)
    ap.add_argument("--dry", action="store_true", help="the non-fluidised column")
    ap.add_argument("--solver", default="newton", help="bi_projection.solver")
    ap.add_argument("--interface-transport", default="clsvof", choices=["clsvof", "level-set"])
    ap.add_argument("--interface-yield", default="density-support", help="bi_projection.interface_yield")
    ap.add_argument("--t-end", type=float, default=3.0)
    ap.add_argument("--out", type=Path, default=Path("out/deposit-at-rest"))
    a = ap.parse_args()
    res = study(a.ny, a.dry, a.solver, a.interface_transport, a.interface_yield, a.t_end)
    a.out.mkdir(parents=True, exist_ok=True)
    path = a.out / f"{res['column']}-{a.ny}-{a.interface_yield}.json"
    path.write_text(json.dumps(res, indent=1) + "\n")
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
