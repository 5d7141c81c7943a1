"""The depth-averaged pore pressure against the two-phase model: the basal ratio under the reservoir and in the channel.

    python studies/depth_averaged_pore.py              # 2D runs at ny = 32 (about 1 min each) and the figure
    python studies/depth_averaged_pore.py --ny 16      # coarser 2D runs

The paper's column (a = 2, and a = 1 for a second geometry), fluidised (β_s = 0.9) and dry, is
run with the two-phase model at ``--ny`` and with the depth-averaged model (its default closure)
with both pore-pressure transports of ``granrs.depth_averaged.PORE_TRANSPORTS``:
'depth-integrated' (eq. (7d) integrated over the depth: ∫p_f dz carried with the flow, decaying
at 2κ/h², supplied under the reservoir) and 'basal-ratio' (h β carried, decaying at π²κ/4h², held
at β ≥ β_s under the reservoir). Every run records the basal pore pressure over the weight,
Σ p_b / Σ ρ g h, under the reservoir (0 < x < L_c) and in the channel (x > L_c), every 0.01 s
(front.csv's ``pf_ratio_reservoir``, ``pf_ratio_channel``; the 2D model's p_b is its lowest row
of cells). The dry runs have no pore pressure (both ratios 0); their fronts are drawn beside the
fluidised ones.

Outputs: ``docs/img/depth_averaged_pore.png`` (basal ratio under the reservoir, in the channel,
and the fronts against time), ``docs/img/depth_averaged_pore.json`` (for each transport and
geometry, the mean absolute difference of each ratio from the 2D model's over 0-1 s, and the
ratios' largest values; and the same difference of min(ratio, 1), the ratio as it enters the
friction (1 − β)⁺), run folders in ``--out`` (reused when present).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from granrs import DepthAveraged
from granrs.cases.column import ColumnCase, ColumnGeometry, Fluidisation, run_column
from granrs.depth_averaged import PORE_TRANSPORTS
from granrs.validation.peer import read_csv_columns

ROOT = Path(__file__).resolve().parents[1]
ASPECT_RATIOS = (2.0, 1.0)
#: the window of the comparison (s): the collapse and the run-out, before the 2D deposit's slow creep
WINDOW_S = 1.0


def run_or_load(case: ColumnCase, folder: Path) -> dict:
    """front.csv's columns of the run in ``folder`` (run first if it is not there)."""
    if not (folder / "front.csv").exists() or not (folder / "summary.json").exists():
        print(f"running {folder.name} ...", flush=True)
        run_column(case, folder, progress=False)
    return read_csv_columns(folder / "front.csv")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ny", type=int, default=32, help="the 2D runs' grid (default 32)")
    ap.add_argument("--out", default=str(ROOT / "out" / "depth_averaged_pore"), help="run folders")
    args = ap.parse_args()
    out = Path(args.out)
    runs: dict = {}
    for a in ASPECT_RATIOS:
        for fluidised in (True, False):
            state = "fluidised" if fluidised else "dry"
            scene = dict(geometry=ColumnGeometry(aspect_ratio=a), fluidisation=Fluidisation(fluidised=fluidised))
            base = ColumnCase(ny=args.ny, **scene)
            runs["2D", a, state] = run_or_load(base, out / f"two-phase-ny{args.ny}-a{a:g}-{state}")
            for transport in PORE_TRANSPORTS if fluidised else PORE_TRANSPORTS[:1]:
                case = ColumnCase(
                    **scene,
                    ny=args.ny,
                    model="depth-averaged",
                    depth_averaged=DepthAveraged(pore_transport=transport),
                )
                runs[transport, a, state] = run_or_load(case, out / f"depth-averaged-{transport}-a{a:g}-{state}")
    record: dict = {"ny": args.ny, "window_s": WINDOW_S, "comparison": {}}
    for a in ASPECT_RATIOS:
        ref = runs["2D", a, "fluidised"]
        t = ref["t_s"][ref["t_s"] <= WINDOW_S + 1e-9]
        entry = {
            "2D": {f"max_{k}": float(np.nanmax(ref[k][: t.size])) for k in ("pf_ratio_reservoir", "pf_ratio_channel")}
        }
        for transport in PORE_TRANSPORTS:
            r = runs[transport, a, "fluidised"]
            e = {}
            for k in ("pf_ratio_reservoir", "pf_ratio_channel"):
                got, want = np.interp(t, r["t_s"], r[k]), ref[k][: t.size]
                e[f"mean_abs_diff_{k}"] = float(np.nanmean(np.abs(got - want)))
                # the ratio as it enters the friction, (1 − β)⁺: above 1 there is no friction
                e[f"mean_abs_diff_friction_{k}"] = float(np.nanmean(np.abs(np.minimum(got, 1) - np.minimum(want, 1))))
                e[f"max_{k}"] = float(np.nanmax(r[k][r["t_s"] <= WINDOW_S + 1e-9]))
            e["front_at_1s_m"] = float(np.interp(1.0, r["t_s"], r["front_m"]))
            e["final_front_m"] = float(r["front_m"][-1])
            entry[transport] = e
        entry["2D"]["front_at_1s_m"] = float(np.interp(1.0, ref["t_s"], ref["front_m"]))
        entry["2D"]["final_front_m"] = float(ref["front_m"][-1])
        record["comparison"][f"a={a:g}"] = entry
    img = ROOT / "docs" / "img"
    (img / "depth_averaged_pore.json").write_text(json.dumps(record, indent=1) + "\n")
    plot(runs, img / "depth_averaged_pore.png", args.ny)
    print(json.dumps(record, indent=1))


def plot(runs: dict, png: Path, ny: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.4))
    styles = {"2D": ("k", f"two-phase, ny = {ny}"), "depth-integrated": ("C0", "depth-averaged, ∫p dz carried")}
    styles["basal-ratio"] = ("C3", "depth-averaged, hβ carried")
    for ls, a in zip(("-", "--"), ASPECT_RATIOS):
        for key, (color, label) in styles.items():
            r = runs[key, a, "fluidised"]
            for ax, k in zip(axes[:2], ("pf_ratio_reservoir", "pf_ratio_channel")):
                ax.plot(r["t_s"], r[k], color=color, ls=ls, lw=1.4, label=f"{label}, a = {a:g}")
            axes[2].plot(r["t_s"], r["front_m"], color=color, ls=ls, lw=1.4, label=f"{label}, a = {a:g}, fluidised")
        for key, color, label in (("2D", "k", "two-phase"), ("depth-integrated", "C0", "depth-averaged")):
            r = runs[key, a, "dry"]
            axes[2].plot(
                r["t_s"], r["front_m"], color=color, ls=ls, lw=0.8, alpha=0.6, label=f"{label}, a = {a:g}, dry"
            )
    for ax, title in zip(axes[:2], ("under the reservoir (x < L_c)", "in the channel (x > L_c)")):
        ax.axhline(1.0, color="grey", lw=0.6)
        ax.set(xlabel="t (s)", ylabel="basal p_f / (ρ g h)", title=f"basal pore-pressure ratio {title}", xlim=(0, 2))
        ax.grid(alpha=0.3)
    axes[1].set_ylim(0, 2.5)
    axes[0].legend(fontsize=7)
    axes[2].set(xlabel="t (s)", ylabel="front from the gate (m)", title="fronts, fluidised and dry", xlim=(0, 3))
    axes[2].grid(alpha=0.3)
    axes[2].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
