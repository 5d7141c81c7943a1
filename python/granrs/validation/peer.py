"""Cross-code checks: granrs's dry column collapse against the same column computed with Basilisk
(the 2D models, :func:`peer_dry_column`), and against IMEX_SfloW2D v2, an independent shallow-layer
code (the depth-averaged model, :func:`peer_depth_averaged`, at the end of this module).

The reference (data/basilisk_dry_column/, README.md there) is the final deposit and the fronts of a
dry column computed with Basilisk, an independent solver (VOF interface, regularised
Drucker–Prager viscosity η = min(μ p/(√2 D₂) + η_s, η_max), regularised Coulomb base
η ∂u/∂y = μ_w p u/(|u| + ε)). The shared set-up (:func:`peer_case`): a column L_c = 0.20 m ×
H_c = 0.40 m of mixture density φρ_s = 1450 kg m⁻³ released from rest; Drucker–Prager with
μ = tan 27° and η_s = 0.1 Pa s; Coulomb base μ_w = tan 15°; **free-slip back wall** and right
wall; domain 6 H_c × 2 H_c = 2.4 m × 0.8 m; 32 or 64 cells per H_c (Δ = 12.5 or 6.25 mm); run to
rest (largest granular speed below 5 mm s⁻¹ for 0.05 s). granrs solves it with its own numerics
(level set, exact plastic projection, unregularised Coulomb walls, a free-slip lid at y = 0.8 m
where Basilisk's top is open): nothing is fitted to the reference.

Both deposits are compared as the granular *volume* per column of cells (Basilisk's Σ_j f Δ,
granrs's :func:`granrs.observables.volume_profile`), on the reference's column centres, x measured
from the gate:

* pointwise relative difference |h − h_B| / h_B and the L1 difference Σ|h − h_B| / Σ h_B over the
  bulk, from the back wall to ``BULK_END_M`` = 0.3 m past the gate;
* the centre of mass x_c = Σ h x / Σ h from the gate, the back-wall height (first column) and the
  height at the gate;
* the thickness fronts (farthest x where h > τ) at τ = Δ/2, 1, 2, 5, 10 and 20 mm;
* the front against time: granrs's front.csv (every 0.01 s) read at the reference's times (every
  0.05 s) for the three fronts the reference records (h > Δ/2, h > 2 cm, the end of the material
  on the lowest row of cells).

Acceptance (the cross-code tolerance of the task, against a 5–7 % agreement seen near the gate
and the back wall): at the finer resolution every point of the bulk within ``BULK_TOLERANCE`` =
10 %, and at every resolution with reference data the centre of mass within
``CENTRE_OF_MASS_TOLERANCE`` = 10 %. A resolution without reference data is run and reported with
``passed`` None. The tail (beyond the bulk) is reported, not judged: the two codes' thin-front
definitions do not converge (docs/validation.md, "Cross-code check: Basilisk").
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import tempfile
from pathlib import Path
from typing import Any, Optional

import numpy as np

from .. import observables as obs
from .._granrs import ParameterError
from ..boundary import CoulombWall
from ..cases.column import (
    ColumnCase,
    ColumnGeometry,
    Fluidisation,
    Grains,
    build_depth_averaged,
    column_rheology,
    run_column,
)
from ..depth_averaged import DepthAveraged
from ..options import parse_options

DATA = Path(__file__).parent / "data" / "basilisk_dry_column"
#: the shared set-up (data/basilisk_dry_column/README.md)
WIDTH, HEIGHT, LENGTH, DOMAIN_HEIGHT = 0.20, 0.40, 2.4, 0.8
#: resolutions of the reference, in cells per H_c
REFERENCE_RESOLUTIONS = (32, 64)
#: end of the bulk of the deposit (m past the gate) for the pointwise check
BULK_END_M = 0.3
BULK_TOLERANCE = 0.10
CENTRE_OF_MASS_TOLERANCE = 0.10
#: thicknesses (m) of the compared fronts besides Δ/2
FRONT_THICKNESSES_M = obs.FRONT_THICKNESSES_M


def peer_case(cells_per_hc: int, threads: int = 1, t_end: float = 3.0, options: Optional[dict] = None):
    """The granrs ColumnCase of the shared set-up at ``cells_per_hc`` cells per H_c (the grid has
    ny = 2 cells_per_hc rows over the 0.8 m domain, nx = 6 cells_per_hc columns over 2.4 m).
    ``options``: model options changed from granrs's defaults by their schema keys
    (``ColumnCase.with_options``, e.g. ``{"proximal_restarts": 20}``), for a sensitivity run; the
    validation case itself runs the defaults."""
    if not isinstance(cells_per_hc, int) or isinstance(cells_per_hc, bool) or not 4 <= cells_per_hc <= 512:
        raise ParameterError(
            f"invalid parameter `n` = {cells_per_hc!r}: allowed an integer number of cells per H_c in [4, 512]"
        )
    case = ColumnCase(
        geometry=ColumnGeometry(aspect_ratio=HEIGHT / WIDTH, width=WIDTH, length=LENGTH, height=DOMAIN_HEIGHT),
        grains=Grains(solid_fraction=0.58, density=2500.0),
        fluidisation=Fluidisation(fluidised=False),
        ny=2 * cells_per_hc,
        back_wall="free-slip",
        rheology=dataclasses.replace(column_rheology(), friction_angle=27.0, viscosity=0.1),
        base=CoulombWall(15.0),
        t_end=t_end,
        threads=threads,
    )
    return case.with_options(**options) if options else case


def load_reference(cells_per_hc: int) -> Optional[dict]:
    """The Basilisk deposit and fronts at ``cells_per_hc`` (None where there are none):
    ``x`` (column centres from the gate), ``h``, ``dx`` and the front table ``fronts`` (arrays by
    the CSV's column names)."""
    dep, fr = DATA / f"deposit_{cells_per_hc}_cells_per_Hc.csv", DATA / f"front_{cells_per_hc}_cells_per_Hc.csv"
    if not dep.exists():
        return None
    d = np.genfromtxt(dep, delimiter=",", names=True)
    f = read_csv_columns(fr)
    return {"x": d["x_from_gate_m"], "h": d["h_m"], "dx": HEIGHT / cells_per_hc, "fronts": f}


def read_csv_columns(path: Path) -> dict:
    """The columns of a CSV file of numbers by their header's names, verbatim (numpy's
    ``genfromtxt(names=True)`` drops the dot of ``front_h0.5cell_m``); empty cells are NaN."""
    lines = [line for line in Path(path).read_text().splitlines() if line and not line.startswith("#")]
    names = lines[0].split(",")
    rows = [[float(v) if v not in ("", "nan") else math.nan for v in line.split(",")] for line in lines[1:]]
    data = np.array(rows, dtype=float).reshape(len(rows), len(names))
    return {name: data[:, k] for k, name in enumerate(names)}


def read_run(folder: Path) -> dict:
    """A granrs column run's final volume profile (profiles.csv's hvol_final), front time series
    (front.csv) and summary."""
    header = (folder / "profiles.csv").read_text().splitlines()[0].split(",")
    p = np.genfromtxt(folder / "profiles.csv", delimiter=",", skip_header=1)
    f = read_csv_columns(folder / "front.csv")
    summary = json.loads((folder / "summary.json").read_text())
    return {"x": p[:, 0], "h": p[:, header.index("hvol_final")], "dx": summary["h_m"], "fronts": f, "summary": summary}


def _profile_observables(x: np.ndarray, h: np.ndarray, dx: float) -> dict:
    x0 = float(x[0] - dx / 2)  # the back wall, from the gate
    out = {
        "centre_of_mass_m": obs.centre_of_mass(h, dx, x0),
        "h_back_wall_m": float(h[0]),
        "h_gate_m": obs.height_at(h, dx, 0.0, x0),
        "area_m2": float(np.sum(h) * dx),
        "front_h_half_cell_m": obs.thickness_front(h, dx, dx / 2, x0),
    }
    for tau in FRONT_THICKNESSES_M:
        out[f"front_h{1e3 * tau:g}mm_m"] = obs.thickness_front(h, dx, tau, x0)
    for q in obs.DEPOSIT_QUANTILES:
        out[f"q{100 * q:g}_m"] = obs.area_quantile(h, dx, q, x0)
    return out


def _rel(a: float, b: float) -> float:
    return (a - b) / abs(b) if b != 0 and math.isfinite(a) and math.isfinite(b) else math.nan


def compare(run: dict, ref: dict, finer: bool) -> dict:
    """Point-by-point comparison of a granrs run (:func:`read_run`) with the reference
    (:func:`load_reference`) at the same resolution.

    Parameters
    ----------
    run, ref : dict
        ``x`` (column centres from the gate), ``h`` (volume per column), ``dx``, ``fronts``.
    finer : bool
        Whether this is the finest resolution of the reference (the pointwise bulk tolerance
        applies there only).

    Returns
    -------
    dict
        The metrics, with ``passed`` (bool) and the reason of a failure in ``failures``.
    """
    xr, hr = np.asarray(ref["x"]), np.asarray(ref["h"])
    hg = np.interp(xr, np.asarray(run["x"]), np.asarray(run["h"]), right=0.0)
    bulk = xr <= BULK_END_M
    rel = np.abs(hg[bulk] - hr[bulk]) / hr[bulk]
    worst = int(np.argmax(rel))
    og, orf = _profile_observables(xr, hg, ref["dx"]), _profile_observables(xr, hr, ref["dx"])
    m: dict[str, Any] = {
        "bulk_end_m": BULK_END_M,
        "bulk_max_rel_diff": float(rel.max()),
        "bulk_max_rel_diff_at_m": float(xr[bulk][worst]),
        "bulk_l1_rel_diff": float(np.sum(np.abs(hg[bulk] - hr[bulk])) / np.sum(hr[bulk])),
        "tail_l1_rel_diff": float(np.sum(np.abs(hg[~bulk] - hr[~bulk])) / np.sum(hr[~bulk])),
        "tail_area_granrs_m2": float(np.sum(hg[~bulk]) * ref["dx"]),
        "tail_area_basilisk_m2": float(np.sum(hr[~bulk]) * ref["dx"]),
        "granrs": og,
        "basilisk": orf,
        "rel_diff": {k: _rel(og[k], orf[k]) for k in og},
        "abs_diff_m": {k: og[k] - orf[k] for k in og},
    }
    # the tail's film: its thickness at 1 m, in mm and in cells (a film of the same thickness in mm
    # at both resolutions is a property of the law; one of a fixed number of cells, of the numerics)
    for xx in (0.5, 1.0, 1.5):
        for name, h in (("granrs", hg), ("basilisk", hr)):
            v = float(np.interp(xx, xr, h))
            m.setdefault("film", {})[f"{name}_h_at_{xx:g}m_mm"] = 1e3 * v
            m["film"][f"{name}_h_at_{xx:g}m_cells"] = v / ref["dx"]
    # fronts against time, at the reference's times within both records
    ft, fr = run["fronts"], ref["fronts"]
    pairs = (
        ("front_h_half_cell_m", "front_h0.5cell_m"),
        ("front_h_2cm_m", "front_h20mm_m"),
        ("front_first_row_m", "front_m"),
    )
    t = fr["t_s"][fr["t_s"] <= ft["t_s"][-1] + 1e-9]
    m["front_vs_time"] = {}
    for rk, gk in pairs:
        if gk not in ft:
            continue
        d = np.interp(t, ft["t_s"], np.nan_to_num(ft[gk])) - fr[rk][: t.size]
        apart = np.nonzero(np.abs(d) > 0.05)[0]
        m["front_vs_time"][rk] = {
            "max_abs_diff_m": float(np.max(np.abs(d))) if d.size else math.nan,
            "final_diff_m": float(d[-1]) if d.size else math.nan,
            "first_apart_5cm_s": float(t[apart[0]]) if apart.size else None,
        }
    failures = []
    com = abs(m["rel_diff"]["centre_of_mass_m"])
    if not com <= CENTRE_OF_MASS_TOLERANCE:
        failures.append(
            f"centre of mass {og['centre_of_mass_m']:.4f} m vs {orf['centre_of_mass_m']:.4f} m "
            f"({com:.1%} > {CENTRE_OF_MASS_TOLERANCE:.0%})"
        )
    if finer and not m["bulk_max_rel_diff"] <= BULK_TOLERANCE:
        failures.append(
            f"bulk {m['bulk_max_rel_diff']:.1%} > {BULK_TOLERANCE:.0%} at x = {m['bulk_max_rel_diff_at_m']:.3f} m"
        )
    m["failures"] = failures
    m["passed"] = not failures
    return _finite(m)


def _finite(v):
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def run_or_load(
    cells_per_hc: int,
    out: Path,
    threads: int = 1,
    t_end: float = 3.0,
    progress: bool = False,
    options: Optional[dict] = None,
) -> dict:
    """granrs's run of the shared set-up in ``out/n{cells_per_hc}`` (run first if its summary is not
    there), as :func:`read_run`."""
    folder = Path(out) / f"n{cells_per_hc}"
    if not (folder / "summary.json").exists():
        run_column(peer_case(cells_per_hc, threads, t_end, options), folder, progress=progress)
    return read_run(folder)


def peer_dry_column(
    n=REFERENCE_RESOLUTIONS,
    threads: int = 1,
    t_end: float = 3.0,
    out: Optional[str] = None,
    options: Optional[dict] = None,
):
    """``granrs validate peer-dry-column``: runs the shared set-up at ``n`` cells per H_c and
    compares each with the reference at that resolution (:func:`compare`). Returns (metrics,
    reference, passed): passed is None when no run has reference data, else True only when every
    compared run passes. ``options`` (see :func:`peer_case`) makes it a sensitivity run; the
    record says which options were changed."""
    ns = [int(k) for k in (n if isinstance(n, (list, tuple)) else [n])]
    for k in ns:
        peer_case(k, options=options)  # the parameters' check, before any run
    finest = max((k for k in ns if load_reference(k) is not None), default=None)
    tmp = tempfile.TemporaryDirectory() if out is None else None
    base = Path(tmp.name) if tmp is not None else Path(str(out))
    metrics: dict[str, Any] = {"cells_per_hc": ns, "options": dict(options or {}), "runs": {}}
    verdicts = []
    try:
        for k in ns:
            run = run_or_load(k, base, threads, t_end, options=options)
            s = run["summary"]
            entry = {
                "stop_reason": s["stop_reason"],
                "t_end_s": s["t_end_s"],
                "wall_s": s["wall_s"],
                "nx": s["nx"],
                "ny": s["ny"],
                "mass_rel_error": s["mass_rel_error"],
                "runout_m": s["runout_m"],
                "observables": s["observables"],
            }
            ref = load_reference(k)
            if ref is None:
                entry["passed"] = None
            else:
                entry.update(compare(run, ref, finer=(k == finest)))
                verdicts.append(entry["passed"])
            metrics["runs"][str(k)] = entry
    finally:
        if tmp is not None:
            tmp.cleanup()
    passed = None if not verdicts else all(verdicts)
    reference = {
        "solver": "Basilisk (VOF, regularised Drucker-Prager and Coulomb base, eps = 1e-3), "
        "data/basilisk_dry_column/README.md",
        "resolutions_cells_per_hc": list(REFERENCE_RESOLUTIONS),
        "acceptance": f"bulk (back wall to {BULK_END_M} m past the gate) within {BULK_TOLERANCE:.0%} pointwise "
        f"at the finest resolution with data; centre of mass within "
        f"{CENTRE_OF_MASS_TOLERANCE:.0%} at every resolution with data",
        "profile": "volume per column of cells in both codes",
    }
    return metrics, reference, passed


def plot_comparison(runs: dict, png: Path) -> None:
    """One figure: both codes' final deposits (top) and fronts against time (bottom) at each
    resolution of ``runs`` (cells per H_c → :func:`read_run`)."""
    import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after its backend is chosen

    fig, (a, b) = plt.subplots(2, 1, figsize=(9, 7.5))
    for c, (k, run) in enumerate(sorted(runs.items())):
        ref = load_reference(k)
        a.plot(run["x"], run["h"], f"C{c}-", lw=1.8, label=f"granrs, {k} cells per H_c")
        if ref is not None:
            a.plot(ref["x"], ref["h"], f"C{c}--", lw=1.2, label=f"Basilisk, {k} cells per H_c")
        f = run["fronts"]
        b.plot(f["t_s"], f["front_m"], f"C{c}-", lw=1.8, label=f"granrs {k}: lowest row")
        b.plot(f["t_s"], f["front_h20mm_m"], f"C{c}-", lw=0.9, alpha=0.7, label=f"granrs {k}: h > 2 cm")
        b.plot(f["t_s"], f["front_h0.5cell_m"], f"C{c}:", lw=1.2, label=f"granrs {k}: h > Δ/2")
        if ref is not None:
            r = ref["fronts"]
            b.plot(r["t_s"], r["front_first_row_m"], f"C{c}o", ms=3, mfc="none", label=f"Basilisk {k}: lowest row")
            b.plot(r["t_s"], r["front_h_2cm_m"], f"C{c}s", ms=2.5, label=f"Basilisk {k}: h > 2 cm")
            b.plot(r["t_s"], r["front_h_half_cell_m"], f"C{c}^", ms=2.5, mfc="none", label=f"Basilisk {k}: h > Δ/2")
    a.axvline(0.0, color="grey", lw=0.8)
    a.axvline(BULK_END_M, color="k", ls=":", lw=0.8, label=f"end of the bulk ({BULK_END_M} m)")
    a.set(
        xlabel="x − L_c (m), gate at 0",
        ylabel="deposit h (m), volume per column",
        title="Dry column, free-slip back wall: granrs against Basilisk",
    )
    a.grid(alpha=0.3)
    a.legend(fontsize=7)
    b.set(xlabel="t (s)", ylabel="front from the gate (m)")
    b.grid(alpha=0.3)
    b.legend(fontsize=6, ncol=2, loc="upper left")
    fig.tight_layout()
    Path(png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=120)
    plt.close(fig)


# ---- the depth-averaged model against an independent shallow-layer code (IMEX_SfloW2D v2)

#: the shallow-layer reference (data/imex_sflow2d_dry_column/README.md): the dry column with k = 1
#: and a Coulomb base at tan 15° on a 6 m channel, cells of 2 mm (and 1 mm)
DA_DATA = Path(__file__).parent / "data" / "imex_sflow2d_dry_column"
#: the reference's resolutions in cells across L_c = 0.20 m (2 mm and 1 mm cells) and their files
DA_REFERENCE_FILES = {
    100: ("front_tan15.csv", "deposit_tan15.csv"),
    200: ("front_tan15_dx1mm.csv", "deposit_tan15_dx1mm.csv"),
}
DA_LENGTH, DA_BASE_ANGLE, DA_T_END = 6.0, 15.0, 3.0
#: the fronts compared, by thickness (m)
DA_FRONT_THICKNESSES_M = (1e-3, 5e-3)
#: acceptance: run-outs and the centre of mass within 2 % (the two codes' run-outs at 2 and 1 mm
#: cells differ by 0.2 %, the reference's own discretisation error), the deposit's profile within
#: 5 % in L1 (Σ|h − h_ref| / Σ h_ref over the channel)
DA_RUNOUT_TOLERANCE = 0.02
DA_CENTRE_OF_MASS_TOLERANCE = 0.02
DA_PROFILE_TOLERANCE = 0.05


def peer_depth_averaged_case(n: int = 100):
    """The ColumnCase of the shared scene with the depth-averaged model: the paper's column
    (0.20 × 0.40 m), dry, Coulomb base at 15°, the closure 'hydrostatic' (k = 1, the peer's
    only one), a 6 m channel, ``n`` cells across L_c (100: the reference's 2 mm cells)."""
    if not isinstance(n, int) or isinstance(n, bool) or not 10 <= n <= 1000:
        raise ParameterError(
            f"invalid parameter `n` = {n!r}: allowed an integer number of cells across L_c in [10, 1000]"
        )
    return ColumnCase(
        geometry=ColumnGeometry(aspect_ratio=HEIGHT / WIDTH, width=WIDTH, length=DA_LENGTH),
        fluidisation=Fluidisation(fluidised=False),
        model="depth-averaged",
        base=CoulombWall(DA_BASE_ANGLE),
        depth_averaged=DepthAveraged(closure="hydrostatic", resolution=n),
        t_end=DA_T_END,
    )


def load_depth_averaged_reference(n: int) -> dict:
    """The peer's fronts (``t``, ``front_1mm``, ``front_5mm``: x from the back wall) and deposit
    (``x``, ``h``) at ``n`` cells across L_c (the 1 mm cells for any n but 100)."""
    front, deposit = DA_REFERENCE_FILES[100 if n == 100 else 200]
    f = read_csv_columns(DA_DATA / front)
    d = read_csv_columns(DA_DATA / deposit)
    return {
        "t": f["t_s"],
        "front_1mm": f["front_1mm_x_m"],
        "front_5mm": f["front_5mm_x_m"],
        "x": d["x_m"],
        "h": d["h_m"],
        "file": deposit,
    }


def cell_front(x: np.ndarray, h: np.ndarray, tau: float) -> float:
    """The peer's front: the centre of the last cell whose thickness exceeds ``tau``."""
    above = np.nonzero(h > tau)[0]
    return float(x[above[-1]]) if above.size else math.nan


def run_depth_averaged_peer(n: int = 100, times=None) -> dict:
    """The shared scene run with granrs's depth-averaged model to t = 3 s: the fronts at ``times``
    (the reference's, every 0.05 s) and the final deposit."""
    m = build_depth_averaged(peer_depth_averaged_case(n))
    times = np.arange(0.0, DA_T_END + 1e-9, 0.05) if times is None else np.asarray(times)
    fronts: dict[float, list] = {tau: [] for tau in DA_FRONT_THICKNESSES_M}
    for t in times:
        if t > m.time:
            m.advance(float(t))
        for tau in DA_FRONT_THICKNESSES_M:
            fronts[tau].append(cell_front(m.x, m.h, tau))
    return {
        "t": times,
        "front_1mm": np.array(fronts[1e-3]),
        "front_5mm": np.array(fronts[5e-3]),
        "x": m.x.copy(),
        "h": m.h.copy(),
        "mass_rel_error": abs(m.mass() - WIDTH * HEIGHT) / (WIDTH * HEIGHT),
        "steps": m.step_count,
    }


def peer_depth_averaged(n: int = 100, threads: int = 1):
    """``granrs validate peer-depth-averaged``: the dry column of the shared scene with granrs's
    depth-averaged model (k = 1, Coulomb base at tan 15°) against IMEX_SfloW2D v2: the 1 mm and
    5 mm fronts against time, the run-outs, the deposit's centre of mass and its profile.
    Returns (metrics, reference, passed). ``threads`` is unused (the model is serial)."""
    ref = load_depth_averaged_reference(n)
    run = run_depth_averaged_peer(n, ref["t"])
    h = np.interp(ref["x"], run["x"], run["h"], right=0.0)
    com, com_ref = float(np.sum(h * ref["x"]) / np.sum(h)), float(np.sum(ref["h"] * ref["x"]) / np.sum(ref["h"]))
    metrics: dict[str, Any] = {
        "n_cells_across_width": n,
        "dx_m": WIDTH / n,
        "reference_file": ref["file"],
        "steps": run["steps"],
        "mass_rel_error": run["mass_rel_error"],
        "centre_of_mass_x_m": {"granrs": com, "peer": com_ref, "rel_diff": (com - com_ref) / com_ref},
        "profile_l1_rel_diff": float(np.sum(np.abs(h - ref["h"])) / np.sum(ref["h"])),
        "runout_m": {},
        "front_vs_time": {},
    }
    for key in ("front_1mm", "front_5mm"):
        got, want = run[key] - WIDTH, ref[key] - WIDTH
        moving = ref["t"] > 0
        metrics["runout_m"][key] = {
            "granrs": float(got[-1]),
            "peer": float(want[-1]),
            "rel_diff": float((got[-1] - want[-1]) / want[-1]),
        }
        metrics["front_vs_time"][key] = {
            "max_abs_diff_m": float(np.max(np.abs(got - want)[moving])),
            "max_rel_diff_after_0.25s": float(np.max((np.abs(got - want) / want)[ref["t"] >= 0.25])),
        }
    failures = []
    for key, r in metrics["runout_m"].items():
        if not abs(r["rel_diff"]) <= DA_RUNOUT_TOLERANCE:
            failures.append(f"{key} run-out {r['granrs']:.4f} m vs {r['peer']:.4f} m ({r['rel_diff']:+.1%})")
    if not abs(metrics["centre_of_mass_x_m"]["rel_diff"]) <= DA_CENTRE_OF_MASS_TOLERANCE:
        failures.append(f"centre of mass {com:.4f} m vs {com_ref:.4f} m")
    if not metrics["profile_l1_rel_diff"] <= DA_PROFILE_TOLERANCE:
        failures.append(f"profile L1 {metrics['profile_l1_rel_diff']:.1%} > {DA_PROFILE_TOLERANCE:.0%}")
    metrics["failures"] = failures
    reference = {
        "solver": "IMEX_SfloW2D v2 (central-upwind FV, IMEX Runge-Kutta, k = 1, Coulomb tan 15°), "
        "data/imex_sflow2d_dry_column/README.md",
        "acceptance": f"run-outs at 1 and 5 mm and the deposit's centre of mass within {DA_RUNOUT_TOLERANCE:.0%}, "
        f"the deposit's profile within {DA_PROFILE_TOLERANCE:.0%} in L1",
        "gravity": "granrs g = 9.81 m/s², the peer's buoyancy-reduced 9.802 (times differ by 0.04 %)",
    }
    return _finite(metrics), reference, not failures


def plot_depth_averaged(n: int, png: Path) -> dict:
    """The figure of the depth-averaged comparison: the deposits (top) and the 1 mm and 5 mm fronts
    against time (bottom), granrs against the peer; returns the case's metrics."""
    import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after its backend is chosen

    ref = load_depth_averaged_reference(n)
    run = run_depth_averaged_peer(n, ref["t"])
    metrics, _, passed = peer_depth_averaged(n)
    fig, (a, b) = plt.subplots(2, 1, figsize=(9, 7))
    a.plot(ref["x"] - WIDTH, ref["h"], "k-", lw=2.2, label="IMEX_SfloW2D v2 (k = 1)")
    a.plot(
        run["x"] - WIDTH,
        run["h"],
        "C1--",
        lw=1.4,
        label=f"granrs depth-averaged, closure 'hydrostatic' ({n} cells per L_c)",
    )
    a.set(xlabel="x − L_c (m), gate at 0", ylabel="deposit h (m)", xlim=(-0.25, 2.8), yscale="log", ylim=(1e-4, 0.2))
    a.set_title(f"Dry column, Coulomb base tan 15°: granrs against IMEX_SfloW2D ({'passes' if passed else 'fails'})")
    a.grid(alpha=0.3)
    a.legend(fontsize=8)
    for key, mk in (("front_1mm", "o"), ("front_5mm", "s")):
        b.plot(ref["t"], ref[key] - WIDTH, f"k{mk}", ms=3.5, mfc="none", label=f"IMEX: h > {key[6:]}")
        b.plot(
            run["t"], run[key] - WIDTH, "C1-" if key == "front_1mm" else "C0-", lw=1.3, label=f"granrs: h > {key[6:]}"
        )
    b.set(xlabel="t (s)", ylabel="front from the gate (m)")
    b.grid(alpha=0.3)
    b.legend(fontsize=8)
    fig.tight_layout()
    Path(png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return metrics


def main(argv=None) -> int:
    """``python -m granrs.validation.peer --out DIR [--png FILE] [--n 32 64] [--option KEY=VALUE
    ...]``: the case with its runs kept in DIR (reused when run again), its JSON record in
    DIR/record.json, and the figure. ``--option`` changes a model option from its default (a
    schema key of ``granrs.options``, the value in TOML syntax) for a sensitivity run."""
    ap = argparse.ArgumentParser(description="granrs's dry column against Basilisk")
    ap.add_argument("--out", required=True)
    ap.add_argument("--png", default=None)
    ap.add_argument("--n", type=int, nargs="+", default=list(REFERENCE_RESOLUTIONS))
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change a model option from its default, e.g. --option proximal_restarts=20 (repeat)",
    )
    ap.add_argument(
        "--depth-averaged",
        dest="depth_averaged",
        type=int,
        default=None,
        metavar="N",
        help="the depth-averaged case instead, N cells across L_c (100: the peer's 2 mm): its figure in --png",
    )
    args = ap.parse_args(argv)
    if args.depth_averaged is not None:
        png = Path(args.png) if args.png else Path(args.out) / "peer_depth_averaged.png"
        print(json.dumps(plot_depth_averaged(args.depth_averaged, png), indent=2))
        return 0
    options = parse_options(args.option)
    metrics, reference, passed = peer_dry_column(args.n, threads=args.threads, out=args.out, options=options)
    record = {"case": "peer-dry-column", "metrics": metrics, "reference": reference, "passed": passed}
    Path(args.out, "record.json").write_text(json.dumps(record, indent=2) + "\n")
    plot_comparison(
        {k: read_run(Path(args.out) / f"n{k}") for k in args.n},
        Path(args.png) if args.png else Path(args.out) / "peer_dry_column.png",
    )
    print(json.dumps(record, indent=2))
    return 0 if passed else 1


if __name__ == "__main__":
    raise SystemExit(main())
