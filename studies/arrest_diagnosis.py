"""Where does the column's late motion live, and what moves its front back?

    python studies/arrest_diagnosis.py --ny 32 --dry        # 10-25 s per variant at ny = 32, 2 min at 64
    python studies/arrest_diagnosis.py --ny 32 --dry --variants default no-mass-correction
    python studies/arrest_diagnosis.py --ny 32 --out out/arrest-wet
    python studies/arrest_diagnosis.py --ny 32 --dry --active-region 2 --variants proximal-20-anderson-5 --out out/arrest-window

Runs the paper's column (granrs.cases.column.build_model) to ``--t-end`` under several level-set
variants and records, every 0.01 s:

* the front on the lowest row of cells (``front_position``) and its largest value so far;
* the largest speed at cell centres in three groups of granular cells: the **bulk**
  (Φ > 2ε, ε = 1.5 h the Heaviside half-width: beyond the smoothed band), the **band on the
  granular side** (0 < Φ ≤ 2ε), and the **air side of the band** (−ε < Φ ≤ 0, where H_ε still
  gives the cell grains);
* the largest speed over the **deposit** (the granular cells 8-connected to the largest
  connected region of them, ``deposit_mask``) and over the **detached pieces** (the other
  granular cells: specks of Φ > 0 in the air, a piece of the tip cut off by a gap), and how many
  cells the pieces hold;
* the largest trial norm |Σ + rD + θ(Σⁿ − Σ)| over the bulk (≤ 1: rigid);
* the dense-phase area, and the energy budget's plastic work and its negative part.

Variants: ``default`` (the column's numerics: global mass correction on, redistancing every 10
steps), ``no-mass-correction``, ``redistance-50`` (redistancing every 50 steps), the
column's ``interface_yield`` choices ``density-support`` and ``granular-side``, and
``theta-0.3`` and ``theta-0.1`` (θ in eq. 12 instead of the column's 0.8), and ``proximal-5``,
``proximal-20`` (that many proximal restarts of the anchor Σⁿ per step,
``ColumnCase().with_options(proximal_restarts=N)``); ``proximal-20-anderson-5`` (the same with Anderson mixing
of depth 5, ``BiProjection(anderson_depth=5)``) and that one combined with: no mass correction;
redistancing every step or every 50 steps; no mass correction and redistancing every step,
every 50 steps or never; and ``density-support``; ``uzawa-anderson-10`` (θ = 0,
whose fixed point is eq. 11 itself, with Anderson mixing of depth 10) and
``theta-0.3-anderson-5``; ``extended``, ``extended-1.5``, ``extended-3`` (Φ transported with the
dense phase's velocity extended along the normal from Φ = d h, d = 0, 1.5, 3:
``Interface(velocity="extended", extension_depth=d)``), ``extended-at-rest`` (the
extension only where the dense phase moves slower than 5 mm/s, the column's rest speed:
``extension_rest_speed=0.005``), each also with ``no-mass-correction`` and with 20 proximal
restarts and Anderson mixing (``proximal-20-extended...``);
``density-support-extended-at-rest-proximal-20`` (the extension where the grains rest and the
yield stress at full strength over the band, with the restarts), also without the correction and
with redistancing every step; ``pieces-4`` (the regions of Φ > 0 of at most 4 cells turned to
air after each step's transport, ``Interface(piece_removal_cells=4)``), alone, with the restarts,
and with the restarts and redistancing every step, with and without the correction; the last
with the Picard tolerance 1e-4 or 1e-5 (``...-picard-tol-1e-4``), with 5 restarts
(``redistance-1-proximal-5-pieces-4``), without Anderson mixing (``...-no-anderson-...``) and with
redistancing every 2 steps (``redistance-2-proximal-20-pieces-4``), with the film-sparing mass
correction (``redistance-1-proximal-20-pieces-4-film-0.5``, ``Interface(mass_correction_film=0.5)``;
``...-film-0.5-at-rest``: only where the dense phase moves slower than 5 mm/s,
``mass_correction_film_speed=0.005``), with the redistancing's tolerance
(``redistance-1-proximal-20-pieces-4-tolerance-0.01``, ``Interface(redistance_tolerance=0.01)``: the
interface cells already within 0.01 cell of their distance keep Φ; also without the correction,
``no-mass-correction-redistance-1-proximal-20-pieces-4-tolerance-0.01``, with redistancing every 10
steps, ``proximal-20-pieces-4-tolerance-0.01``, with 5 restarts,
``redistance-1-proximal-5-pieces-4-tolerance-0.01``, and with the extension
where the dense phase rests, ``...-tolerance-0.01-extended-at-rest``, also with the yield stress
at full strength over the band,
``density-support-redistance-1-proximal-20-pieces-4-tolerance-0.01-extended-at-rest``), and
switched on late (``switch-U-redistance-1-proximal-20-pieces-4-tolerance-0.01``, U = 0.6, 0.3,
0.03: the column's own numerics until its largest granular speed falls below U m/s after
0.5 s, then the same state continued with the five options; ``switched_at_s`` in the summary),
and with the yield stress at
full strength over the band or its granular side (``density-support-...``,
``granular-side-redistance-1-proximal-20-pieces-4``). The runs do not stop at rest (the records go to t_end); the column's
rest criterion (granular speed below ``rest.speed`` for ``rest.duration``) is evaluated all the
same, to say when the run would have stopped and what changes after that.

Writes ``OUT/arrest_<variant>.csv`` (the records, with two fronts of the volume profile beside the
lowest-row front: where the deposit is half a cell thick, and its 99 % area quantile) and
``OUT/arrest_summary.json`` (per variant: largest front and when, the front at t_end, its retreat
in cells for the three fronts, the late speeds by group at t = 1.5-t_end, the area drift, the
give-back of the plastic work after 1.5 s, gravity's work and the potential energy released
after 1.5 s and their difference over the run, the deposit profile's change from 2.5 s to t_end,
the observables of the final volume profile (``granrs.observables.observe_profile``);
``arrest_time_s`` under the rest criterion and, after it, the largest granular speed, the
front's retreat, the change of the surface profile and of the volume profile to t_end, the
largest speeds of the deposit and of the detached pieces and the most cells the pieces held;
``deposit_arrest_time_s``, the same criterion on the deposit alone, and the deposit's largest
speed after it; ``pieces_removed_cells``, the cells of detached pieces turned to air over the
run (``piece_removal_cells``; per record in the CSV's ``pieces_removed``), and when the first
were; ``mass_shift_after_arrest_m``, the global mass correction's shifts δ of Φ summed from the
arrest to t_end (and of their magnitudes; per record in the CSV's ``mass_shift``); and
``eroded_after_arrest``: the columns whose volume profile fell by more than 1 mm, split into
those with no granular cell on the lowest row at the arrest (a film thinner than half a cell)
and the others, with where they lie, the area they lost and the speed of their lowest-row cells
at t_end).
docs/validation.md, "Arrest of the deposit", quotes it.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np

from granrs import ActiveRegion
from granrs.cases.column import ColumnCase, Fluidisation, RestWatch, build_model, front_position, surface_profile
from granrs.observables import area_quantile, observe_profile, thickness_front, volume_profile

#: 20 proximal restarts of the anchor Σⁿ per step with Anderson mixing of depth 5 (the variants
#: named ``...proximal-20...`` below, except ``proximal-20`` itself)
RESTARTS = {"case": {"proximal_restarts": 20}, "anderson_depth": 5}
#: the global mass correction off
NO_CORRECTION = {"mass_correction": False}
#: Φ transported with the dense phase's velocity extended along the normal
EXTENDED = {"interface_velocity": "extended"}
#: the extension only where the dense phase is at rest (the column's rest speed, 5 mm/s): the
#: one-fluid velocity where it flows
AT_REST = {**EXTENDED, "extension_rest_speed": 0.005}
#: pieces of Φ > 0 of at most 4 cells turned to air after each step's transport
PIECES = {"piece_removal_cells": 4}
#: the yield stress at full strength over the band, with the 20 restarts of RESTARTS
DENSITY_SUPPORT_20 = {"case": {"interface_yield": "density-support", "proximal_restarts": 20}}
#: a variant with this key runs the column's own numerics until its largest granular speed falls
#: below the value (m/s) after SWITCH_AFTER, then continues the same state with its options
SWITCH_BELOW = "switch_below_m_s"
#: no switch before this time (s): the collapse starts from rest
SWITCH_AFTER = 0.5

VARIANTS = {
    "default": {},
    "no-mass-correction": NO_CORRECTION,
    "redistance-50": {"redistance_every": 50},
    # the column's own settings (ColumnCase fields), for comparison
    "density-support": {"case": {"interface_yield": "density-support"}},
    "granular-side": {"case": {"interface_yield": "granular-side"}},
    "theta-0.3": {"case": {"theta": 0.3}},
    "theta-0.1": {"case": {"theta": 0.1}},
    "proximal-5": {"case": {"proximal_restarts": 5}},
    "proximal-20": {"case": {"proximal_restarts": 20}},
    # the same, with Anderson mixing of the Picard iterates (granrs.Numerics.anderson_depth)
    "proximal-20-anderson-5": RESTARTS,
    # Uzawa (θ = 0: the fixed point is eq. 11 itself) with Anderson mixing
    "uzawa-anderson-10": {"case": {"theta": 0.0}, "anderson_depth": 10},
    "theta-0.3-anderson-5": {"case": {"theta": 0.3}, "anderson_depth": 5},
    "density-support-proximal-20": {
        **RESTARTS,
        **DENSITY_SUPPORT_20,
    },
    "no-mass-correction-proximal-20": {**RESTARTS, **NO_CORRECTION},
    # redistancing every step, every 50 steps or never (the column: every 10)
    "redistance-50-proximal-20": {**RESTARTS, "redistance_every": 50},
    "no-mass-correction-redistance-50-proximal-20": {**RESTARTS, **NO_CORRECTION, "redistance_every": 50},
    "redistance-1-proximal-20": {**RESTARTS, "redistance_every": 1},
    "no-mass-correction-redistance-1-proximal-20": {**RESTARTS, **NO_CORRECTION, "redistance_every": 1},
    "no-mass-correction-no-redistancing-proximal-20": {**RESTARTS, **NO_CORRECTION, "redistance_every": 0},
    # the yield stress at full strength over the band's granular side or where the density
    # supports it, with redistancing at every step
    "granular-side-redistance-1-proximal-20": {
        **RESTARTS,
        "redistance_every": 1,
        "case": {"interface_yield": "granular-side", "proximal_restarts": 20},
    },
    "density-support-redistance-1-proximal-20": {
        **RESTARTS,
        "redistance_every": 1,
        **DENSITY_SUPPORT_20,
    },
    "density-support-no-mass-correction-proximal-20": {
        **RESTARTS,
        **NO_CORRECTION,
        **DENSITY_SUPPORT_20,
    },
    # Φ transported with the dense phase's velocity extended along the normal from Φ = d h
    # (interface_velocity = "extended", extension_depth = d), alone and with 20 restarts
    "extended": EXTENDED,
    "extended-1.5": {**EXTENDED, "extension_depth": 1.5},
    "extended-3": {**EXTENDED, "extension_depth": 3.0},
    "extended-no-mass-correction": {**EXTENDED, **NO_CORRECTION},
    "proximal-20-extended": {**RESTARTS, **EXTENDED},
    "proximal-20-extended-1.5": {**RESTARTS, **EXTENDED, "extension_depth": 1.5},
    "proximal-20-extended-3": {**RESTARTS, **EXTENDED, "extension_depth": 3.0},
    "proximal-20-extended-no-mass-correction": {**RESTARTS, **EXTENDED, **NO_CORRECTION},
    "proximal-20-extended-1.5-no-mass-correction": {**RESTARTS, **EXTENDED, "extension_depth": 1.5, **NO_CORRECTION},
    "extended-at-rest": AT_REST,
    "extended-at-rest-no-mass-correction": {**AT_REST, **NO_CORRECTION},
    "proximal-20-extended-at-rest": {**RESTARTS, **AT_REST},
    "proximal-20-extended-at-rest-no-mass-correction": {**RESTARTS, **AT_REST, **NO_CORRECTION},
    # small detached pieces of the dense phase turned to air
    "pieces-4": PIECES,
    "proximal-20-pieces-4": {**RESTARTS, **PIECES},
    "redistance-1-proximal-20-pieces-4": {**RESTARTS, **PIECES, "redistance_every": 1},
    "redistance-1-proximal-20-pieces-4-picard-tol-1e-4": {
        **RESTARTS,
        **PIECES,
        "redistance_every": 1,
        "picard_tol": 1e-4,
    },
    "redistance-1-proximal-20-pieces-4-picard-tol-1e-5": {
        **RESTARTS,
        **PIECES,
        "redistance_every": 1,
        "picard_tol": 1e-5,
    },
    "redistance-1-proximal-5-pieces-4": {**RESTARTS, **PIECES, "redistance_every": 1, "case": {"proximal_restarts": 5}},
    "redistance-1-proximal-5-no-anderson-pieces-4": {
        **RESTARTS,
        **PIECES,
        "redistance_every": 1,
        "case": {"proximal_restarts": 5},
        "anderson_depth": 0,
    },
    "redistance-1-proximal-20-no-anderson-pieces-4": {**RESTARTS, **PIECES, "redistance_every": 1, "anderson_depth": 0},
    "redistance-2-proximal-20-pieces-4": {**RESTARTS, **PIECES, "redistance_every": 2},
    # the same with the film-sparing mass correction (films thinner than about half a cell keep Φ)
    "redistance-1-proximal-20-pieces-4-film-0.5": {
        **RESTARTS,
        **PIECES,
        "redistance_every": 1,
        "mass_correction_film": 0.5,
    },
    # ... sparing only the films at rest (below the column's rest speed, 5 mm/s)
    "redistance-1-proximal-20-pieces-4-film-0.5-at-rest": {
        **RESTARTS,
        **PIECES,
        "redistance_every": 1,
        "mass_correction_film": 0.5,
        "mass_correction_film_speed": 0.005,
    },
    # ... with the redistancing's interface cells kept where they are already a distance
    "redistance-1-proximal-20-pieces-4-tolerance-0.01": {
        **RESTARTS,
        **PIECES,
        "redistance_every": 1,
        "redistance_tolerance": 0.01,
    },
    # the same with one thing changed: without the mass correction
    "no-mass-correction-redistance-1-proximal-20-pieces-4-tolerance-0.01": {
        **RESTARTS,
        **PIECES,
        **NO_CORRECTION,
        "redistance_every": 1,
        "redistance_tolerance": 0.01,
    },
    # ... redistancing every 10 steps (the column's) instead of every step
    "proximal-20-pieces-4-tolerance-0.01": {**RESTARTS, **PIECES, "redistance_tolerance": 0.01},
    # ... 5 restarts instead of 20
    "redistance-1-proximal-5-pieces-4-tolerance-0.01": {
        **RESTARTS,
        **PIECES,
        "redistance_every": 1,
        "case": {"proximal_restarts": 5},
        "redistance_tolerance": 0.01,
    },
    # ... Φ transported by the dense phase's velocity extended where it rests
    "redistance-1-proximal-20-pieces-4-tolerance-0.01-extended-at-rest": {
        **RESTARTS,
        **PIECES,
        **AT_REST,
        "redistance_every": 1,
        "redistance_tolerance": 0.01,
    },
    # ... the same five options switched on only once the column has slowed down (SWITCH_BELOW):
    # the column's own numerics until its largest granular speed falls below 0.6, 0.3 or 0.03 m/s
    **{
        f"switch-{u}-redistance-1-proximal-20-pieces-4-tolerance-0.01": {
            **RESTARTS,
            **PIECES,
            "redistance_every": 1,
            "redistance_tolerance": 0.01,
            SWITCH_BELOW: u,
        }
        for u in (0.6, 0.3, 0.03)
    },
    # ... the same extension and the yield stress at full strength over the band
    "density-support-redistance-1-proximal-20-pieces-4-tolerance-0.01-extended-at-rest": {
        **DENSITY_SUPPORT_20,
        "anderson_depth": 5,
        **PIECES,
        **AT_REST,
        "redistance_every": 1,
        "redistance_tolerance": 0.01,
    },
    "no-mass-correction-redistance-1-proximal-20-pieces-4": {
        **RESTARTS,
        **PIECES,
        **NO_CORRECTION,
        "redistance_every": 1,
    },
    # the yield stress at full strength over the band (or its granular side) with the four
    # options of the deposit-at-rest how-to
    "density-support-redistance-1-proximal-20-pieces-4": {
        **RESTARTS,
        **PIECES,
        "redistance_every": 1,
        **DENSITY_SUPPORT_20,
    },
    "granular-side-redistance-1-proximal-20-pieces-4": {
        **RESTARTS,
        **PIECES,
        "redistance_every": 1,
        "case": {"interface_yield": "granular-side", "proximal_restarts": 20},
    },
    # the yield stress at full strength over the band and the extension where the grains rest
    "density-support-extended-at-rest-proximal-20": {**RESTARTS, **AT_REST, **DENSITY_SUPPORT_20},
    "density-support-extended-at-rest-no-mass-correction-proximal-20": {
        **RESTARTS,
        **AT_REST,
        **DENSITY_SUPPORT_20,
        **NO_CORRECTION,
    },
    "density-support-extended-at-rest-redistance-1-proximal-20": {
        **RESTARTS,
        **AT_REST,
        **DENSITY_SUPPORT_20,
        "redistance_every": 1,
    },
    "density-support-extended-at-rest-no-mass-correction-redistance-1-proximal-20": {
        **RESTARTS,
        **AT_REST,
        **DENSITY_SUPPORT_20,
        **NO_CORRECTION,
        "redistance_every": 1,
    },
}


def deposit_mask(granular: np.ndarray) -> np.ndarray:
    """The deposit: the granular cells (Φ > 0) 8-connected to the largest 8-connected region of
    them. The other granular cells are detached pieces (specks of Φ > 0 in the air, a piece of
    the tip cut off by a gap)."""
    ny, nx = granular.shape
    label = np.zeros(granular.shape, dtype=np.int32)
    sizes = [0]
    for start in zip(*np.nonzero(granular)):
        if label[start]:
            continue
        sizes.append(0)
        label[start] = len(sizes) - 1
        stack = [start]
        while stack:
            j, i = stack.pop()
            sizes[-1] += 1
            for jj in range(max(j - 1, 0), min(j + 2, ny)):
                for ii in range(max(i - 1, 0), min(i + 2, nx)):
                    if granular[jj, ii] and not label[jj, ii]:
                        label[jj, ii] = label[start]
                        stack.append((jj, ii))
    return label == int(np.argmax(sizes)) if len(sizes) > 1 else granular


def largest_after(rows: list, after: np.ndarray, key: str) -> float:
    """The largest ``key`` of the records where ``after`` is True (0 when none)."""
    return float(max((r[key] for r, a in zip(rows, after) if a), default=0.0))


def build(case: ColumnCase, numerics: dict):
    """build_model with the options of ``numerics`` (and of ``numerics["case"]``) changed by their
    schema keys, each in the case's object that holds it (``ColumnCase.with_options``)."""
    numerics = dict(numerics)
    numerics.pop(SWITCH_BELOW, None)
    return build_model(case.with_options(**numerics.pop("case", {}), **numerics))


