"""Pore-pressure validation: diffusion in a static granular layer against the exact 1D series."""

from __future__ import annotations

import math
import time as _t

import numpy as np

from ..boundary import BoundaryConditions, FreeSlip, FullyDeveloped, NoSlip, Outflow
from ..grid import Grid
from ..materials import AIR, Material
from ..model import Model, Numerics, PorePressure
from ..rheology import DruckerPrager
from ..shapes import Rectangle

#: a layer of thickness H = 0.8 in a unit-height box, κ = 1, basal gradient G = −1:
#: ∂_t p = κ ∂²p/∂y², p(H) = 0, ∂p/∂y(0) = G, p(y, 0) = 0. Non-dimensional.
H, KAPPA, G = 0.8, 1.0, -1.0
#: the bound on the relative L2 error at n = 64 against the exact series: the measured error is
#: 7.9e-5 there (2.3e-3, 2.5e-4, 7.9e-5, 2.1e-5 at n = 16, 32, 64, 128: least-squares order 2.2);
#: the bound is 2.5 times the measured
PORE_DIFFUSION_L2_AT_64 = 2e-4
#: the sharp κ_∞ formulation and the granular-only solve must agree within this relative L2
#: difference of p_f: a cross-check of granrs with itself. They differ through the air cells (p_f
#: of order κ_f/κ_∞ = 3.5e-18 there) and the tolerances of the solves: measured 1.3e-7 at ny = 32
#: (t_end 0.15 s); the bound is 77 times that
PORE_FORMULATIONS_AGREEMENT = 1e-5
#: the fluidised layer at rest without pore pressure: round-off speeds (measured over 1 s: 1.0e-13
#: m/s at ny = 32, 2.6e-15 m/s at ny = 16; round-off, up to 1.2e-13 m/s seen); the bound is 100
#: times the largest
LAYER_REST_SPEED = 1e-11
#: the fluidised layer (β = 0.95) flows at t between two exact speeds: the Coulomb slider held by
#: the friction of the effective pressure left, g (sin θ − (1 − β) cos θ tan α) t (0.624 m/s at
#: 0.2 s for θ = 20°, α = 27°), and the frictionless g sin θ t (0.671 m/s). Measured 0.630 m/s at
#: ny = 16 and 0.629 m/s at ny = 32. Acceptance: above this fraction of the slider's speed (a 10 %
#: margin for the viscous layer at the no-slip base) and not above the frictionless speed
LAYER_FLOW_FRACTION = 0.9
#: the Coulomb ratio the balanced dry layer needs exceeds tan θ / tan α (0.714 at 20°) by the
#: sampling of ρ on faces, first order in h: +6.7 % at ny = 16, +3.2 % at ny = 32 (measured).
#: Acceptance: |ratio / (tan θ / tan α) − 1| <= this × 16 / ny, 1.5 times the measured excess
LAYER_REST_RATIO_EXCESS = 0.1


def exact_flux(y: np.ndarray, t: float, terms: int = 200) -> np.ndarray:
    """p = G (y − H) + Σ_k 2G/(H λ_k²) cos(λ_k y) e^{−κ λ_k² t}, λ_k = (2k+1)π/(2H)."""
    p = G * (y - H)
    for k in range(terms):
        lam = (2 * k + 1) * math.pi / (2 * H)
        p = p + 2 * G / (H * lam**2) * np.cos(lam * y) * math.exp(-KAPPA * lam**2 * t)
    return p


