"""
A tiny calibration
==================

The pore-pressure diffusivity κ_f sets how fast the fluidised column drains its gas, and so how
long the grains stay fluidised and how far they run. This example runs the paper's fluidised
column to rest (or 3 s) at ny = 16 for three values of κ_f around the paper's 0.035 m² s⁻¹,
and interpolates the κ_f whose run-out matches the experiment's 1.8443 m.

This shows the method, not a result: on this coarse grid the run-out differs from the paper's
grid by tens of per cent (Explanation → Validation), so the κ_f found here says nothing about
the paper's. ``examples/calibrate_runout.py`` does the same over κ_f × η_s on Dask.
"""

# %%
import dataclasses
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from granrs.cases.column import PAPER_RUNOUT_EXP, ColumnCase, column_pore_pressure, run_column

kappas = [0.01, 0.035, 0.1]
out = Path(tempfile.mkdtemp())
runouts = []
for k in kappas:
    pore = dataclasses.replace(column_pore_pressure(), diffusivity=k)
    s = run_column(ColumnCase(ny=16, pore_pressure=pore), out / f"kappa-{k}", progress=False)
    runouts.append(s["runout_m"])
    print(f"κ_f = {k:5.3f} m² s⁻¹: run-out {s['runout_m']:.3f} m ({s['stop_reason']} at t = {s['t_end_s']:.2f} s)")

# %%
# Interpolate in log κ_f
# ----------------------
# The run-out falls as κ_f grows; between two bracketing members, interpolate linearly in
# log κ_f. Outside the bracket there is no fit, and the example says so.
logk, r = np.log(kappas), np.array(runouts)
fit = None
for i in range(len(kappas) - 1):
    if (r[i] - PAPER_RUNOUT_EXP) * (r[i + 1] - PAPER_RUNOUT_EXP) <= 0:
        w = (PAPER_RUNOUT_EXP - r[i]) / (r[i + 1] - r[i])
        fit = float(np.exp(logk[i] + w * (logk[i + 1] - logk[i])))
print(f"κ_f matching {PAPER_RUNOUT_EXP} m at ny = 16: " + (f"{fit:.4f} m² s⁻¹" if fit else "not bracketed"))

fig, ax = plt.subplots(figsize=(5.5, 3.6))
ax.plot(kappas, runouts, "o-", label="granrs, ny = 16")
ax.axhline(PAPER_RUNOUT_EXP, color="k", ls="--", lw=1, label="experiment, 1.8443 m")
if fit:
    ax.axvline(fit, color="C3", lw=1, label=f"κ_f ≈ {fit:.3f}")
ax.set(xscale="log", xlabel="κ_f (m² s⁻¹)", ylabel="run-out from the gate (m)")
ax.grid(alpha=0.3)
ax.legend()
fig.tight_layout()
