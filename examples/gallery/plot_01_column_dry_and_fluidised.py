"""
The paper's column, dry and fluidised
=====================================

The experiment of the paper: a column of glass beads 0.20 m wide and 0.40 m high is released
in a channel. Fluidised, the column starts with a pore gas pressure that carries 90 % of the
grains' weight, and air is supplied through the base of the reservoir; dry, it has none. The
pore pressure lowers the grains' effective pressure and so their friction: the fluidised column
runs about twice as far.

Both runs use :class:`granrs.cases.column.ColumnCase` with the paper's values, on a coarse grid
(ny = 16) and for the first second only, so that the example runs in seconds.
"""

# %%
# Build and run both cases
# ------------------------
# ``build_model`` turns a case into a :class:`granrs.Model`; a :class:`granrs.Callback` records
# the front (the end of the granular mass on the lowest row of cells, measured from the gate)
# every 10 ms of simulated time.
import matplotlib.pyplot as plt
import numpy as np

import granrs
from granrs.cases.column import ColumnCase, Fluidisation, build_model, front_position

T_END = 1.0


def run(fluidised):
    case = ColumnCase(ny=16, t_end=T_END, fluidisation=Fluidisation(fluidised=fluidised))
    model = build_model(case)
    rec = {"t": [], "front": []}

    def record(sim):
        rec["t"].append(model.time)
        rec["front"].append(front_position(model.phi, model.grid.dx) - case.geometry.width)

    granrs.Simulation(model, stop_time=T_END, callbacks=[granrs.Callback(record, every_time=0.01)]).run()
    return case, model, rec


runs = {name: run(name == "fluidised") for name in ("dry", "fluidised")}
for name, (_case, model, rec) in runs.items():
    print(
        f"{name:9s}: front {rec['front'][-1]:.3f} m from the gate at t = {model.time:.2f} s, {model.step_count} steps"
    )

# %%
# The front against time
# ----------------------
# The collapse accelerates, then the front moves at a nearly constant speed; the fluidised front
# pulls ahead within the first 0.3 s.
fig, ax = plt.subplots(figsize=(6, 3.8))
for name, (_, _, rec) in runs.items():
    ax.plot(rec["t"], rec["front"], label=name)
ax.set(xlabel="t (s)", ylabel="front from the gate (m)", title="column collapse, ny = 16")
ax.grid(alpha=0.3)
ax.legend()
fig.tight_layout()

# %%
# The grains at t = 1 s
# ---------------------
# ``model.phi`` is the level set (Φ > 0 in the grains) and ``model.pf`` the pore pressure, both
# read-only NumPy views at the cell centres, shape (ny, nx).
fig, axes = plt.subplots(2, 1, figsize=(7, 3.6), sharex=True, layout="constrained")
pf_image = None
for ax, (name, (case, model, _)) in zip(axes, runs.items()):
    g = model.grid
    extent = (0, g.lx, 0, g.ly)
    ax.imshow(
        np.where(model.phi > 0, 1.0, np.nan),
        origin="lower",
        extent=extent,
        cmap="Oranges",
        vmin=0,
        vmax=1.5,
        aspect="auto",
    )
    if model.pore_pressure is not None:
        pf_image = ax.imshow(
            np.where(model.phi > 0, model.pf, np.nan), origin="lower", extent=extent, cmap="viridis", aspect="auto"
        )
    ax.axvline(case.geometry.width, color="k", lw=0.8, ls="--")
    ax.set(xlim=(0, 2.0), ylabel="y (m)", title=f"{name}, t = {model.time:.1f} s")
axes[-1].set_xlabel("x (m); dashed: the gate; orange: grains without pore pressure")
fig.colorbar(pf_image, ax=list(axes), label="pore pressure p_f (Pa)")
plt.show()
