"""The stability map: for each method, the largest time step that stays stable
against the cell size h, and what failure looks like past it, classified from granrs's own error
messages and metrics.

    .venv/bin/python studies/stability_map.py                 # docs/img/stability_map.{csv,png}
    .venv/bin/python studies/stability_map.py --quick         # fewer bisection steps (a check)
    .venv/bin/python studies/stability_map.py --plot-only     # redraw the PNG from the CSV

Families (short simulated times; every run is a fixed δt or a fixed CFL number):

(a) heap at rest (``validation/rheology.py``: a D-P layer inclined at 20° < α = 27°, 1 s) with the
    bi-projection at the default θ = 0.5 and at θ = 0 (Uzawa), and with the Papanastasiou
    regularised law (m = 1000 s); stable = no error and the creep detector's verdict 'at rest'
    (max speed < 1e-8 m/s after 1 s), failure = creep, Picard non-convergence, blow-up;
(b) pore-pressure diffusion (``validation/pore_pressure.py``: layer with a basal flux, exact 1D
    series, κ t/H² = 0.1) with the implicit (BDF2) and explicit (forward Euler) time schemes; a
    round-off-sized checkerboard (1e-9) in the initial p_f excites the x-modes of this x-invariant
    layer; stable = no error and a relative L2 error < 1 (bounded);
(c) the fluidised column (``granrs.cases.column``, paper's values) at ny = 16, 32 over 0.6 s with the
    adaptive step at CFL numbers 0.25 … 2: with the default guard cfl_abort = 1 and its 3 retries
    (a step ending above the guard is retaken with δt halved), with the guard and no retries, and
    with the guard lifted (cfl_abort = 100) to see what it prevents; the δt plotted is the median
    step of the run at the largest stable CFL number.

Each method is scanned over a fixed grid of δt (or CFL numbers), then both edges of its stable
range are bisected (geometric mean for δt, arithmetic for CFL; 3 steps each, 5 for the cheap
pore-pressure family): the largest stable
step, and the smallest one where a method also fails at small steps (Uzawa's Picard iteration
needs more iterations as δt shrinks). Every trial is a row of the CSV (outcome, the error message
or creep verdict, wall time); the summary table of docs/stability.md is printed at the end.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

import granrs
from granrs import Model, SimulationError, SolverError
from granrs.cases.column import ColumnCase, build_model
from granrs.validation.pore_pressure import KAPPA, pore_diffusion_error
from granrs.validation.rheology import REST_SPEED, creep_verdict, run_heap

ROOT = Path(__file__).resolve().parents[1]
FIELDS = [
    "family",
    "method",
    "n",
    "h_m",
    "dt_s",
    "cfl",
    "stable",
    "outcome",
    "metric_name",
    "metric",
    "steps",
    "wall_s",
    "message",
]


# ---------------------------------------------------------------------------------------------
# classification
# ---------------------------------------------------------------------------------------------
def classify(err: BaseException) -> str:
    """A failure class from granrs's error message (the order matters: a NaN increment of the
    Picard iteration is a blow-up)."""
    msg = str(err)
    if "pore pressure p_f" in msg:
        return "p_f instability"
    if "non-finite" in msg or "not finite" in msg or "NaN" in msg or " inf" in msg:
        return "blow-up"
    if "CFL number" in msg:
        return "CFL abort"
    if "Picard" in msg:
        return "Picard non-convergence"
    if "did not converge" in msg or "failed" in msg:
        return "solver non-convergence"
    return f"other ({type(err).__name__})"


def trial(family: str, method: str, n: int, h: float, dt: float, run, cfl: float = math.nan) -> dict:
    """Runs ``run()`` → (stable, outcome, metric_name, metric, steps, message, dt_used, cfl) and
    records it; a SimulationError/SolverError is classified."""
    t0 = time.perf_counter()
    try:
        stable, outcome, mname, metric, steps, message, dt_used, cfl = run()
    except (SimulationError, SolverError) as err:
        # an adaptive run's δt: the median of the steps it took before failing
        done = getattr(err, "history", {}).get("dt", [])
        stable, outcome, mname, metric, steps, message, dt_used, cfl = (
            False,
            classify(err),
            "",
            math.nan,
            getattr(err, "step", -1),
            str(err),
            float(np.median(done)) if math.isnan(dt) and len(done) else dt,
            cfl,
        )
    row = {
        "_x": dt,
        "family": family,
        "method": method,
        "n": n,
        "h_m": h,
        "dt_s": dt_used,
        "cfl": cfl,
        "stable": stable,
        "outcome": outcome,
        "metric_name": mname,
        "metric": metric,
        "steps": steps,
        "wall_s": time.perf_counter() - t0,
        "message": message,
    }
    print(
        f"  {method:38s} n={n:3d} dt={dt_used:.3e} cfl={cfl:.3g} -> {outcome:24s} ({row['wall_s']:.1f} s)"
        + ("" if stable else f"  [{message[:110]}]"),
        flush=True,
    )
    return row


def scan_and_bisect(evaluate, grid, iterations: int, rows: list, geometric: bool = True) -> None:
    """Evaluates the parameter values of ``grid``, then bisects the edges of the stable range:
    between its largest value and the next failing one above (the largest stable step), and
    between its smallest value and the failing one below, if any (a method can also fail at small
    steps: Uzawa's Picard iteration needs ∝ 1/δt iterations)."""
    done = [evaluate(v) for v in grid]
    rows.extend(done)
    ok = [r["_x"] for r in done if r["stable"]]
    bad = [r["_x"] for r in done if not r["stable"]]
    if not ok:
        return
    mid = (lambda a, b: math.sqrt(a * b)) if geometric else (lambda a, b: 0.5 * (a + b))
    above = [v for v in bad if v > max(ok)]
    if above:
        lo, hi = max(ok), min(above)
        for _ in range(iterations):
            r = evaluate(mid(lo, hi))
            rows.append(r)
            lo, hi = (r["_x"], hi) if r["stable"] else (lo, r["_x"])
    below = [v for v in bad if v < min(ok)]
    if below:
        lo, hi = max(below), min(ok)
        for _ in range(iterations):
            r = evaluate(mid(lo, hi))
            rows.append(r)
            lo, hi = (lo, r["_x"]) if r["stable"] else (r["_x"], hi)


# ---------------------------------------------------------------------------------------------
# (a) heap at rest
# ---------------------------------------------------------------------------------------------
HEAP_METHODS = {
    "heap: bi-projection, theta = 0.5": dict(plastic="projection", theta=0.5),
    "heap: bi-projection, Uzawa theta = 0": dict(plastic="projection", theta=0.0),
    "heap: Papanastasiou m = 1000 s": dict(plastic="papanastasiou", regularisation=1000.0, theta=0.0),
}


def heap_family(ns, iterations, rows, t_end=1.0):
    for method, kw in HEAP_METHODS.items():
        for n in ns:
            h = 0.1 / n

            def evaluate(dt, n=n, h=h, kw=kw, method=method):
                def run():
                    # a whole number of steps lands on t_end; the default Picard cap (1000)
                    steps = max(1, round(t_end / dt))
                    m, log = run_heap(20.0, n, dt=t_end / steps, t_end=t_end, picard_max_iterations=1000, **kw)
                    v = creep_verdict(log)
                    outcome = (
                        "stable" if v["verdict"] == "at rest" else ("creep" if v["verdict"] == "creeps" else "blow-up")
                    )
                    return (
                        v["verdict"] == "at rest",
                        outcome,
                        "creep_speed_m_s",
                        v["creep_speed"],
                        m.step_count,
                        v["message"],
                        t_end / steps,
                        math.nan,
                    )

                return trial("heap", method, n, h, dt, run)

            scan_and_bisect(evaluate, np.geomspace(1e-3, 1.0, 7), iterations, rows)


# ---------------------------------------------------------------------------------------------
# (b) pore-pressure diffusion
# ---------------------------------------------------------------------------------------------
def pore_family(ns, iterations, rows, t_end=0.064):
    for scheme in ("implicit", "explicit"):
        method = f"pore diffusion: {scheme}"
        for n in ns:
            h = 1.0 / n
            limit = h * h / (4 * KAPPA)

            def evaluate(dt, n=n, h=h, scheme=scheme, method=method, limit=limit):
                def run():
                    err, _, model = pore_diffusion_error(
                        n, dt_factor=dt / limit, time_scheme=scheme, t_end=t_end, seed=1e-9
                    )
                    used = model.time / model.step_count
                    ok = math.isfinite(err) and err < 1.0
                    return (
                        ok,
                        "stable" if ok else "blow-up",
                        "l2_rel_error",
                        err,
                        model.step_count,
                        f"relative L2 error {err:.3e} at t = {model.time:.3g} (dt/limit = {used / limit:.3f})",
                        used,
                        math.nan,
                    )

                return trial("pore", method, n, h, dt, run)

            # from a quarter of the explicit limit by factors of 2 up to a single step over the run
            grid = [0.25 * limit * 2.0**k for k in range(40) if 0.25 * limit * 2.0**k < 0.9 * t_end] + [t_end]
            scan_and_bisect(evaluate, grid, iterations, rows)


# ---------------------------------------------------------------------------------------------
# (c) fluidised column, adaptive step at a CFL number
# ---------------------------------------------------------------------------------------------
def with_numerics(model: Model, **changes) -> Model:
    """The same model and initial state with some numerical settings replaced."""
    m = Model(
        model.grid,
        model.dense,
        model.light,
        bc=model.bc,
        gravity=model.gravity,
        numerics=dataclasses.replace(model.numerics, **changes),
        threads=model.threads,
        rheology=model.rheology,
        pore_pressure=model.pore_pressure,
    )
    m.set_initial(phi=model.phi.copy(), pf=None if model.pore_pressure is None else model.pf.copy(), p=model.p.copy())
    return m


def column_family(
    nys,
    cfls,
    iterations,
    rows,
    t_end=0.6,
    guards=(
        (1.0, 3, "column: CFL, cfl_abort = 1, 3 retries (default)"),
        (1.0, 0, "column: CFL, cfl_abort = 1, no retries"),
        (100.0, 3, "column: CFL, guard lifted (cfl_abort = 100)"),
    ),
):
    for cfl_abort, retries, method in guards:
        for ny in nys:
            base = build_model(ColumnCase(ny=ny, t_end=t_end))
            h = base.grid.dy

            def evaluate(cfl, base=base, h=h, ny=ny, method=method, cfl_abort=cfl_abort, retries=retries):
                def run():
                    m = with_numerics(base, cfl=cfl, cfl_abort=cfl_abort, step_retries=retries)
                    log = m.advance(t_end=t_end)
                    dts = np.asarray(log["dt"])
                    retaken = int(np.count_nonzero(log["step_retries"]))
                    return (
                        True,
                        "stable",
                        "max_cfl",
                        float(np.max(log["cfl"])),
                        m.step_count,
                        f"reached t = {m.time:.3g} s, max CFL {np.max(log['cfl']):.3f}, {retaken} steps retaken",
                        float(np.median(dts)),
                        cfl,
                    )

                r = trial("column", method, ny, h, math.nan, run, cfl=cfl)
                r["cfl"], r["_x"] = cfl, cfl
                return r

            scan_and_bisect(evaluate, cfls, iterations, rows, geometric=False)


# ---------------------------------------------------------------------------------------------
# summary and plot
# ---------------------------------------------------------------------------------------------
def summarise(rows: list) -> list:
    """Per (method, n): the largest stable δt (and CFL), and the first failure above it."""
    out = []
    keys = list(dict.fromkeys((r["family"], r["method"], int(r["n"])) for r in rows))
    for fam, method, n in keys:
        rs = [r for r in rows if r["method"] == method and int(r["n"]) == n]
        par = (lambda r: float(r["cfl"])) if fam == "column" else (lambda r: float(r["dt_s"]))
        ok = [r for r in rs if str(r["stable"]) in ("True", "true", "1")]
        bad = [r for r in rs if str(r["stable"]) not in ("True", "true", "1")]
        best = max(ok, key=par) if ok else None
        above = [r for r in bad if best is None or par(r) > par(best)]
        fail = min(above, key=par) if above else None
        low_ok = min(ok, key=par) if ok else None
        below = [r for r in bad if low_ok is not None and par(r) < par(low_ok)]
        fail_low = max(below, key=par) if below else None
        out.append(
            {
                "family": fam,
                "method": method,
                "n": n,
                "h_m": float(rs[0]["h_m"]),
                "largest_stable_dt_s": float(best["dt_s"]) if best else math.nan,
                "largest_stable_cfl": float(best["cfl"]) if best and fam == "column" else math.nan,
                "first_failure_dt_s": float(fail["dt_s"]) if fail else math.nan,
                "first_failure_cfl": float(fail["cfl"]) if fail and fam == "column" else math.nan,
                "failure": fail["outcome"]
                if fail
                else ("none in the range tried" if best else "fails everywhere tried"),
                "fails_everywhere": best is None,
                "failure_message": fail["message"] if fail else "",
                "smallest_stable_dt_s": float(low_ok["dt_s"]) if low_ok else math.nan,
                "failure_below_dt_s": float(fail_low["dt_s"]) if fail_low else math.nan,
                "failure_below": fail_low["outcome"] if fail_low else "",
                "failure_below_message": fail_low["message"] if fail_low else "",
                "outcomes": ", ".join(sorted({r["outcome"] for r in bad})),
            }
        )
    return out


STYLE = {  # method -> (colour, linestyle)
    "heap: bi-projection, theta = 0.5": ("tab:blue", "-"),
    "heap: bi-projection, Uzawa theta = 0": ("tab:cyan", "--"),
    "heap: Papanastasiou m = 1000 s": ("tab:purple", ":"),
    "pore diffusion: implicit": ("tab:green", "-"),
    "pore diffusion: explicit": ("tab:olive", "--"),
    "column: CFL, cfl_abort = 1, 3 retries (default)": ("tab:red", "-"),
    "column: CFL, cfl_abort = 1, no retries": ("tab:brown", ":"),
    "column: CFL, guard lifted (cfl_abort = 100)": ("tab:orange", "--"),
}
FAILURE_MARKERS = {
    "blow-up": "X",
    "p_f instability": "P",
    "CFL abort": "^",
    "creep": "s",
    "Picard non-convergence": "D",
    "solver non-convergence": "v",
}


def plot(summary: list, rows: list, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(11.5, 7.0))
    fig.subplots_adjust(left=0.08, right=0.72, bottom=0.09, top=0.88)
    methods = list(dict.fromkeys(s["method"] for s in summary))
    for mi, method in enumerate(methods):
        colour, ls = STYLE.get(method, ("k", "-"))
        # methods that fail everywhere share the smallest δt: spread their markers a little in h
        shift = 1.0 + 0.07 * (mi - len(methods) / 2)
        ss = sorted((s for s in summary if s["method"] == method), key=lambda s: s["h_m"])
        h = np.array([s["h_m"] for s in ss])
        dt = np.array([s["largest_stable_dt_s"] for s in ss])
        ax.plot(h, dt, color=colour, ls=ls, marker="o", ms=6, lw=1.8, label=method)
        for s in ss:
            if s["fails_everywhere"]:
                # no stable step in the range: the smallest step tried, with its failure
                tried = [r for r in rows if r["method"] == method and int(r["n"]) == s["n"]]
                low = min(tried, key=lambda r: float(r["dt_s"]))
                ax.plot(
                    [s["h_m"] * shift],
                    [float(low["dt_s"])],
                    marker=FAILURE_MARKERS.get(low["outcome"], "*"),
                    ms=11,
                    color=colour,
                    mec="k",
                    mew=0.8,
                    ls="none",
                )
                if s is ss[0]:
                    ax.annotate(
                        f"{method.split(': ')[-1]}: fails at every δt tried\n({s['outcomes']})",
                        (s["h_m"] * shift, float(low["dt_s"])),
                        textcoords="offset points",
                        xytext=(8, -26 if "Papa" in method else 10),
                        fontsize=7,
                        color=colour,
                    )
                continue
            if math.isfinite(s["failure_below_dt_s"]):
                ax.plot(
                    [s["h_m"]],
                    [s["failure_below_dt_s"]],
                    marker=FAILURE_MARKERS.get(s["failure_below"], "*"),
                    ms=10,
                    color=colour,
                    mec="k",
                    mew=0.8,
                    ls="none",
                    alpha=0.9,
                )
                ax.plot(
                    [s["h_m"]] * 2, [s["failure_below_dt_s"], s["smallest_stable_dt_s"]], color=colour, lw=0.8, ls=":"
                )
                if s is ss[0]:
                    ax.annotate(
                        f"Uzawa: {s['failure_below']} below {s['smallest_stable_dt_s']:.2g} s"
                        if "Uzawa" in method
                        else f"{s['failure_below']} below {s['smallest_stable_dt_s']:.2g} s",
                        (s["h_m"], s["failure_below_dt_s"]),
                        textcoords="offset points",
                        xytext=(-25, 10),
                        fontsize=7,
                        color=colour,
                    )
            if math.isfinite(s["first_failure_dt_s"]):
                fdt = s["first_failure_dt_s"]
                if s["family"] == "column":
                    # an adaptive run that fails does so in its first steps, whose δt is not
                    # comparable with the median of a whole run: drawn at the stable run's δt
                    # scaled by the ratio of the CFL numbers
                    fdt = s["largest_stable_dt_s"] * s["first_failure_cfl"] / s["largest_stable_cfl"]
                ax.plot(
                    [s["h_m"]],
                    [fdt],
                    marker=FAILURE_MARKERS.get(s["failure"], "*"),
                    ms=10,
                    color=colour,
                    mec="k",
                    mew=0.8,
                    ls="none",
                    alpha=0.9,
                )
            elif s["failure"] == "none in the range tried":
                ax.annotate(
                    "",
                    xy=(s["h_m"], s["largest_stable_dt_s"] * 2.2),
                    xytext=(s["h_m"], s["largest_stable_dt_s"]),
                    arrowprops=dict(arrowstyle="->", color=colour, lw=1.5),
                )
            if s["family"] == "column" and math.isfinite(s["largest_stable_cfl"]):
                ax.annotate(
                    f"CFL {s['largest_stable_cfl']:.2g}",
                    (s["h_m"], s["largest_stable_dt_s"]),
                    textcoords="offset points",
                    xytext=(7, 5) if "lifted" in method else ((7, -11) if "no retries" in method else (-40, -14)),
                    fontsize=7,
                    color=colour,
                )
    # reference slopes: h through the column at its guard without retries, h² through the explicit diffusion
    hs = np.array(sorted({s["h_m"] for s in summary}))
    hh = np.geomspace(hs.min() / 1.3, hs.max() * 1.3, 10)

    def anchor(method, fallback):
        pts = [
            (s["h_m"], s["largest_stable_dt_s"])
            for s in summary
            if s["method"] == method and math.isfinite(s["largest_stable_dt_s"])
        ]
        if not pts:
            return fallback
        return math.exp(np.mean([math.log(d) - p * math.log(h) for h, d in pts for p in [fallback[1]]])), fallback[1]

    for method, (c0, p) in (
        ("column: CFL, cfl_abort = 1, no retries", (0.2, 1)),
        ("pore diffusion: explicit", (0.25, 2)),
    ):
        c, p = anchor(method, (c0, p))
        ax.plot(hh, c * hh**p, color="0.45", lw=1, ls=(0, (6, 3)) if p == 1 else (0, (1, 2)), zorder=0)
        ax.annotate(
            "∝ h" if p == 1 else "∝ h²",
            (hh[-1], c * hh[-1] ** p),
            fontsize=9,
            color="0.35",
            xytext=(3, 0),
            textcoords="offset points",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("cell size h (m)  [heap: layer 0.1 m; pore diffusion: unit box, κ = 1; column: 0.45 m high]")
    ax.set_ylabel("largest stable δt (s)")
    ax.set_title(
        "granrs stability map: largest stable δt against h (circles and lines); filled markers: the first failing\n"
        "step above it and how granrs reported it (below it: a failure at small δt); arrows: no failure up to the "
        "largest δt tried.\nColumn: adaptive δt, median step of the run at the largest stable CFL number (labelled)",
        fontsize=9,
    )
    ax.grid(alpha=0.3, which="both")
    leg1 = ax.legend(
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize=8,
        title="method (largest stable δt)",
        title_fontsize=8,
        frameon=False,
    )
    ax.add_artist(leg1)
    handles = [
        Line2D([], [], marker=mk, color="0.6", mec="k", ls="none", ms=9, label=name)
        for name, mk in FAILURE_MARKERS.items()
    ]
    ax.legend(
        handles=handles,
        loc="lower left",
        bbox_to_anchor=(1.01, 0.0),
        fontsize=8,
        title="failure (granrs's report)",
        title_fontsize=8,
        frameon=False,
    )
    fig.savefig(path, dpi=130)
    plt.close(fig)


def markdown(summary: list) -> str:
    lines = [
        "| method | n | h (m) | largest stable δt (s) | CFL | first failure above it | δt there (s) | failure below the stable range |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in summary:
        cfl = f"{s['largest_stable_cfl']:.3g}" if math.isfinite(s["largest_stable_cfl"]) else ""
        if math.isfinite(s["first_failure_cfl"]):
            cfl += f" (fails at {s['first_failure_cfl']:.3g})"
        dt = f"{s['largest_stable_dt_s']:.3g}" if math.isfinite(s["largest_stable_dt_s"]) else "none"
        fdt = f"{s['first_failure_dt_s']:.3g}" if math.isfinite(s["first_failure_dt_s"]) else ""
        low = (
            f"{s['failure_below']} at {s['failure_below_dt_s']:.3g} s (stable from {s['smallest_stable_dt_s']:.3g} s)"
            if s["failure_below"]
            else ""
        )
        fail = s["failure"] if not s["fails_everywhere"] else f"fails everywhere tried: {s['outcomes']}"
        lines.append(f"| {s['method']} | {s['n']} | {s['h_m']:.4g} | {dt} | {cfl} | {fail} | {fdt} | {low} |")
    return "\n".join(lines)


def read_rows(path: Path) -> list:
    with open(path) as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k in ("h_m", "dt_s", "cfl", "metric", "wall_s"):
            r[k] = float(r[k]) if r[k] not in ("", "nan") else math.nan
        r["stable"] = r["stable"] == "True"
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(ROOT / "docs/img"), help="folder of stability_map.csv and .png")
    ap.add_argument(
        "--quick", action="store_true", help="1 bisection step per edge instead of 3 (a check of the script)"
    )
    ap.add_argument("--plot-only", action="store_true", help="redraw the PNG from an existing CSV")
    ap.add_argument(
        "--families",
        default="heap,pore,column",
        help="comma-separated subset of heap,pore,column (an existing CSV keeps the other families' rows)",
    )
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path, png_path = out / "stability_map.csv", out / "stability_map.png"
    t0 = time.perf_counter()
    if args.plot_only:
        rows = read_rows(csv_path)
    else:
        k = 1 if args.quick else 3
        fams = set(args.families.split(","))
        rows: list = []
        if "pore" in fams:
            print("(b) pore-pressure diffusion", flush=True)
            pore_family([16, 32, 64, 128], k + 2, rows)
        if "heap" in fams:
            print("(a) heap at rest", flush=True)
            heap_family([16, 32, 64], k, rows)
        if "column" in fams:
            print("(c) fluidised column", flush=True)
            column_family([16, 32], [0.25, 0.5, 0.75, 1.0, 1.5, 2.0], k, rows)
        if csv_path.exists() and fams != {"heap", "pore", "column"}:
            kept = [r for r in read_rows(csv_path) if r["family"] not in fams]
            rows = kept + rows
        with open(csv_path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=FIELDS)
            w.writeheader()
            for r in rows:
                w.writerow({k2: (f"{v:.6g}" if isinstance(v, float) else v) for k2, v in r.items() if k2 in FIELDS})
    summary = summarise(rows)
    plot(summary, rows, png_path)
    wall = time.perf_counter() - t0
    print(markdown(summary))
    print(
        f"\nwrote {csv_path} ({len(rows)} trials) and {png_path} in {wall:.0f} s (granrs {granrs.__version__}, "
        f"rest criterion {REST_SPEED:g} m/s)",
        file=sys.stderr,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
