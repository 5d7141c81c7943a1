"""How predictable is the column's run-out? An ensemble of runs perturbed at round-off level.

    python studies/runout_ensemble.py --ny 32 --members 8                 # about 2 min
    python studies/runout_ensemble.py --ny 64 --members 4                 # about 12 min
    python studies/runout_ensemble.py --ny 64 --members 4 --active-region 8 --compare-with out/ensemble-two-phase-fluidised-64
    python studies/runout_ensemble.py --ny 64 --members 4 --active-region 8 --active-region-sides open-right --compare-with out/ensemble-two-phase-fluidised-64
    python studies/runout_ensemble.py --ny 32 --members 8 --model granular --out out/ensemble-g32
    python studies/runout_ensemble.py --ny 32 --members 8 --option proximal_restarts=20 --compare-with out/ensemble-two-phase-fluidised-32

Member k runs the paper's column (`granrs run column`, fluidised unless ``--dry``) with the column
width multiplied by 1 + k·ε (ε = 1e-12 by default: a relative change of the size of the
floating-point round-off of the grid's coordinates) and the channel's length and height held at
the unperturbed values, so that every member has the same grid and differs only in the initial
level set and the extent of the basal gas inflow, by about 1e-13 m. Member 0 is the case itself.

The question it answers: to how many digits is one run's run-out a property of the model, and
from when on do round-off differences (another build, another thread count on another machine,
an active region, a different multigrid hierarchy) become visible in the front? docs/validation.md
("Predictability of the late run-out") reports what it measured; the spread it prints is the
floor below which two runs cannot be said to disagree.

What it writes into ``OUT`` (each member in ``OUT/member-K/``, reused when run
again if it finished; one that was killed, interrupted or failed is run again):

* ``ensemble.csv``: per member the perturbation, run-out, largest front, the 99 % area quantile
  of the final deposit (``runout_q99_m``), front at 0.5 / 1.0 / 1.5 / 2.0 s, steps and wall time;
* ``ensemble_summary.json``: mean, standard deviation, min, max and relative spread of the
  run-out, the largest front and the 99 % quantile, and ``divergence_time_s``: the first time at which the members'
  fronts differ by more than 1 % of their mean; under ``observables`` the same statistics of every
  observable of the final deposits (``summary.json["observables"]``, granrs.observables), of the
  front's retreat and, where every member came to rest, of the arrest time;
* ``ensemble_fronts.png``: every member's front against time, with the band min–max;
* with ``--compare-with DIR`` (another ensemble's folder), ``comparison.json``: for every
  statistic, the difference of the means relative to the other ensemble's, and the standard error
  of that difference (the "± " of the active-region and model comparisons in docs/models.md), and
  the difference in standard deviations of the other ensemble (``sigmas``), observables included.

Run time on the 2-core development machine, one thread per member: about 13 s per member at
ny = 32 (two-phase), 8 s granular-only; about 3 min at ny = 64 (two-phase), 1 min with
``--active-region 8``. ``--jobs 2`` runs two members side by side, each in a process of its own,
with the same members to the last bit: 4 members at ny = 32 took 13.6 s instead of 26.9 s
(2-core VM, 2026-12-05; docs/howto/threads.md).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from granrs import ActiveRegion, SideWalls
from granrs.cases.column import (
    PAPER_RUNOUT_EXP,
    PAPER_RUNOUT_SIM,
    ColumnCase,
    Fluidisation,
    deposit_quantile,
    run_columns,
    run_finished,
)
from granrs.config import parse_options
from granrs.model import ACTIVE_REGION_SIDES

#: Fronts of the members are said to have diverged once their range exceeds this fraction of
#: their mean.
DIVERGENCE = 0.01
#: Times at which the front is tabulated.
TIMES = (0.5, 1.0, 1.5, 2.0)


def member_case(base: ColumnCase, k: int, eps: float) -> ColumnCase:
    """Member k: the base case with the column width scaled by 1 + k·eps, on the base's grid."""
    length, height = base.domain()
    g = base.geometry
    geometry = dataclasses.replace(g, width=g.width * (1.0 + k * eps), length=length, height=height)
    return dataclasses.replace(base, geometry=geometry)