def pore_diffusion_error(
    n: int,
    dt_factor: float = 10.0,
    formulation: str = "granular-only",
    threads: int = 1,
    t_end: float = 0.064,
    time_scheme: str = "implicit",
    seed: float = 0.0,
):
    """Relative L2 error of p_f in the layer at κ t/H² = 0.1, with δt = dt_factor × h²/(4κ) (the
    explicit limit; rounded so that a whole number of steps lands on t_end). The interface y = H
    is not aligned with the grid (H/h = 0.8 n). ``time_scheme``: 'implicit' (BDF2) or 'explicit'
    (forward Euler, stable for dt_factor <= 1). ``seed``: amplitude of a checkerboard
    (−1)^{i+j} added to the initial p_f = 0 in the layer; the layer is x-invariant, so without
    it the x-modes are never excited and the explicit scheme sees only the 1D limit h²/(2κ)."""
    grid = Grid(4, n, 4.0 / n, 1.0)
    dt = dt_factor * grid.h**2 / (4 * KAPPA)
    steps = max(1, round(t_end / dt))
    pore = PorePressure(
        diffusivity=KAPPA, formulation=formulation, basal_gradient=G, kappa_air=1e8, time_scheme=time_scheme
    )
    model = Model(
        grid,
        Material(1450.0, 0.1),
        light=AIR,
        bc=BoundaryConditions(left=FreeSlip(), right=FreeSlip(), bottom=FreeSlip(), top=Outflow()),
        numerics=Numerics(dt=t_end / steps, transport_interface=False),
        threads=threads,
        pore_pressure=pore,
    )

    def pf0(x, y):
        board = 1.0 - 2.0 * ((np.floor(x / grid.dx) + np.floor(y / grid.dy)) % 2)
        return np.where(y < H, seed * board, 0.0)

    model.set_initial(phi=lambda x, y: H - y, pf=pf0)
    model.advance(max_steps=steps)
    y = (np.arange(n) + 0.5) * grid.dy
    inside = y < H
    p = model.pf.mean(axis=1)[inside]
    exact = exact_flux(y[inside], model.time)
    return float(np.sqrt(np.sum((p - exact) ** 2) / np.sum(exact**2))), float(np.max(np.abs(model.u))), model


def pore_diffusion(n, dt_factor: float = 10.0, formulation: str = "granular-only", threads: int = 1):
    ns = [int(x) for x in (n if isinstance(n, (list, tuple)) else [n])]
    errs = [pore_diffusion_error(k, dt_factor, formulation, threads)[0] for k in ns]
    metrics = {"n": ns, "l2_rel_error": errs if len(ns) > 1 else errs[0]}
    # judged against the exact series: the order needs two or more n, the error bound is stated at
    # n = 64; one n other than 64 has neither, and passed is None
    passed = None
    if len(ns) > 1:
        orders = [math.log(errs[i] / errs[i + 1]) / math.log(ns[i + 1] / ns[i]) for i in range(len(ns) - 1)]
        metrics["successive_orders"] = orders
        # the interface sits at a different fraction θ of a cell on each grid (H/h = 0.8 n), which
        # changes the error constant of the sub-cell Dirichlet condition from grid to grid: the
        # order is the least-squares slope over all grids
        slope = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
        metrics["observed_order"] = float(slope)
        passed = bool(slope >= 1.8)
    if 64 in ns:
        e64 = errs[ns.index(64)]
        passed = (passed is not False) and e64 <= PORE_DIFFUSION_L2_AT_64
    reference = {
        "solution": "1D series, flux at the base, p_f = 0 on the interface",
        "acceptance": f"l2_rel_error <= {PORE_DIFFUSION_L2_AT_64:g} at n = 64; observed_order (least-squares slope) >= 1.8 "
        "(two or more n); one n other than 64: passed null",
        "dt": f"{dt_factor} x h^2/(4 kappa)",
    }
    return metrics, reference, passed


def _collapse_pf(formulation: str, ny: int, t_end: float, threads: int, kappa_air: float):
    """A fluidised heavy column (φρ_s = 1450 kg m⁻³, Newtonian η = 0.1 Pa s here: the comparison
    concerns the pore-pressure solve, not the rheology) collapsing under air in a 1.0 m × 0.45 m
    box; β = 0.9, κ_f = 0.035 m² s⁻¹, air supply under the column."""
    rho, g, lc, hc, beta = 1450.0, 9.81, 0.2, 0.4, 0.9
    grid = Grid(int(round(ny * 1.0 / 0.45 / 2)) * 2, ny, 1.0, 0.45)
    grid = Grid(grid.nx, ny, grid.nx * 0.45 / ny, 0.45)
    pore = PorePressure(
        diffusivity=0.035,
        formulation=formulation,
        kappa_air=kappa_air,
        basal_gradient=-beta * rho * g,
        basal_x_min=0.0,
        basal_x_max=lc,
    )
    model = Model(
        grid,
        Material(rho, 0.1),
        light=AIR,
        gravity=(0.0, -g),
        bc=BoundaryConditions(left=FreeSlip(), right=FreeSlip(), bottom=FreeSlip(), top=Outflow()),
        numerics=Numerics(cfl=0.4),
        threads=threads,
        pore_pressure=pore,
    )
    model.set_shape(Rectangle(-1.0, lc, -1.0, hc), balance_pressure=False)
    model.set_initial(pf=lambda x, y: np.where((x < lc) & (y < hc), beta * rho * g * (hc - y), 0.0))
    t0 = _t.perf_counter()
    log = model.advance(t_end=t_end)
    wall = _t.perf_counter() - t0
    return model, wall, log


