"""An animated GIF of the collapse, made from the fields saved in an output folder.

``make_animation(out)`` reads ``out/fields.nc`` (when netCDF4 is installed) or ``out/fields.pvd``
and its .vti files, and writes ``out/animation.gif`` with matplotlib's PillowWriter: the granular
speed inside the granular phase (Φ > 0) with the interface Φ = 0, and the pore pressure below
when the run is fluidised. Colour scales are fixed over the whole run.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from .netcdf import available, read_netcdf
from .outputs import record
from .vtk import read_pvd, read_vti


def load_frames(out) -> Optional[dict]:
    """{"time": (nt,), "x", "y", "phi", "speed", "pf" (or None)} from the saved fields, or None."""
    out = Path(out)
    if (out / "fields.nc").exists() and available():
        data = read_netcdf(out / "fields.nc")
        f = data["fields"]
        if data["time"].size == 0:
            return None
        return {
            "time": data["time"],
            "x": data["x"],
            "y": data["y"],
            "phi": f["phi"],
            "speed": np.hypot(f["u"], f["v"]),
            "pf": f.get("pf"),
        }
    if (out / "fields.pvd").exists():
        frames = [read_vti(p) for _, p in read_pvd(out / "fields.pvd")]
        if not frames:
            return None
        ny, nx = frames[0]["shape"]
        dx, dy = frames[0]["spacing"][:2]
        fields = [fr["fields"] for fr in frames]
        return {
            "time": np.array([fr["time"] for fr in frames]),
            "x": (np.arange(nx) + 0.5) * dx,
            "y": (np.arange(ny) + 0.5) * dy,
            "phi": np.array([f["phi"] for f in fields]),
            "speed": np.array([np.hypot(f["velocity"][..., 0], f["velocity"][..., 1]) for f in fields]),
            "pf": np.array([f["pf"] for f in fields]) if "pf" in fields[0] else None,
        }
    return None


def make_animation(out, path=None, fps: int = 8, dpi: int = 90) -> Optional[Path]:
    """Writes the GIF (default ``out/animation.gif``); returns its path, or None without saved fields."""
    import matplotlib  # deferred: pyplot's backend is chosen (Agg) when a figure is made, not on import

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after its backend is chosen
    from matplotlib.animation import PillowWriter  # deferred: with pyplot, after its backend is chosen

    data = load_frames(out)
    if data is None:
        return None
    path = Path(path) if path is not None else Path(out) / "animation.gif"
    record(path)
    x, y, phi = data["x"], data["y"], data["phi"]
    speed = np.where(phi > 0, data["speed"], np.nan)
    panels = [("granular speed (m/s)", speed, "viridis")]
    if data["pf"] is not None:
        panels.append(("pore pressure p_f (Pa)", np.where(phi > 0, data["pf"], np.nan), "magma"))
    lx, ly = x[-1] + x[0], y[-1] + y[0]
    fig, axes = plt.subplots(
        len(panels), 1, figsize=(9, 0.8 + len(panels) * 9 * ly / lx * 1.1), squeeze=False, layout="constrained"
    )
    extent = (0, lx, 0, ly)
    images, contours = [], []
    for ax, (label, values, cmap) in zip(axes[:, 0], panels):
        vmax = float(np.nanmax(values)) if np.isfinite(values).any() else 1.0
        im = ax.imshow(
            values[0],
            origin="lower",
            extent=extent,
            cmap=cmap,
            vmin=0.0,
            vmax=max(vmax, 1e-12),
            aspect="equal",
            interpolation="nearest",
        )
        fig.colorbar(im, ax=ax, label=label, fraction=0.025, pad=0.01)
        ax.set(ylabel="y (m)")
        images.append((im, values))
        contours.append(ax)
    axes[-1, 0].set_xlabel("x (m)")
    title = fig.suptitle("")
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(path), dpi):
        for k, t in enumerate(data["time"]):
            drawn = []
            for (im, values), ax in zip(images, contours):
                im.set_data(values[k])
                drawn.append(ax.contour(x, y, phi[k], levels=[0.0], colors="w", linewidths=1.0))
            title.set_text(f"column collapse, t = {t:.3f} s")
            writer.grab_frame()
            for c in drawn:
                c.remove()
    plt.close(fig)
    return path
