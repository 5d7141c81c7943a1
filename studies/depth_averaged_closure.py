"""The depth-averaged model's lateral-pressure closure, chosen by measurement against the two-phase reference.

    python studies/depth_averaged_closure.py                  # the runs (about 3 min) and the tables
    python studies/depth_averaged_closure.py --update-ladder  # and the depth-averaged rows of the ladder
    python studies/depth_averaged_closure.py --ladder-only    # the ladder's rows from the stored table, no runs

For every closure of ``granrs.depth_averaged.CLOSURES`` (the earth-pressure coefficient k of the
effective stress, the pore pressure isotropic: 'hydrostatic' k = 1, 'savage-hutter' the active k
of the internal and basal friction angles, 'rankine' the active k of the internal angle alone)
and both pore-pressure transports (``PORE_TRANSPORTS``), this script runs the depth-averaged
model on the eight scenes of the model ladder (the paper's column at a = 0.5, 1, 2, 4,
fluidised and dry; studies/model_ladder.py) and compares each with the two-phase reference of
the ladder (the rows ``reference`` of docs/img/model_ladder.csv: ny = 64 on the open window). The
error of a scene is the largest relative error over the ladder's six well-conditioned
observables (the 50 % quantile left out where the reference's lies within 0.1 m of the gate,
as in the ladder's table) and the lowest-row run-out is reported beside it.

It also sweeps the base's friction angle over 10-30 degrees (every 5) at a = 2 with β = 0.9 and
tabulates the fluidised and dry run-outs of each closure: where the fluidised run is shorter
than the dry one, the closure contradicts the experiment and the two-phase model.

Outputs: ``docs/img/depth_averaged_closures.csv`` (one row per closure, transport and scene),
``docs/img/depth_averaged_angle_sweep.csv``, and the summary printed as JSON. With
``--update-ladder`` the depth-averaged rows of docs/img/model_ladder.csv are replaced by the
default closure's runs (``--ladder-only``: from the stored table) and docs/img/model_ladder.png is
redrawn (studies/model_ladder.py's plot).
"""

from __future__ import annotations

import argparse
import csv
import json
import runpy
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from granrs import CoulombWall, DepthAveraged, SimulationError
from granrs.cases.column import ColumnCase, ColumnGeometry, Fluidisation, run_column
from granrs.depth_averaged import CLOSURES, PORE_TRANSPORTS

ROOT = Path(__file__).resolve().parents[1]
LADDER = ROOT / "docs" / "img" / "model_ladder.csv"
#: the ladder's observables (studies/model_ladder.py), the six well-conditioned ones first
SIX = ("front_h20mm_m", "centre_of_mass_travel_m", "q50_m", "q90_m", "h_back_wall_m", "h_gate_m")
#: a 50 % quantile within this distance of the gate (m) is left out of the worst error
Q50_NEAR_GATE_M = 0.1
ANGLES = (10.0, 15.0, 20.0, 25.0, 30.0)


def references() -> dict:
    """The reference rows of the ladder by (fluidised, a)."""
    rows = list(csv.DictReader(LADDER.open()))
    return {
        (r["fluidised"] == "True", float(r["aspect_ratio"])): {k: float(r[k]) for k in SIX + ("runout_m",)}
        for r in rows
        if r["rung"] == "reference"
    }


def run(case: ColumnCase) -> dict:
    """The run's summary (a run that reaches the far end of its channel is rerun on one twice as long)."""
    while True:
        with tempfile.TemporaryDirectory() as tmp:
            try:
                return run_column(case, tmp, progress=False)
            except SimulationError as err:
                if "far end" not in str(err):
                    raise
                case = replace(case, geometry=replace(case.geometry, length=2.0 * case.domain()[0]))


