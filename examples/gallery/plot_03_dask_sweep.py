"""
A sweep on Dask
===============

:func:`granrs.sweep.run_sweep` runs the cartesian product of parameter values of a run file on
``dask.distributed``: here a local cluster of two single-threaded workers (on a cluster, pass
``scheduler="tcp://HOST:8786"`` instead). Each member is the paper's fluidised column at ny = 16,
run to 0.5 s, for two pore-pressure diffusivities κ_f and two CFL numbers. The results come back
as a table, an xarray Dataset with one dimension per swept key, and files.
"""

# %%
# The whole script sits under ``if __name__ == "__main__":``: Dask starts its workers as new
# processes, which re-import the main module, and they must not start a sweep of their own.
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from granrs.config import load_config
from granrs.sweep import run_sweep

if __name__ == "__main__":  # Dask's worker processes re-import the main module
    run_file = next(
        d / "examples" / "paper_fluidised.toml"
        for d in (Path.cwd(), *Path.cwd().parents)
        if (d / "examples" / "paper_fluidised.toml").exists()
    )
    cfg = load_config(run_file, ["grid.ny=16", "time.t_end=0.5", "output.fields_every_s=0", "output.animation=false"])
    out = Path(tempfile.mkdtemp()) / "sweep"
    result = run_sweep(cfg, ["pore_pressure.diffusivity=0.01,0.1", "time.cfl=0.25,0.5"], workers=2, out=out)
    for row in result.table:
        print(
            f"κ_f = {row['pore_pressure.diffusivity']:5.3f}, CFL = {row['time.cfl']:.2f}: "
            f"front {row['runout_m']:.3f} m at t = {row['t_end_s']:.2f} s ({row['status']}, {row['steps']} steps)"
        )

    # the Dataset has one dimension per swept key
    ds = result.dataset
    print(ds)
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for cfl in ds["time.cfl"].values:
        sel = ds.sel({"time.cfl": cfl})
        ax.plot(sel["pore_pressure.diffusivity"], sel["runout_m"], "o-", label=f"CFL {cfl:g}")
    ax.set(
        xscale="log",
        xlabel="κ_f (m² s⁻¹)",
        ylabel="front at 0.5 s (m)",
        title="a faster-draining pore pressure shortens the flow",
    )
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