def read_front(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    data = np.genfromtxt(folder / "front.csv", delimiter=",", names=True)
    return np.atleast_1d(data["t_s"]), np.atleast_1d(data["front_m"])


def q99(folder: Path) -> float:
    """The 99 % area quantile of the member's final deposit (``runout_q99_m``), from profiles.csv
    (so that members run before summary.json had it are read the same way)."""
    d = np.genfromtxt(folder / "profiles.csv", delimiter=",", names=True)
    x, h = d["x_from_gate_m"], d["h_final"]
    dx = float(x[1] - x[0])
    return deposit_quantile(h, dx, -(float(x[0]) - 0.5 * dx))


def common_fronts(curves: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """The members' fronts interpolated on the first member's times up to the shortest run:
    (times, array members × times)."""
    t0 = curves[0][0]
    t_common = t0[t0 <= min(t[-1] for t, _ in curves)]
    return t_common, np.array([np.interp(t_common, t, f) for t, f in curves])


def divergence_time(t_common: np.ndarray, fronts: np.ndarray, threshold: float = DIVERGENCE) -> float | None:
    """First time at which the members' fronts (:func:`common_fronts`) span more than
    ``threshold`` of their mean; None if they never do."""
    mean = fronts.mean(axis=0)
    spread = fronts.max(axis=0) - fronts.min(axis=0)
    hit = np.nonzero((mean > 0) & (spread > threshold * np.abs(mean)))[0]
    return float(t_common[hit[0]]) if hit.size else None


def statistics(values: list[float]) -> dict:
    v = np.asarray(values, dtype=float)
    mean = float(v.mean())
    return {
        "mean": mean,
        "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
        "min": float(v.min()),
        "max": float(v.max()),
        "relative_spread": float((v.max() - v.min()) / mean) if mean else float("nan"),
        "n": int(v.size),
    }


def observable_statistics(summaries: list[dict]) -> dict:
    """The statistics of every observable of the members' final deposits
    (``summary.json["observables"]``, granrs.observables) that every member reports as a number,
    and of ``front_retreat_m`` and ``arrest_time_s`` where every member has one."""
    stats = {}
    keys = set.intersection(*(set(s.get("observables") or {}) for s in summaries))
    for key in sorted(keys):
        values = [s["observables"][key] for s in summaries]
        if all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            stats[key] = statistics(values)
    for key in ("front_retreat_m", "arrest_time_s"):
        values = [s.get(key) for s in summaries]
        if all(isinstance(v, (int, float)) for v in values):
            stats[key] = statistics(values)
    return stats


def compare(summary: dict, other: dict) -> dict:
    """Differences of this ensemble's means against another's (``--compare-with``), relative to the
    other's mean, with the standard error of the difference √(s₁²/n₁ + s₂²/n₂) in the same units
    and the difference in units of the other's standard deviation (``sigmas``, the other's
    round-off spread; null when that is 0): how the docs compare an active region with the whole
    domain, two models, or two sets of numerics. The observables of ``summary["observables"]`` are
    compared the same way, under ``"observables"``."""
    out: dict = {"against": other.get("case"), "this": summary.get("case")}
    for key, a in summary.items():
        b = other.get(key)
        if key == "observables" and isinstance(a, dict) and isinstance(b, dict):
            out[key] = {k: v for k, v in compare(a, b).items() if k not in ("against", "this")}
            continue
        if not (isinstance(a, dict) and isinstance(b, dict) and "mean" in a and "mean" in b) or not b["mean"]:
            continue
        se = math.sqrt(a["std"] ** 2 / a["n"] + b["std"] ** 2 / b["n"])
        out[key] = {
            "difference": a["mean"] - b["mean"],
            "relative_difference": a["mean"] / b["mean"] - 1.0,
            "relative_standard_error": se / abs(b["mean"]),
            "sigmas": (a["mean"] - b["mean"]) / b["std"] if b["std"] > 0 else None,
        }
    return out


def run_members(base: ColumnCase, args: argparse.Namespace, out: Path, tag: str) -> None:
    """Runs the members whose folder ``out/member-K`` holds no finished run
    (:func:`granrs.cases.column.run_finished`: a member that was killed, interrupted or failed is
    run again), ``args.jobs`` at a time (:func:`granrs.cases.column.run_columns`)."""
    todo = [k for k in range(args.members) if not run_finished(out / f"member-{k}")]
    for k in todo:
        print(f"member {k} of {args.members} ({tag}) ...", flush=True)
    run_columns([(member_case(base, k, args.eps), out / f"member-{k}") for k in todo], jobs=args.jobs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ny", type=int, default=32)
    ap.add_argument("--members", type=int, default=8)
    ap.add_argument("--eps", type=float, default=1e-12, help="relative perturbation of the width per member")
    ap.add_argument("--model", default="two-phase", choices=["two-phase", "granular"])
    ap.add_argument("--active-region", type=int, default=None)
    ap.add_argument(
        "--active-region-sides",
        default="walls",
        choices=ACTIVE_REGION_SIDES,
        help="the window's right and top sides (ActiveRegion.sides)",
    )
    ap.add_argument("--dry", action="store_true")
    ap.add_argument("--t-end", type=float, default=None)
    ap.add_argument(
        "--theta",
        type=float,
        default=None,
        help="the Picard relaxation θ of eq. (12) (BiProjection.theta; the column's 0.8)",
    )
    ap.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change a model option from the column's default by its schema key (`granrs keys`), "
        "e.g. --option proximal_restarts=20 (repeat)",
    )
    ap.add_argument(
        "--channel-width",
        dest="channel_width",
        type=float,
        default=None,
        help="the friction of side walls this far apart (m; SideWalls(W, the base's angle); not in the paper's model)",
    )
    ap.add_argument("--threads", type=int, default=1, help="threads of each member's run")
    ap.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="members run side by side, each in a process of its own (at most the free cores / --threads)",
    )
    ap.add_argument("--out", default=None)
    ap.add_argument(
        "--compare-with",
        default=None,
        metavar="DIR",
        help="another ensemble's output folder: writes comparison.json (differences of the means, ± standard error)",
    )
    args = ap.parse_args()
    if args.members < 2:
        raise SystemExit(f"invalid parameter `--members` = {args.members}: allowed an integer >= 2")
    if args.jobs < 1:
        raise SystemExit(f"invalid parameter `--jobs` = {args.jobs}: allowed an integer >= 1")
    options = parse_options(args.option)
    tag = (
        f"{args.model}-{'dry' if args.dry else 'fluidised'}-{args.ny}"
        + (f"-band{args.active_region}" if args.active_region else "")
        + (f"-{args.active_region_sides}" if args.active_region and args.active_region_sides != "walls" else "")
        + (f"-theta{args.theta:g}" if args.theta is not None else "")
        + (f"-walls{args.channel_width:g}" if args.channel_width is not None else "")
        + "".join(f"-{k}{v}" for k, v in options.items())
    )
    out = Path(args.out or f"out/ensemble-{tag}")

    base = ColumnCase(
        ny=args.ny,
        fluidisation=Fluidisation(fluidised=not args.dry),
        model=args.model,
        active_region=None
        if args.active_region is None
        else ActiveRegion(args.active_region, sides=args.active_region_sides),
        threads=args.threads,
    )
    if args.t_end is not None:
        base.t_end = args.t_end
    if args.theta is not None:
        base = base.with_options(theta=args.theta)
    if options:
        base = base.with_options(**options)
    if args.channel_width is not None:
        base.side_walls = SideWalls(args.channel_width, base.base.friction_angle)
    out.mkdir(parents=True, exist_ok=True)  # after the case's options were checked
    run_members(base, args, out, tag)
    rows, curves, summaries = [], [], []
    for k in range(args.members):
        folder = out / f"member-{k}"
        s = json.loads((folder / "summary.json").read_text())
        summaries.append(s)
        t, f = read_front(folder)
        curves.append((t, f))
        row = {
            "member": k,
            "width_rel_perturbation": k * args.eps,
            "runout_m": s["runout_m"],
            "max_front_m": s.get("max_front_m", float(np.max(f))),
            "runout_q99_m": q99(folder),
            "steps": s["steps"],
            "wall_s": s["wall_s"],
        }
        for tt in TIMES:
            row[f"front_{tt:g}s_m"] = float(np.interp(tt, t, f)) if t[-1] >= tt else float("nan")
        rows.append(row)

    with open(out / "ensemble.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    t_common, fronts = common_fronts(curves)
    summary = {
        "case": tag,
        "eps": args.eps,
        "runout_m": statistics([r["runout_m"] for r in rows]),
        "max_front_m": statistics([r["max_front_m"] for r in rows]),
        "runout_q99_m": statistics([r["runout_q99_m"] for r in rows]),
        "divergence_threshold": DIVERGENCE,
        "divergence_time_s": divergence_time(t_common, fronts),
        "observables": observable_statistics(summaries),
    }
    for tt in TIMES:
        vals = [r[f"front_{tt:g}s_m"] for r in rows if np.isfinite(r[f"front_{tt:g}s_m"])]
        if len(vals) > 1:
            summary[f"front_{tt:g}s_m"] = statistics(vals)
    (out / "ensemble_summary.json").write_text(json.dumps(summary, indent=2))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    ax.fill_between(t_common, fronts.min(axis=0), fronts.max(axis=0), color="0.85", label="range of the members")
    for k, (t, f) in enumerate(curves):
        ax.plot(t, f, lw=0.9, label=f"member {k}: run-out {rows[k]['runout_m']:.3f} m" if k < 8 else None)
    ax.axhline(PAPER_RUNOUT_SIM, color="k", ls="--", lw=0.8, label=f"paper, simulation {PAPER_RUNOUT_SIM} m")
    ax.axhline(PAPER_RUNOUT_EXP, color="k", ls=":", lw=0.8, label=f"paper, experiment {PAPER_RUNOUT_EXP} m")
    td = summary["divergence_time_s"]
    if td is not None:
        ax.axvline(td, color="r", lw=0.8, label=f"fronts differ by > {DIVERGENCE:.0%} from t = {td:.2f} s")
    r = summary["runout_m"]
    ax.set_title(
        f"{tag}: {len(rows)} members, width × (1 + k·{args.eps:g});\nrun-out {r['mean']:.3f} ± {r['std']:.3f} m "
        f"(range {r['relative_spread']:.1%})",
        fontsize=9,
    )
    ax.set_xlabel("t (s)")
    ax.set_ylabel("front from the gate (m)")
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "ensemble_fronts.png", dpi=130)
    report = {"out": str(out), "runout_m": summary["runout_m"], "divergence_time_s": td}
    if args.compare_with:
        other = json.loads((Path(args.compare_with) / "ensemble_summary.json").read_text())
        comparison = compare(summary, other)
        (out / "comparison.json").write_text(json.dumps(comparison, indent=2))
        report["comparison_runout"] = comparison.get("runout_m")
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
