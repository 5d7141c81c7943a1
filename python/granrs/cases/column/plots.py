"""The column's plots, read back from its output files: front.png, profiles.png, energy.png and
fluidisation.png."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ... import observables as obs
from .case import PAPER_RUNOUT_EXP, PAPER_RUNOUT_SIM


def plot_energy(out: Path) -> None:
    """energy.png: where gravity's work goes against time (from energy.csv)."""
    import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after its backend is chosen

    d = np.genfromtxt(out / "energy.csv", delimiter=",", names=True)
    meta = json.loads((out / "summary.json").read_text())
    fig, ax = plt.subplots(figsize=(10, 4.2))
    t = d["t_s"]
    ax.plot(t, d["gravity_work_J_m"], "k", lw=2, label="work of gravity W_g")
    ax.plot(t, d["potential_drop_J_m"], "k:", lw=1, label="potential energy drop")
    ax.plot(t, d["plastic_work_J_m"], color="C0", label="plastic work ∫τΣ:D")
    ax.plot(
        t,
        -d["plastic_negative_work_J_m"],
        color="C0",
        ls="--",
        lw=1,
        label="its negative part (stress given back), sign flipped",
    )
    ax.plot(t, d["wall_work_J_m"], color="C1", label="Coulomb friction, base and back wall")
    if np.any(d["side_wall_work_J_m"] != 0):
        ax.plot(t, d["side_wall_work_J_m"], color="C5", label="friction of the channel's side walls")
    ax.plot(t, d["kinetic_J_m"], color="C2", label="kinetic energy")
    ax.plot(t, d["viscous_work_J_m"], color="C4", lw=1, label="viscous work")
    ax.plot(t, -d["residual_J_m"], color="C3", label="numerical dissipation (− residual)")
    ax.set(xlabel="t (s)", ylabel="J per metre of width", title=_label(meta) + " column: energy budget")
    ax.title.set_fontsize(9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(out / "energy.png", dpi=120)
    plt.close(fig)


def plot_fluidisation(out: Path) -> None:
    """fluidisation.png: the basal pore pressure over the weight against time, under the
    reservoir and in the channel (from front.csv)."""
    import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after its backend is chosen

    d = np.genfromtxt(out / "front.csv", delimiter=",", names=True)
    meta = json.loads((out / "summary.json").read_text())
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    ax.plot(d["t_s"], d["pf_ratio_reservoir"], label="under the reservoir (x < L_c)")
    ax.plot(d["t_s"], d["pf_ratio_channel"], label="in the channel (x > L_c)")
    beta = meta["case"]["fluidisation"]["pore_pressure_ratio"]
    ax.axhline(beta, color="0.5", ls=":", lw=1, label=f"initial β = {beta:g}")
    ax.axhline(1.0, color="k", ls="--", lw=0.8, label="pore pressure = weight (p_s = 0)")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("basal p_f / (φ ρ_s g h)")
    ax.set_ylim(bottom=0.0)
    ax.set_title(f"{_label(meta)}: fluidisation of the base", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "fluidisation.png", dpi=120)
    plt.close(fig)


def _label(meta: dict) -> str:
    state = "fluidised" if meta["fluidised"] else "non-fluidised"
    if meta.get("model") == "depth-averaged":
        return f"{state}, depth-averaged ({meta['cells']} cells)"
    model = ", granular-only" if meta.get("model") == "granular" else ""
    window = f", active region {meta['active_region']}" if meta.get("active_region") else ""
    walls = f", side walls {100 * meta['channel_width_m']:g} cm apart" if meta.get("channel_width_m") else ""
    return f"{state}{model}{walls}{window}, ny = {meta['ny']}"


def _read_front(path: Path):
    meta = json.loads((path / "summary.json").read_text())
    if len((path / "front.csv").read_text().splitlines()) < 2:  # a run that failed before its first record
        return np.zeros(0), np.zeros(0), meta
    data = np.genfromtxt(path / "front.csv", delimiter=",", skip_header=1, ndmin=2)
    return data[:, 0], data[:, 1], meta


def _front_label(meta: dict) -> str:
    """Legend entry of a run on front.png: a run that came to rest has a run-out; one cut at
    t_end has only the front it reached then."""
    reason = str(meta.get("stop_reason", ""))
    if reason == "rest":
        return _label(meta) + f": run-out {meta['runout_m']:.3f} m (at rest)"
    why = "stopped by an error" if reason.startswith(("error", "interrupted")) else "not at rest"
    return _label(meta) + f": front {meta['runout_m']:.3f} m at t = {meta.get('t_end_s', 0.0):g} s ({why})"


def _front_band(path: Path) -> Optional[dict]:
    """The thickness fronts of front.csv in ``path`` by thickness in metres (None for a front.csv
    without them)."""
    d = np.genfromtxt(path / "front.csv", delimiter=",", names=True)
    keys = [k for k in obs.front_keys(cells=()) if k in (d.dtype.names or ())]
    if not keys or d.ndim == 0:
        return None
    return {"t": d["t_s"], "fronts": [(k, d[k]) for k in keys]}


def plot_front(out: Path, compare_with: Optional[Path] = None) -> None:
    """front.png: the lowest-row front (bold) and the band of the thickness fronts of the volume
    profile (from 1 to 20 mm, shaded; each thickness a thin line) against time, for this run and
    for ``compare_with``."""
    import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after its backend is chosen

    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    runs = [out] + ([compare_with] if compare_with is not None and (compare_with / "front.csv").exists() else [])
    for k, path in enumerate(runs):
        t, x, meta = _read_front(path)
        label = _front_label(meta)
        ax.plot(t, x, f"C{k}-", lw=2, label=label)
        band = _front_band(path) if t.size > 1 else None
        if band is not None:
            lo, hi = band["fronts"][-1][1], band["fronts"][0][1]  # the thickest and the thinnest
            ax.fill_between(
                band["t"],
                np.nan_to_num(lo),
                np.nan_to_num(hi),
                color=f"C{k}",
                alpha=0.15,
                lw=0,
                label=f"fronts at h = {band['fronts'][0][0][7:-2]} to {band['fronts'][-1][0][7:-2]} (volume profile)",
            )
            for name, xf in band["fronts"]:
                ax.plot(band["t"], xf, f"C{k}", lw=0.6, alpha=0.8)
                ax.annotate(
                    name[7:-2],
                    (band["t"][-1], xf[-1]),
                    fontsize=6,
                    color=f"C{k}",
                    xytext=(2, 0),
                    textcoords="offset points",
                    va="center",
                )
    ax.axhline(PAPER_RUNOUT_SIM, color="k", ls="--", lw=1, label=f"paper, simulation: {PAPER_RUNOUT_SIM} m")
    ax.axhline(PAPER_RUNOUT_EXP, color="k", ls=":", lw=1.5, label=f"paper, experiment: {PAPER_RUNOUT_EXP} m")
    ax.set(
        xlabel="t (s)",
        ylabel="front position from the gate (m)",
        title="Column collapse: front (bold: lowest row of cells) and thickness fronts",
    )
    ax.title.set_fontsize(10)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(out / "front.png", dpi=120)
    plt.close(fig)


def plot_profiles(out: Path) -> None:
    import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after its backend is chosen

    header = (out / "profiles.csv").read_text().splitlines()[0].split(",")
    data = np.genfromtxt(out / "profiles.csv", delimiter=",", skip_header=1)
    meta = json.loads((out / "summary.json").read_text())
    cols = [(k, name) for k, name in enumerate(header) if name.startswith("h_")]
    fig, ax = plt.subplots(figsize=(9, 3.8))
    cmap = plt.get_cmap("viridis")
    for n, (k, name) in enumerate(cols):
        label = "final deposit" if name == "h_final" else f"t = {float(name[2:]):g} s"
        style: dict[str, Any] = (
            dict(color="k", lw=2) if name == "h_final" else dict(color=cmap(n / max(1, len(cols) - 1)), lw=1)
        )
        ax.plot(data[:, 0], data[:, k], label=label, **style)
    if "hvol_final" in header and meta.get("model") != "depth-averaged":
        ax.plot(
            data[:, 0],
            data[:, header.index("hvol_final")],
            color="C3",
            ls="--",
            lw=1.2,
            label="final, volume per column",
        )
    ax.axvline(0.0, color="grey", lw=0.8)
    ax.axvline(PAPER_RUNOUT_SIM, color="k", ls="--", lw=1, label="paper run-out (simulation)")
    ax.axvline(PAPER_RUNOUT_EXP, color="k", ls=":", lw=1.5, label="paper run-out (experiment)")
    ax.set(
        xlabel="x − L_c (m), gate at 0",
        ylabel="h (m): surface height; dashed: volume per column",
        title=_label(meta) + " column: surface profiles\n(paper: thickest near the gate, gentle decrease downstream)",
    )
    ax.title.set_fontsize(9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(out / "profiles.png", dpi=120)
    plt.close(fig)
