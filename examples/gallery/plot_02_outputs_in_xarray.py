"""
Reading the outputs in xarray (and ParaView)
============================================

A run described by a run file writes field snapshots every ``output.fields_every_s`` seconds of
simulated time: NetCDF (``fields.nc``, CF attributes, for xarray) and VTK XML image data
(``fields.pvd`` with ``fields/*.vti``, for ParaView). This example runs the paper's fluidised
column for 0.2 s at ny = 16 and reads both back.
"""

# %%
# Run a run file
# --------------
# ``load_config`` reads and validates the TOML file, with overrides in the ``--set`` form;
# ``run_config`` runs it and writes every output into ``output.dir``.
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import xarray as xr

from granrs.config import load_config
from granrs.io import read_pvd, read_vti
from granrs.runner import run_config

out = Path(tempfile.mkdtemp()) / "fluidised"
# the run file of the paper's fluidised case, found from the repository or its examples/gallery
run_file = next(
    d / "examples" / "paper_fluidised.toml"
    for d in (Path.cwd(), *Path.cwd().parents)
    if (d / "examples" / "paper_fluidised.toml").exists()
)
cfg = load_config(
    run_file,
    [
        "grid.ny=16",
        "time.t_end=0.2",
        "output.fields_every_s=0.05",
        'output.formats=["netcdf", "vtk"]',
        "output.animation=false",
        f'output.dir="{out}"',
    ],
)
summary = run_config(cfg, progress=False)
print(sorted(p.name for p in out.iterdir()))

# %%
# The snapshots as an xarray Dataset
# ----------------------------------
# One variable per field, on cell-centre coordinates, with a time dimension.
ds = xr.open_dataset(out / "fields.nc")
print(ds)

# %%
# Select by time and plot: the level set's zero contour is the grains' surface, coloured by the
# pore pressure inside.
fig, axes = plt.subplots(len(ds.time), 1, figsize=(7, 1.4 * len(ds.time)), sharex=True, layout="constrained")
vmax = float(ds["pf"].max())
for ax, t in zip(axes, ds.time.values):
    snap = ds.sel(time=t)
    image = (
        snap["pf"]
        .where(snap["phi"] > 0)
        .plot(ax=ax, x=snap["phi"].dims[-1], add_colorbar=False, cmap="viridis", vmin=0, vmax=vmax)
    )
    snap["phi"].plot.contour(ax=ax, x=snap["phi"].dims[-1], levels=[0.0], colors="k", linewidths=0.8)
    ax.set(xlim=(0, 1.0), title=f"t = {float(t):.2f} s", xlabel="", ylabel="y (m)")
axes[-1].set_xlabel("x (m)")
fig.colorbar(image, ax=list(axes), label="pore pressure p_f (Pa)")
ds.close()

# %%
# The VTK files, as ParaView reads them
# -------------------------------------
# ``fields.pvd`` lists the snapshots with their times; each ``.vti`` is a uniform grid with the
# fields as cell data. In ParaView: *File → Open* ``fields.pvd``, colour by ``phi`` or ``pf``, add
# a *Contour* filter at ``phi = 0`` for the surface; the time controls step through the snapshots.
# The same files read back in Python:
entries = read_pvd(out / "fields.pvd")
print(entries[:2])
t_last, vti = entries[-1]
snap = read_vti(vti)
print(
    f"t = {t_last:.2f} s: {snap['shape']} cells of {snap['spacing'][0] * 1e3:.1f} mm, fields {sorted(snap['fields'])}"
)
