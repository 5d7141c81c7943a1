"""The fields saved at each output time, all at cell centres, and their names, units and meanings.

``snapshot(model)`` copies the live views into a dict ``name -> (ny, nx) array``:
phi (level set), volume_fraction (the conserved dense volume fraction F, models with
``interface_transport = "clsvof"`` only), u and v (velocity averaged to cell centres), p (pressure),
pf (pore pressure, fluidised models only) and yielded (1 where the granular phase has yielded, models with a
plastic tensor only).
"""

from __future__ import annotations

from typing import Any

import numpy as np

# CF-style attributes (UDUNITS units) of each field; the order is the order in the files.
FIELDS: dict[str, dict[str, Any]] = {
    "phi": {"long_name": "level set: signed distance to the interface, positive in the granular phase", "units": "m"},
    "volume_fraction": {"long_name": "volume fraction of the granular phase in the cell", "units": "1"},
    "u": {"long_name": "x-velocity at cell centres (along the channel)", "units": "m s-1"},
    "v": {"long_name": "y-velocity at cell centres (upwards)", "units": "m s-1"},
    "p": {"long_name": "pressure", "units": "Pa"},
    "pf": {"long_name": "pore gas pressure", "units": "Pa"},
    "yielded": {
        "long_name": "yielded granular cell: 1 where phi > 0 and the trial stress norm exceeds 1, else 0",
        "units": "1",
        "flag_values": [0, 1],
        "flag_meanings": "not_yielded yielded",
    },
}


def snapshot(model) -> dict[str, np.ndarray]:
    """Copies of the model's fields at cell centres, each (ny, nx), in ``FIELDS`` order.

    The yielded mask is ``(trial_norm > 1) & (phi > 0)``: trial_norm is the argument of the
    plastic projection, <= 1 exactly where the material is rigid; in the air (no yield stress)
    it is meaningless, so the mask is 0 there."""
    uc, vc = model.centre_velocity()
    out = {"phi": np.array(model.phi)}
    if getattr(model, "volume_fraction", None) is not None:
        out["volume_fraction"] = np.array(model.volume_fraction)
    out |= {"u": np.array(uc), "v": np.array(vc), "p": np.array(model.p)}
    if getattr(model, "pore_pressure", None) is not None:
        out["pf"] = np.array(model.pf)
    if getattr(model, "_has_plastic", False):
        out["yielded"] = ((np.asarray(model.trial_norm) > 1.0) & (out["phi"] > 0)).astype(np.uint8)
    return out


def coordinates(grid) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) of the cell centres, 1-D."""
    return (np.arange(grid.nx) + 0.5) * grid.dx, (np.arange(grid.ny) + 0.5) * grid.dy
