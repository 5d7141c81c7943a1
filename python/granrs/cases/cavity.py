"""Lid-driven cavity: steady flow, streamlines and centreline profiles against Ghia et al. (1982)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..validation.navier_stokes import ghia_re100, run_cavity


def run_cavity_case(re: float, n: int, out: Path, threads: int = 1) -> dict:
    import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after its backend is chosen

    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    model, change, iters = run_cavity(re, n, threads)
    wall = time.perf_counter() - t0
    grid = model.grid
    psi = model.streamfunction()
    xn, yn = grid.nodes()
    uc, vc = model.centre_velocity()
    speed = np.hypot(uc, vc)

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.8))
    ax = axes[0]
    im = ax.imshow(speed, origin="lower", extent=(0, 1, 0, 1), cmap="viridis")
    levels = np.concatenate([np.linspace(psi.min(), 0, 12)[:-1], np.geomspace(1e-6, max(psi.max(), 2e-6), 5)])
    ax.contour(xn, yn, psi, levels=np.unique(levels), colors="w", linewidths=0.7)
    fig.colorbar(im, ax=ax, label="|u| / U")
    ax.set(title=f"Cavity Re = {re:g}, {n}² cells: speed and streamlines", xlabel="x / L", ylabel="y / L")
    ax = axes[1]
    yu = (np.arange(grid.ny) + 0.5) * grid.dy
    xv = (np.arange(grid.nx) + 0.5) * grid.dx
    ax.plot(model.u[:, grid.nx // 2], yu, "C0-", label="u(0.5, y)  granrs")
    ax.plot(xv, model.v[grid.ny // 2, :], "C1-", label="v(x, 0.5)  granrs")
    if abs(re - 100) < 1e-9:
        gu, gv = ghia_re100()
        ax.plot(gu[:, 1], gu[:, 0], "C0o", mfc="none", label="u  Ghia et al. 1982")
        ax.plot(gv[:, 0], gv[:, 1], "C1s", mfc="none", label="v  Ghia et al. 1982")
    ax.set(
        xlabel="velocity / U  (u)   or   x / L  (v)",
        ylabel="y / L  (u)   or   velocity / U  (v)",
        title="Centreline profiles",
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "cavity.png", dpi=120)
    plt.close(fig)
    summary = {
        "case": "cavity",
        "re": re,
        "n": n,
        "t_final": model.time,
        "steps": model.step_count,
        "steady_change": change,
        "wall_s": wall,
        "psi_min": float(psi.min()),
        "pressure_iterations_median": float(np.median(iters)),
        "threads": threads,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary, indent=2))
    return summary
