"""Level-set validation: Zalesak's slotted disk, the Rider–Kothe single vortex, and the dam break
of Martin & Moyce (1952)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import _granrs
from ..boundary import BoundaryConditions, FreeSlip, Outflow
from ..grid import Grid
from ..materials import Material
from ..model import Model, Numerics
from ..shapes import Rectangle

#: the exact area of Zalesak's slotted disk (radius 15, slot 5 wide and 25 deep, in the 100 × 100
#: box; Zalesak 1979, docs/reference-data.md): after one revolution the disk is back where it started
ZALESAK_AREA = 582.207
#: the Rider–Kothe vortex (Rider & Kothe 1998) reverses at t = T/2, so at t = T the exact interface
#: is the initial circle of radius 0.15: its area
SINGLE_VORTEX_AREA = math.pi * 0.15**2


def zalesak(n: int, redistance_every: int = 0, cfl: float = 0.5, threads: int = 1):
    """One revolution of Zalesak's disk (docs/reference-data.md); area against the exact area, and
    the symmetric difference with the exact disk."""
    m = _granrs.levelset_validation("zalesak", int(n), 628.0, int(redistance_every), float(cfl), threads)
    m["area_rel_error"] = (m["area_final"] - ZALESAK_AREA) / ZALESAK_AREA
    limit = 0.02 if redistance_every else 0.01
    passed = abs(m["area_rel_error"]) <= limit and (redistance_every or m["symdiff_rel"] <= 0.05)
    reference = {
        "area_exact": ZALESAK_AREA,
        "source": "exact area of the slotted disk (Zalesak 1979)",
        "acceptance": f"|area_rel_error| <= {limit:.0%}" + ("" if redistance_every else ", symdiff_rel <= 5 %"),
    }
    return m, reference, bool(passed)


def single_vortex(n: int, period: float = 2.0, redistance_every: int = 0, cfl: float = 0.5, threads: int = 1):
    """Rider–Kothe single vortex, evaluated at t = T against the initial circle. The acceptance
    (area within 1 %) is stated for T = 2; for other T (T = 8, the hard case, loses tens of per
    cent with plain level sets) the metrics are reported with ``passed`` None."""
    m = _granrs.levelset_validation("single-vortex", int(n), float(period), int(redistance_every), float(cfl), threads)
    m["area_rel_error"] = (m["area_final"] - SINGLE_VORTEX_AREA) / SINGLE_VORTEX_AREA
    passed = abs(m["area_rel_error"]) <= 0.01 if abs(period - 2.0) <= 1e-12 else None
    reference = {
        "area_exact": SINGLE_VORTEX_AREA,
        "source": "the initial circle (the flow reverses at T/2)",
        "acceptance": "|area_rel_error| <= 1 % for T = 2; other T: reported, passed null",
    }
    return m, reference, passed


# Martin & Moyce (1952), Phil. Trans. R. Soc. A 244, 312-324, a = 2.25 in, height 2a:
# dimensionless front Z = x/a against T = t √(2g/a) (docs/reference-data.md, "Dam break").
MARTIN_MOYCE = np.array(
    [
        [0.0, 1.00],
        [0.41, 1.11],
        [0.84, 1.22],
        [1.19, 1.44],
        [1.43, 1.67],
        [1.63, 1.89],
        [1.83, 2.11],
        [1.98, 2.33],
        [2.20, 2.56],
        [2.32, 2.78],
        [2.51, 3.00],
        [2.65, 3.22],
        [2.83, 3.44],
        [2.98, 3.67],
        [3.11, 3.89],
        [3.33, 4.11],
    ]
)


def _front(phi_row: np.ndarray, dx: float) -> float:
    """Largest x where Φ > 0 on a row of cell centres, at the linear zero crossing."""
    inside = np.nonzero(phi_row > 0)[0]
    if inside.size == 0:
        return 0.0
    i = inside[-1]
    xc = (i + 0.5) * dx
    if i + 1 >= phi_row.size:
        return xc
    return xc + dx * phi_row[i] / (phi_row[i] - phi_row[i + 1])


def _speed_fit(t, z, lo=1.5, hi=3.0):
    sel = (t >= lo) & (t <= hi)
    return float(np.polyfit(t[sel], z[sel], 1)[0])


def run_dam_break(
    n: int = 32,
    threads: int = 1,
    cfl: float = 0.4,
    out: Path | None = None,
    mass_correction: bool = True,
    air: str = "resolved",
):
    """Water column of width a = 0.05715 m and height 2a under air (density ratio 1000) in a box
    7a × 2.5a with free-slip walls and an open top; n cells across a. The simulated front leads
    the experiment (the gate is removed instantly here), so the box is long enough for Z ≈ 5 at T = 3.33.
    ``air='free-surface'``: the granular-only model's free surface (the air not resolved) instead of
    the two-phase model; the plot is then ``dam_break_free_surface.png``."""
    a = 0.05715
    g = 9.81
    grid = Grid(7 * n, int(2.5 * n), 7 * a, 2.5 * a)
    model = Model(
        grid,
        Material(1000.0, 1.0e-3),
        light=Material(1.0, 1.8e-5),
        gravity=(0.0, -g),
        bc=BoundaryConditions(left=FreeSlip(), right=FreeSlip(), bottom=FreeSlip(), top=Outflow()),
        numerics=Numerics(cfl=cfl, mass_correction=mass_correction),
        threads=threads,
        air=air,
    )
    model.set_shape(Rectangle(-1.0, a, -1.0, 2 * a))
    area0 = model.dense_area()
    t_scale = math.sqrt(2 * g / a)
    t_end = 3.33 / t_scale
    times, fronts, areas = [0.0], [_front(model.phi[0], grid.dx) / a], [area0]
    while model.time < t_end - 1e-12:
        model.advance(t_end=min(t_end, model.time + 0.02 / t_scale))
        times.append(model.time * t_scale)
        fronts.append(_front(model.phi[0], grid.dx) / a)
        areas.append(model.dense_area())
    T, Z = np.array(times), np.array(fronts)
    speed = _speed_fit(T, Z)
    speed_exp = _speed_fit(MARTIN_MOYCE[:, 0], MARTIN_MOYCE[:, 1])
    area_change = float(np.max(np.abs(np.array(areas)[T <= 3.0] - area0)) / area0)
    table = [[float(t), float(np.interp(t, T, Z)), float(z)] for t, z in MARTIN_MOYCE]
    # alignment at Z = 1.44 (docs/reference-data.md, "Dam break"): the simulation leads early because the gate
    # is removed instantly; shift its time so that it reaches Z = 1.44 at the experiment's T = 1.19
    t_align = float(np.interp(1.44, Z, T)) - 1.19
    aligned_err = np.interp(MARTIN_MOYCE[:, 0] + t_align, T, Z) - MARTIN_MOYCE[:, 1]
    sel = (MARTIN_MOYCE[:, 0] >= 1.19) & (MARTIN_MOYCE[:, 0] + t_align <= T[-1])
    if out is not None:
        import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # deferred: after its backend is chosen

        out.mkdir(parents=True, exist_ok=True)
        fig, ax = plt.subplots(figsize=(6, 4.2))
        ax.plot(
            T,
            Z,
            "C0-",
            label=f"granrs ({'free surface' if air == 'free-surface' else 'two-phase'}), {n} cells across a",
        )
        ax.plot(T - t_align, Z, "C0--", lw=1, label=f"granrs aligned at Z = 1.44 (ΔT = {t_align:.2f})")
        ax.plot(MARTIN_MOYCE[:, 0], MARTIN_MOYCE[:, 1], "ks", mfc="none", label="Martin & Moyce 1952")
        ax.set(xlabel="T = t √(2g/a)", ylabel="Z = x_front / a", title="Dam break, water under air (ρ ratio 1000)")
        ax.grid(alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / ("dam_break_free_surface.png" if air == "free-surface" else "dam_break.png"), dpi=120)
        plt.close(fig)
    return {
        "front_speed": speed,
        "front_speed_experiment": speed_exp,
        "front_speed_rel_error": (speed - speed_exp) / speed_exp,
        "area_rel_change_max": area_change,
        "time_shift_at_Z_1_44": t_align,
        "aligned_max_abs_dZ": float(np.max(np.abs(aligned_err[sel]))),
        "table_T_Zsim_Zexp": table,
        "steps": model.step_count,
        "mass_correction": mass_correction,
        "air": air,
    }


def dam_break(n: int = 32, mass_correction: bool = True, threads: int = 1, air: str = "resolved"):
    m = run_dam_break(n, threads, out=Path("out/validation"), mass_correction=mass_correction, air=air)
    passed = abs(m["front_speed_rel_error"]) <= 0.10 and m["area_rel_change_max"] <= 0.01
    reference = {
        "source": 'Martin & Moyce 1952 (docs/reference-data.md, "Dam break")',
        "acceptance": "front speed dZ/dT over T in [1.5, 3] within 10 %; area conserved within 1 % to T = 3",
        "plot": "out/validation/" + ("dam_break_free_surface.png" if air == "free-surface" else "dam_break.png"),
    }
    return m, reference, bool(passed)