def pore_formulations(ny: int = 32, t_end: float = 0.15, kappa_air: float = 1e16, threads: int = 1):
    """Granular-only solve against the κ_∞ formulations on a collapsing (moving-interface)
    fluidised column: relative L2 difference of p_f over the granular phase at t_end, and timings."""
    a, wa, la = _collapse_pf("granular-only", ny, t_end, threads, kappa_air)
    metrics = {
        "steps": a.step_count,
        "wall_s_granular-only": wa,
        "pore_iterations_median_granular-only": float(np.median(la["pore_iterations"])),
    }
    for form in ("kappa-infinity", "kappa-infinity-smoothed"):
        b, wb, lb = _collapse_pf(form, ny, t_end, threads, kappa_air)
        inside = (a.phi > 0) & (b.phi > 0)
        metrics[f"pf_rel_l2_difference_{form}"] = float(
            np.sqrt(np.sum((a.pf - b.pf)[inside] ** 2) / np.sum(a.pf[inside] ** 2))
        )
        metrics[f"wall_s_{form}"] = wb
        metrics[f"pore_iterations_median_{form}"] = float(np.median(lb["pore_iterations"]))
    diff = metrics["pf_rel_l2_difference_kappa-infinity"]
    reference = {
        "kind": "cross-check: granrs against itself, no external reference",
        "acceptance": f"granular-only and kappa-infinity (sharp) agree within {PORE_FORMULATIONS_AGREEMENT:g} (relative "
        "L2 of p_f over the granular phase); the smoothed form differs by O(eps) and is reported",
        "kappa_air": kappa_air,
    }
    return metrics, reference, diff <= PORE_FORMULATIONS_AGREEMENT


def fluidised_layer_speed(
    beta: float,
    ny: int = 32,
    slope_deg: float = 20.0,
    t_end: float = 0.2,
    threads: int = 1,
    nx: int = 2,
    interface_yield: str = "density-support",
    balance: bool = True,
):
    """An x-invariant granular layer (thickness 0.1 m, φρ_s = 1450, D-P with α = 27°, η_s = 0.1)
    on a rough base inclined at ``slope_deg`` < α under air, sides fully developed. β = 0: the
    yield stress holds the layer; β near 1: the pore pressure (kept by a basal air flux) carries
    the weight, the effective pressure and the yield stress vanish and the layer flows.

    - The air's weight along the slope is balanced by the ambient hydrostatic pressure
      (``Numerics.ambient_hydrostatic``): between open sides nothing else can hold it.
    - With ``balance`` the plastic tensor starts from the one that holds the layer at rest
      (``Model.balance_plastic_stress``); from Σ = 0 the Picard iteration of eq. (12) builds it up
      over many steps while the layer moves.
    - ``interface_yield`` 'density-support' gives the interface band, which carries granular
      weight, the full Coulomb ratio; with the paper's H_ε(Φ) the top of the band needs a ratio
      tan θ / H_ε > tan α and slides.
    - The layer is uniform along x, so ``nx`` = 2 columns represent it (model no more than the
      scene needs); with nx ≥ 4 a round-off mode varying along x grows between the fully
      developed sides (docs/validation.md, fluidised layer).

    Returns the largest speed over the run, the model and the balance report (None without)."""
    rho, g, hl = 1450.0, 9.81, 0.1
    th = math.radians(slope_deg)
    gx, gy = g * math.sin(th), -g * math.cos(th)
    ly = 0.2
    grid = Grid(nx, ny, nx * ly / ny, ly)
    pore = None
    if beta > 0:
        pore = PorePressure(diffusivity=0.035, basal_gradient=-beta * rho * g * math.cos(th))
    model = Model(
        grid,
        Material(rho, 0.1),
        light=AIR,
        gravity=(gx, gy),
        bc=BoundaryConditions(left=FullyDeveloped(), right=FullyDeveloped(), bottom=NoSlip(), top=Outflow()),
        numerics=Numerics(
            cfl=0.4,
            max_dt=2e-3,
            picard_tol=1e-6,
            theta=0.8,
            picard_max_iterations=500,
            ambient_hydrostatic=True,
            interface_yield=interface_yield,
        ),
        threads=threads,
        rheology=DruckerPrager(friction_angle=27.0),
        pore_pressure=pore,
    )
    model.set_initial(phi=lambda x, y: hl - y, balance_pressure=False)
    if pore is not None:
        model.set_initial(
            pf=lambda x, y: np.where(y < hl, beta * rho * g * math.cos(th) * (hl - y), 0.0), balance_pressure=False
        )
    model.set_initial(balance_pressure=True)
    report = model.balance_plastic_stress() if balance else None
    log = model.advance(t_end=t_end)
    return float(np.max(log["max_speed"])), model, report


