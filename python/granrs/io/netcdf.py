"""NetCDF-4 time series of the fields (``fields.nc``), CF-style, readable with ``xarray.open_dataset``.

Dimensions (time, y, x); coordinates x, y (cell centres, m) and time (simulated seconds since the
release, units "s" so that xarray keeps plain floats); each field carries ``long_name`` and
UDUNITS ``units`` from ``granrs.io.fields.FIELDS``. Global attributes follow CF (Conventions,
title, source, history, references) and carry the provenance (granrs_version, git_revision,
command_line, configuration). The file is opened, extended by one record and closed at each
output time, so an interrupted run leaves a readable file with the records written so far.
Needs the optional dependency netCDF4 (``pip install granrs[io]``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .fields import FIELDS
from .outputs import OutputError, record

REFERENCE = (
    "Aravena, Chupin, Dubois & Roche, Fluidisation by pore pressure of dense granular flows: "
    "numerical simulations versus experiments"
)


def available() -> bool:
    try:
        import netCDF4  # noqa: F401  # deferred: optional dependency (the io extra)
    except ImportError:
        return False
    return True


class NetCDFWriter:
    """Appends one time record per ``append(time, fields)`` to ``path`` (created on the first call)."""

    def __init__(self, path, x: np.ndarray, y: np.ndarray, provenance: dict, title: str = "granrs fields"):
        self.path = Path(path)
        self.x, self.y = np.asarray(x, float), np.asarray(y, float)
        self.provenance = provenance
        self.title = title
        self.records = 0

    def _create(self, fields: dict):
        import netCDF4  # deferred: optional dependency (the io extra)

        ds = netCDF4.Dataset(self.path, "w", format="NETCDF4")
        prov = self.provenance
        ds.setncatts(
            {
                "Conventions": "CF-1.10",
                "title": self.title,
                "source": f"granrs {prov['granrs_version']} (git {prov['git_revision'] or 'unknown'})",
                "history": f"{prov['created_utc']}: {prov['command_line']}",
                "references": REFERENCE,
                "comment": "2D fluidised granular column collapse: level-set two-phase Navier-Stokes, viscoplastic rheology",
                **{k: str(v) for k, v in prov.items()},
            }
        )
        ds.createDimension("time", None)
        ds.createDimension("y", self.y.size)
        ds.createDimension("x", self.x.size)
        t = ds.createVariable("time", "f8", ("time",))
        t.setncatts(
            {"standard_name": "time", "long_name": "simulated time since the release", "units": "s", "axis": "T"}
        )
        for name, values, long_name, axis in (
            ("x", self.x, "distance along the channel from the back wall", "X"),
            ("y", self.y, "height above the base", "Y"),
        ):
            var = ds.createVariable(name, "f8", (name,))
            var.setncatts({"long_name": long_name, "units": "m", "axis": axis})
            var[:] = values
        for name, arr in fields.items():
            dtype = "u1" if arr.dtype == np.uint8 else "f8"
            var = ds.createVariable(name, dtype, ("time", "y", "x"), zlib=True, complevel=4)
            var.setncatts({k: (np.array(v, dtype=dtype) if k == "flag_values" else v) for k, v in FIELDS[name].items()})
        return ds

    def append(self, time: float, fields: dict) -> None:
        """One record more; a failure of the NetCDF library (a full disk: an HDF error) is an
        ``OutputError`` naming the file."""
        import netCDF4  # deferred: optional dependency (the io extra)

        if self.records == 0:
            record(self.path)
        try:
            ds = self._create(fields) if self.records == 0 else netCDF4.Dataset(self.path, "a")
            try:
                n = self.records  # a restart's writer starts after the records it keeps
                ds["time"][n] = time
                for name, arr in fields.items():
                    ds[name][n, :, :] = arr
            finally:
                ds.close()
        except (OSError, RuntimeError) as err:
            raise OutputError(
                f"cannot write {self.path} ({getattr(err, 'strerror', None) or err}); the files written before "
                f"are kept in {self.path.parent}"
            ) from None
        self.records += 1


def read_netcdf(path) -> dict:
    """{"time": (nt,), "x", "y", "fields": {name: (nt, ny, nx)}, "attrs"} read with netCDF4."""
    import netCDF4  # deferred: optional dependency (the io extra)

    with netCDF4.Dataset(path) as ds:
        names = [n for n in ds.variables if n not in ("time", "x", "y")]
        return {
            "time": np.array(ds["time"][:]),
            "x": np.array(ds["x"][:]),
            "y": np.array(ds["y"][:]),
            "fields": {n: np.array(ds[n][:]) for n in names},
            "attrs": {k: ds.getncattr(k) for k in ds.ncattrs()},
        }
