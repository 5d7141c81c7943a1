"""Outputs of a run: field snapshots (VTK .vti/.pvd, NetCDF), animation, checkpoints, provenance.

    from granrs.io import FieldWriter, make_animation, provenance
    writer = FieldWriter("out/run", model.grid, formats=["vtk", "netcdf"], provenance=provenance())
    sim = granrs.Simulation(model, stop_time=0.5, callbacks=[granrs.Callback(writer, every_time=0.05)])

NetCDF needs the optional dependency group ``granrs[io]`` (netCDF4; xarray to open the files).
"""

from .animation import load_frames, make_animation
from .checkpoint import Checkpoint, load_checkpoint, restore_checkpoint, save_checkpoint
from .fields import FIELDS, coordinates, snapshot
from .netcdf import NetCDFWriter, read_netcdf
from .provenance import git_revision, provenance
from .vtk import read_pvd, read_vti, write_pvd, write_vti
from .writer import FieldWriter, deferred_interrupt

__all__ = [
    "Checkpoint",
    "FIELDS",
    "FieldWriter",
    "NetCDFWriter",
    "coordinates",
    "deferred_interrupt",
    "git_revision",
    "load_checkpoint",
    "load_frames",
    "make_animation",
    "provenance",
    "read_netcdf",
    "read_pvd",
    "read_vti",
    "restore_checkpoint",
    "save_checkpoint",
    "snapshot",
    "write_pvd",
    "write_vti",
]