def run_variant(case: ColumnCase, name: str, t_end: float, every: float = 0.01) -> dict:
    switch_below = VARIANTS[name].get(SWITCH_BELOW)
    switched = None  # when the variant's options were switched on (SWITCH_BELOW)
    m = build(case, {} if switch_below is not None else VARIANTS[name])
    g = m.grid
    eps = 1.5 * g.dy
    lc = case.geometry.width
    rows = []
    profiles = {}
    t0 = time.perf_counter()
    k = 0
    # the column's rest criterion (granrs.cases.column.RestCriterion), evaluated without stopping:
    # the start of the first quiet window of rest.duration, and the profile then; and the same
    # criterion on the deposit alone (deposit_mask: without the detached pieces)
    rest, deposit_rest = (RestWatch(case.rest) for _ in range(2))
    arrest = deposit_arrest = arrest_profile = None
    while m.time < t_end - 1e-12:
        k += 1
        log = m.advance(min(t_end, k * every))
        phi = m.phi
        uc, vc = m.centre_velocity()
        speed = np.hypot(uc, vc)
        groups = {"bulk": phi > 2 * eps, "band": (phi > 0) & (phi <= 2 * eps), "air_band": (phi > -eps) & (phi <= 0)}
        row = {"t": m.time, "front": front_position(phi, g.dx) - lc, "area": m.dense_area()}
        row["pieces_removed"] = int(sum(log["pieces_removed"]))  # cells turned to air since the last record
        row["mass_shift"] = float(sum(log["mass_shift"]))  # the mass correction's δ since the last record (m)
        row["mass_shift_abs"] = float(sum(abs(d) for d in log["mass_shift"]))
        # fronts of the volume profile, which do not jump when a film thinner than h/2 on the
        # lowest row changes sign: where it is half a cell thick, and the 99 % area quantile
        hvol = volume_profile(phi, g.dy)
        row["front_half_cell"] = thickness_front(hvol, g.dx, 0.5 * g.dy) - lc
        row["front_q99"] = area_quantile(hvol, g.dx, 0.99) - lc
        row["front_20mm"] = thickness_front(hvol, g.dx, 0.02) - lc
        for key, mask in groups.items():
            row[f"speed_{key}"] = float(speed[mask].max()) if mask.any() else 0.0
        granular = phi > 0
        deposit = deposit_mask(granular)
        detached = granular & ~deposit
        row["speed_deposit"] = float(speed[deposit].max()) if deposit.any() else 0.0
        row["speed_detached"] = float(speed[detached].max()) if detached.any() else 0.0
        row["detached_cells"] = int(detached.sum())
        row["detached_phi_max_over_h"] = float(phi[detached].max() / g.dy) if detached.any() else 0.0
        j, i = np.unravel_index(np.argmax(np.where(granular, speed, -1.0)), speed.shape)
        row["speed_granular"] = float(speed[j, i])
        row["where_x"], row["where_y"], row["where_phi_over_h"] = (
            (i + 0.5) * g.dx - lc,
            (j + 0.5) * g.dy,
            phi[j, i] / g.dy,
        )
        tn = m.trial_norm
        row["trial_norm_bulk_max"] = float(tn[groups["bulk"]].max()) if groups["bulk"].any() else 0.0
        b = m.energy_budget()
        row["plastic_work"], row["plastic_negative_work"] = b["plastic_work"], b["plastic_negative_work"]
        row["gravity_work"] = b["gravity_work"]
        row["potential"] = b["potential"]
        rows.append(row)
        if (
            switched is None
            and switch_below is not None
            and m.time > SWITCH_AFTER
            and row["speed_granular"] < switch_below
        ):
            # the same state (fields, history, clock) continued with the variant's options
            state = m.state()
            m = build(case, VARIANTS[name])
            m.restore(state)
            switched = m.time
        if deposit_arrest is None and deposit_rest.update(m.time, row["speed_deposit"]):
            deposit_arrest = deposit_rest.since
        if arrest is None and rest.update(m.time, row["speed_granular"]):
            arrest = rest.since
            arrest_profile = (surface_profile(phi, g.dy), volume_profile(phi, g.dy), np.array(phi[0, :]))
        for tp in (1.5, 2.0, 2.5, t_end):
            if abs(m.time - tp) < 1e-9:
                profiles[tp] = surface_profile(phi, g.dy)
    wall = time.perf_counter() - t0
    t = np.array([r["t"] for r in rows])
    front = np.array([r["front"] for r in rows])
    area = np.array([r["area"] for r in rows])
    imax = int(np.argmax(front))
    late = t >= 1.5
    out = {
        "variant": name,
        "switched_at_s": switched,
        "wall_s": wall,
        "steps": m.step_count,
        "max_front_m": float(front[imax]),
        "max_front_time_s": float(t[imax]),
        "front_end_m": float(front[-1]),
        "retreat_m": float(front[imax] - front[-1]),
        "retreat_cells": float((front[imax] - front[-1]) / g.dx),
        "area_rel_drift": float(np.max(np.abs(area / area[0] - 1.0))),
        "late_speed_max": {
            key: float(max(r[f"speed_{key}"] for r, is_late in zip(rows, late) if is_late))
            for key in ("bulk", "band", "air_band", "granular")
        },
        "speed_at_end": {key: rows[-1][f"speed_{key}"] for key in ("bulk", "band", "air_band", "granular")},
        "trial_norm_bulk_max_late": float(max(r["trial_norm_bulk_max"] for r, is_late in zip(rows, late) if is_late)),
        "where_at_end": {
            "x_from_gate_m": rows[-1]["where_x"],
            "y_m": rows[-1]["where_y"],
            "phi_over_h": rows[-1]["where_phi_over_h"],
        },
    }
    i15 = int(np.searchsorted(t, 1.5 - 1e-9))
    out["plastic_work_after_1p5_J_m"] = rows[-1]["plastic_work"] - rows[i15]["plastic_work"]
    out["plastic_negative_work_after_1p5_J_m"] = rows[-1]["plastic_negative_work"] - rows[i15]["plastic_negative_work"]
    out["gravity_work_after_1p5_J_m"] = rows[-1]["gravity_work"] - rows[i15]["gravity_work"]
    # the potential energy the interface's motion releases; equal to gravity's work on the flow
    # when Φ moves with the momentum's velocity
    out["potential_drop_after_1p5_J_m"] = rows[i15]["potential"] - rows[-1]["potential"]
    b0 = m.energy_budget()
    out["gravity_work_minus_potential_drop_J_m"] = b0["gravity_work"] - (b0["potential_initial"] - b0["potential"])
    if 2.5 in profiles and t_end in profiles:
        out["profile_change_2p5_to_end_m"] = float(np.max(np.abs(profiles[t_end] - profiles[2.5])))
    out["observables_end"] = observe_profile(volume_profile(m.phi, g.dy), g.dx, g.dy, lc)
    for key in ("front_half_cell", "front_q99", "front_20mm"):
        f = np.array([r[key] for r in rows])
        out[f"retreat_{key}_cells"] = float((f.max() - f[-1]) / g.dx)
    out["arrest_time_s"] = arrest
    out["pieces_removed_cells"] = int(sum(r["pieces_removed"] for r in rows))
    out["pieces_removed_first_time_s"] = next((r["t"] for r in rows if r["pieces_removed"]), None)
    out["deposit_arrest_time_s"] = deposit_arrest
    if deposit_arrest is not None:
        after = t > deposit_arrest + case.rest.duration
        out["deposit_speed_after_deposit_arrest_max"] = largest_after(rows, after, "speed_deposit")
    if arrest is not None:
        after = t > arrest + case.rest.duration
        out["profile_change_after_arrest_m"] = float(np.max(np.abs(surface_profile(m.phi, g.dy) - arrest_profile[0])))
        out["volume_profile_change_after_arrest_m"] = float(
            np.max(np.abs(volume_profile(m.phi, g.dy) - arrest_profile[1]))
        )
        out["granular_speed_after_arrest_max"] = largest_after(rows, after, "speed_granular")
        # the fastest granular cells after the arrest: in the deposit, or in detached pieces
        for key in ("deposit", "detached"):
            out[f"{key}_speed_after_arrest_max"] = largest_after(rows, after, f"speed_{key}")
        out["detached_cells_after_arrest_max"] = int(largest_after(rows, after, "detached_cells"))
        # how far the global mass correction moved the interface after the arrest: the sum of
        # its shifts δ (Φ ← Φ + δ), and of their magnitudes
        out["mass_shift_after_arrest_m"] = float(sum(r["mass_shift"] for r, a in zip(rows, after) if a))
        out["mass_shift_abs_after_arrest_m"] = float(sum(r["mass_shift_abs"] for r, a in zip(rows, after) if a))
        out["front_retreat_after_arrest_m"] = float(front[t <= arrest + case.rest.duration + 1e-9][-1] - front[-1])
        # the columns whose volume profile fell by more than 1 mm after the arrest, in two groups:
        # "thin", with no granular cell on the lowest row at the arrest (Φ ≤ 0 there: a film
        # thinner than half a cell, which the smoothed Heaviside still counts), and "thick"; for
        # each, where they lie, the area they lost and how fast their lowest-row cells move at t_end
        loss = arrest_profile[1] - volume_profile(m.phi, g.dy)
        eroded = {}
        for group, cols in (("thin", arrest_profile[2] <= 0.0), ("thick", arrest_profile[2] > 0.0)):
            idx = np.where((loss > 1e-3) & cols)[0]
            if idx.size:
                eroded[group] = {
                    "columns": int(idx.size),
                    "x_from_gate_m": [float((idx.min() + 0.5) * g.dx - lc), float((idx.max() + 0.5) * g.dx - lc)],
                    "area_lost_m2": float(loss[idx].sum() * g.dx),
                    "largest_loss_m": float(loss[idx].max()),
                    "lowest_row_speed_at_end_max": float(speed[0, idx].max()),
                }
        out["eroded_after_arrest"] = {
            **eroded,
            "area_lost_all_columns_m2": float(loss.sum() * g.dx),
            "granular_speed_at_end": rows[-1]["speed_granular"],
        }
        out["area_drift_after_arrest"] = float(
            np.max(np.abs(area[t >= arrest] / area[t >= arrest][0] - 1.0)) if np.any(t >= arrest) else 0.0
        )
    if 1.5 in profiles and t_end in profiles:
        out["profile_change_1p5_to_end_m"] = float(np.max(np.abs(profiles[t_end] - profiles[1.5])))
    return out, rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ny", type=int, default=32)
    ap.add_argument("--dry", action="store_true", help="the non-fluidised column")
    ap.add_argument("--t-end", type=float, default=3.0)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument(
        "--active-region",
        dest="active_region",
        type=int,
        default=None,
        metavar="BAND",
        help="run on the active region with BAND cells of air and open right and top sides (the air leaves)",
    )
    ap.add_argument("--out", type=Path, default=Path("out/arrest"))
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    window = {} if a.active_region is None else {"active_region": ActiveRegion(a.active_region, sides="open-right-top")}
    case = ColumnCase(ny=a.ny, fluidisation=Fluidisation(fluidised=not a.dry), t_end=a.t_end, **window)
    summary_path = a.out / "arrest_summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    for name in a.variants:
        s, rows = run_variant(case, name, a.t_end)
        s["case"] = {"ny": a.ny, "fluidised": not a.dry, "t_end": a.t_end, "active_region_band": a.active_region}
        summary[name] = s
        with open(a.out / f"arrest_{name}.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            for r in rows:
                w.writerow({k: f"{v:.6g}" for k, v in r.items()})
        summary_path.write_text(json.dumps(summary, indent=2) + "\n")
        print(json.dumps(s, indent=1))


if __name__ == "__main__":
    main()