def fluidised_layer(ny: int = 32, slope_deg: float = 20.0, t_end: float = 1.0, threads: int = 1):
    """β = 0 over ``t_end`` (default 1 s, as heap-at-rest) and β = 0.95 over 0.2 s, with the
    balanced initial Σ and the 'density-support' yield band; beside them, reported, the paper's
    band (H_ε(Φ)) and the start from Σ = 0."""
    beta, alpha, th, t_wet = 0.95, math.radians(27.0), math.radians(slope_deg), min(t_end, 0.2)
    dry, _, rep = fluidised_layer_speed(0.0, ny, slope_deg, t_end, threads)
    wet, _, _ = fluidised_layer_speed(beta, ny, slope_deg, t_wet, threads)
    paper, _, rep_paper = fluidised_layer_speed(0.0, ny, slope_deg, t_end, threads, interface_yield="paper")
    unbalanced, _, _ = fluidised_layer_speed(0.0, ny, slope_deg, min(t_end, 0.2), threads, balance=False)
    metrics = {
        "max_speed_beta_0": dry,
        "max_speed_beta_0.95": wet,
        "slope_deg": slope_deg,
        "friction_angle_deg": 27.0,
        "rest_ratio": rep["max_ratio"],
        "rest_ratio_bound": math.tan(math.radians(slope_deg)) / math.tan(math.radians(27.0)),
        "flow_speed_coulomb_slider": 9.81 * (math.sin(th) - (1 - beta) * math.cos(th) * math.tan(alpha)) * t_wet,
        "flow_speed_frictionless": 9.81 * math.sin(th) * t_wet,
        "max_speed_beta_0_paper_band": paper,
        "rest_ratio_paper_band": rep_paper["max_ratio"],
        "clamped_nodes_paper_band": rep_paper["clamped"],
        "max_speed_beta_0_from_zero_stress": unbalanced,
    }
    reference = {
        "source": "continuum: below its friction angle a dry layer rests; with its weight carried by the pore "
        "pressure its yield stress vanishes and it flows",
        "acceptance": f"at rest without pore pressure (max_speed < {LAYER_REST_SPEED:g} m/s over t_end), flowing "
        f"with it (beta = 0.95, over min(t_end, 0.2 s): above {LAYER_FLOW_FRACTION:g} of the Coulomb slider's "
        "speed with (1 - beta) of the weight, not above the frictionless speed); rest_ratio within "
        f"{LAYER_REST_RATIO_EXCESS:g} x 16/ny of tan(slope)/tan(27°) (the density sampled on faces, first order in h)",
        "note": "interface_yield 'density-support' and the balanced initial Σ; the paper's band and the start "
        "from Σ = 0 are reported beside (docs/validation.md)",
    }
    flowing = LAYER_FLOW_FRACTION * metrics["flow_speed_coulomb_slider"] < wet <= metrics["flow_speed_frictionless"]
    holding = abs(metrics["rest_ratio"] / metrics["rest_ratio_bound"] - 1.0) <= LAYER_REST_RATIO_EXCESS * 16 / ny
    return metrics, reference, dry < LAYER_REST_SPEED and flowing and holding