def errors(summary: dict, ref: dict) -> dict:
    """Relative errors of the six observables and the run-out, and the worst of the six."""
    obs = summary["observables"]
    rel = {k: (obs[k] - ref[k]) / ref[k] for k in SIX}
    rel["runout_m"] = (summary["runout_m"] - ref["runout_m"]) / ref["runout_m"]
    judged = [k for k in SIX if not (k == "q50_m" and abs(ref[k]) < Q50_NEAR_GATE_M)]
    rel["worst"] = max(abs(rel[k]) for k in judged)
    return rel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--update-ladder",
        dest="update_ladder",
        action="store_true",
        help="after the runs, the ladder's depth-averaged rows from the default closure's",
    )
    ap.add_argument(
        "--ladder-only",
        dest="ladder_only",
        action="store_true",
        help="no runs: the ladder's depth-averaged rows from the stored docs/img/depth_averaged_closures.csv",
    )
    args = ap.parse_args()
    if args.ladder_only:
        update_ladder()
        return
    refs = references()
    rows, by_scene = [], {}
    t0 = time.perf_counter()
    for transport in PORE_TRANSPORTS:
        for closure in CLOSURES:
            for (fluidised, a), ref in sorted(refs.items()):
                da = DepthAveraged(closure=closure, pore_transport=transport)
                scene = dict(geometry=ColumnGeometry(aspect_ratio=a), fluidisation=Fluidisation(fluidised=fluidised))
                s = run(ColumnCase(**scene, model="depth-averaged", depth_averaged=da))
                rel = errors(s, ref)
                row = {"closure": closure, "transport": transport, "aspect_ratio": a, "fluidised": fluidised}
                row.update({k: s["observables"][k] for k in SIX})
                row["runout_m"] = s["runout_m"]
                row.update({f"rel_{k}": v for k, v in rel.items()})
                row.update(wall_s=s["wall_s"], stop_reason=s["stop_reason"], t_end_s=s["t_end_s"])
                rows.append(row)
                by_scene[closure, transport, fluidised, a] = (s, rel)
    img = ROOT / "docs" / "img"
    with open(img / "depth_averaged_closures.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: f"{v:.6g}" if isinstance(v, float) else v for k, v in r.items()})
    summary = {}
    for transport in PORE_TRANSPORTS:
        for closure in CLOSURES:
            worst = {
                f"{'fluidised' if fl else 'dry'} a={a:g}": round(100 * rel["worst"], 1)
                for (c, t, fl, a), (_, rel) in by_scene.items()
                if (c, t) == (closure, transport)
            }
            runout = [
                abs(rel["runout_m"]) for (c, t, _, _), (_, rel) in by_scene.items() if (c, t) == (closure, transport)
            ]
            summary[f"{closure} / {transport}"] = {
                "worst_percent_by_scene": worst,
                "largest_worst_percent": max(worst.values()),
                "mean_worst_percent": round(sum(worst.values()) / len(worst), 1),
                "largest_runout_error_percent": round(100 * max(runout), 1),
            }
    # the base angle sweep: fluidised against dry run-out at a = 2
    sweep = []
    for closure in CLOSURES:
        for angle in ANGLES:
            r = {"closure": closure, "base_angle_deg": angle}
            for fluidised in (True, False):
                case = ColumnCase(
                    fluidisation=Fluidisation(fluidised=fluidised),
                    model="depth-averaged",
                    base=CoulombWall(angle),
                    depth_averaged=DepthAveraged(closure=closure),
                )
                r["fluidised_runout_m" if fluidised else "dry_runout_m"] = run(case)["runout_m"]
            r["ratio"] = r["fluidised_runout_m"] / r["dry_runout_m"]
            sweep.append(r)
    with open(img / "depth_averaged_angle_sweep.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(sweep[0]))
        w.writeheader()
        for r in sweep:
            w.writerow({k: f"{v:.6g}" if isinstance(v, float) else v for k, v in r.items()})
    summary["angle_sweep"] = [{k: round(v, 3) if isinstance(v, float) else v for k, v in r.items()} for r in sweep]
    summary["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(summary, indent=1, ensure_ascii=False))
    if args.update_ladder:
        update_ladder()


def update_ladder() -> None:
    """The depth-averaged rows of docs/img/model_ladder.csv replaced by the default closure's and
    transport's rows of docs/img/depth_averaged_closures.csv, and the ladder's figure redrawn."""
    default = DepthAveraged()
    runs = {
        (r["fluidised"] == "True", float(r["aspect_ratio"])): r
        for r in csv.DictReader((ROOT / "docs" / "img" / "depth_averaged_closures.csv").open())
        if (r["closure"], r["transport"]) == (default.closure, default.pore_transport)
    }
    rows = list(csv.DictReader(LADDER.open()))
    fields = list(rows[0])
    for r in rows:
        if r["rung"] == "depth-averaged":
            new = runs[r["fluidised"] == "True", float(r["aspect_ratio"])]
            r.update({k: new[k] for k in fields if k in new and k not in ("aspect_ratio", "fluidised")})
    with open(LADDER, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
    ladder = runpy.run_path(str(ROOT / "studies" / "model_ladder.py"))
    table = ladder["read_table"](LADDER)
    ny = int(next(r["ny"] for r in table if r["rung"] == "two-phase"))
    ladder["plot"](table, ROOT / "docs" / "img" / "model_ladder.png", ny)


if __name__ == "__main__":
    main()
