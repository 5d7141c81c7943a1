"""Named validation cases for ``granrs validate NAME``.

Each case runs a model against an analytic solution, a published reference or an independent
method and returns one JSON-able dict ``{"case", "kind", "params", "metrics", "reference", "passed",
"wall_s"}``. ``passed`` is True or False against the stated reference, and None where the
parameters lie outside the reference's range (the metrics are then reported, not judged). The
acceptance thresholds live beside each case with the number that justifies them. ``kind`` is
``"validation"``, or ``"cross-check"`` for a comparison of granrs with itself (one formulation
against another), which has no external reference.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from .._granrs import ParameterError
from . import levelset, navier_stokes, peer, pore_pressure, rheology

#: name → (function(**params) → (metrics, reference, passed), default params, help)
CASES: dict[str, tuple[Callable, dict, str]] = {
    "taylor-green": (navier_stokes.taylor_green, {"n": [32, 64, 128]}, "decaying Taylor–Green vortex, free-slip box"),
    "cavity": (navier_stokes.cavity, {"re": 100.0, "n": 64}, "lid-driven cavity to steady state"),
    "hydrostatic": (navier_stokes.hydrostatic, {"steps": 1000, "n": 32}, "heavy fluid under a light one, at rest"),
    "zalesak": (
        levelset.zalesak,
        {"n": 100, "redistance_every": 0, "cfl": 0.5},
        "Zalesak's slotted disk, one revolution",
    ),
    "single-vortex": (
        levelset.single_vortex,
        {"n": 128, "period": 2.0, "redistance_every": 0, "cfl": 0.5},
        "Rider-Kothe single vortex, back at t = T",
    ),
    "dam-break": (
        levelset.dam_break,
        {"n": 32, "mass_correction": True, "air": "resolved"},
        "water column under air against Martin & Moyce (1952); --air free-surface: the granular-only model's free surface",
    ),
    "pore-formulations": (
        pore_pressure.pore_formulations,
        {"ny": 32, "t_end": 0.15, "kappa_air": 1e16},
        "cross-check: granular-only against kappa-infinity pore pressure on a collapsing column",
    ),
    "fluidised-layer": (
        pore_pressure.fluidised_layer,
        {"ny": 32, "slope_deg": 20.0, "t_end": 1.0},
        "granular layer on a slope below its friction angle: at rest dry, flowing when fluidised",
    ),
    "pore-diffusion": (
        pore_pressure.pore_diffusion,
        {"n": [16, 32, 64, 128], "dt_factor": 10.0, "formulation": "granular-only"},
        "pore pressure in a static layer with a basal air flux, exact 1D series",
    ),
    "poiseuille-bingham": (
        rheology.poiseuille_bingham,
        {"tau_y": 0.25, "n": [16, 32, 64]},
        "Bingham plane Poiseuille flow against the exact solution",
    ),
    "cavity-bingham": (
        rheology.cavity_bingham,
        {"bn": [0.0, 2.0, 5.0, 20.0, 50.0], "n": 32},
        "Bingham lid-driven cavity at Re = 0: vortex and plug against Bn",
    ),
    "cessation": (
        rheology.cessation,
        {"geometry": "couette", "tau_y": 0.5, "dt": [4e-3, 2e-3, 1e-3], "n": 32},
        "Bingham flow left without forcing: finite stopping time against the bound",
    ),
    "bagnold": (rheology.bagnold, {"n": 64}, "mu(I) layer on an incline against the exact Bagnold profile"),
    "sliding-block": (
        rheology.sliding_block,
        {"slope": 30.0, "stop_slope": 10.0, "n": 32},
        "D-P block on a Coulomb base: acceleration, and stopping below the friction angle",
    ),
    "heap-at-rest": (
        rheology.heap_at_rest,
        {"slope": 20.0, "n": 32, "regularised": False},
        "granular layer inclined below its friction angle stays at rest",
    ),
    "picard-ratio": (
        rheology.picard_ratio,
        {"theta": [0.1, 0.25, 0.5, 0.75], "n": 32},
        "geometric convergence of the Picard iteration against 1 - theta",
    ),
    "peer-dry-column": (
        peer.peer_dry_column,
        {"n": [32, 64], "t_end": 3.0},
        "dry column, free-slip back wall, against Basilisk (n: cells per H_c; docs/validation.md)",
    ),
    "peer-depth-averaged": (
        peer.peer_depth_averaged,
        {"n": 100},
        "depth-averaged dry column, k = 1, tan 15°, against IMEX_SfloW2D (n: cells per L_c; docs/models.md)",
    ),
}


#: cases that compare granrs with itself rather than with an external reference
CROSS_CHECKS = frozenset({"pore-formulations"})


def run_case(name: str, threads: int = 1, **params) -> dict:
    """Runs validation case ``name`` with ``params`` (defaults filled in) and returns its record.

    Parameters
    ----------
    name : str
        One of :data:`CASES` (``granrs validate list``).
    threads : int
        Threads of the Rust core.
    **params
        The case's parameters; None leaves a default.

    Returns
    -------
    dict
        ``{"case", "kind", "params", "metrics", "reference", "passed", "wall_s"}``; ``passed`` is
        None where the parameters lie outside the reference's range.
    """
    if name not in CASES:
        raise ParameterError(f"invalid parameter `case` = {name!r}: allowed one of {', '.join(sorted(CASES))}")
    func, defaults, _ = CASES[name]
    full = dict(defaults)
    for k, v in params.items():
        if v is None:
            continue
        if k not in defaults:
            raise ParameterError(f"invalid parameter `{k}` for case {name!r}: allowed {', '.join(defaults) or 'none'}")
        full[k] = v
    t0 = time.perf_counter()
    metrics, reference, passed = func(threads=threads, **full)
    return {
        "case": name,
        "kind": "cross-check" if name in CROSS_CHECKS else "validation",
        "params": full | {"threads": threads},
        "metrics": metrics,
        "reference": reference,
        "passed": None if passed is None else bool(passed),
        "wall_s": time.perf_counter() - t0,
    }
