"""FieldWriter: a Simulation callback that saves the fields on a simulated-time schedule.

    writer = FieldWriter(out, model.grid, formats=["vtk", "netcdf"], provenance=prov)
    sim = Simulation(model, stop_time=1.0, callbacks=[Callback(writer, every_time=0.05)])

Each call writes ``out/fields/fields_NNNNN.vti`` and rewrites ``out/fields.pvd`` (VTK), and/or
appends a record to ``out/fields.nc`` (NetCDF). A Ctrl-C that arrives while a snapshot is being
written is held until the snapshot is complete, so the files on disk are always readable.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable
from pathlib import Path

from .._granrs import ParameterError
from ..simulation import deferred_interrupt
from .fields import coordinates, snapshot
from .netcdf import NetCDFWriter, available
from .outputs import OutputError, read_manifest, record
from .provenance import provenance as make_provenance
from .vtk import read_pvd, write_pvd, write_vti

FORMATS = ("vtk", "netcdf")


@contextlib.contextmanager
def _output_errors(out: Path):
    """An OSError of a snapshot's write (a full disk) as an OutputError naming the folder."""
    try:
        yield
    except OutputError:
        raise
    except OSError as err:
        raise OutputError(
            f"cannot write a field snapshot in {out} ({err.strerror or err}); the files written before "
            f"are kept in {out}"
        ) from None


class FieldWriter:
    """Writes snapshots of ``granrs.io.fields.snapshot(model)`` in the given formats. A new writer
    replaces the snapshots in ``out``; with ``append_after`` = t (a restart at t) it keeps those
    up to t and numbers its own after them."""

    def __init__(
        self,
        out,
        grid,
        formats: Iterable[str] = ("vtk",),
        provenance: dict | None = None,
        append_after: float | None = None,
    ):
        self.out = Path(out)
        self.formats = tuple(formats)
        for f in self.formats:
            if f not in FORMATS:
                raise ParameterError(f"invalid parameter `formats` item {f!r}: allowed 'vtk' or 'netcdf'")
        if "netcdf" in self.formats and not available():
            raise ParameterError(
                "invalid parameter `output.formats` item 'netcdf': needs the optional dependency "
                "netCDF4 (pip install 'granrs[io]')"
            )
        self.grid = grid
        self.provenance = provenance
        self.entries: list[tuple[float, str]] = []
        self.times: list[float] = []
        kept_nc = 0
        #: the time of the last snapshot kept by a restart: the restart's first one, at the same
        #: time, is not written again
        self._kept_last: float | None = None
        if append_after is None:
            listed = read_manifest(self.out) or set()  # only what the folder's manifest lists as granrs's
            for stale in [self.out / "fields.pvd", self.out / "fields.nc", *self.out.glob("fields/fields_*.vti")]:
                if stale.relative_to(self.out).as_posix() in listed and not stale.is_symlink():
                    stale.unlink(missing_ok=True)  # a previous run's snapshots in the same folder
        else:
            if (self.out / "fields.pvd").exists():
                self.entries = [
                    (t, str(Path(name).relative_to(self.out)))
                    for t, name in read_pvd(self.out / "fields.pvd")
                    if t <= append_after * (1 + 1e-12)
                ]
            if (self.out / "fields.nc").exists():
                import netCDF4  # deferred: optional dependency (the io extra)

                with netCDF4.Dataset(self.out / "fields.nc") as ds:
                    times = ds["time"][:]
                    kept_nc = int((times <= append_after * (1 + 1e-12)).sum())
                    if kept_nc:
                        self._kept_last = float(times[kept_nc - 1])
            if self.entries:
                self._kept_last = self.entries[-1][0]
        x, y = coordinates(grid)
        # the NetCDF attributes need a provenance: this process's when none is given
        nc_provenance = provenance if provenance is not None else make_provenance()
        self.netcdf = NetCDFWriter(self.out / "fields.nc", x, y, nc_provenance) if "netcdf" in self.formats else None
        if self.netcdf is not None:
            self.netcdf.records = kept_nc
        if "vtk" in self.formats:
            record(self.out / "fields", folder=True)
            (self.out / "fields").mkdir(parents=True, exist_ok=True)

    def __call__(self, sim) -> None:
        self.write(sim.model)

    def write(self, model) -> None:
        t = float(model.time)
        if self._kept_last is not None and abs(t - self._kept_last) <= 1e-12 * max(1.0, abs(t)):
            self._kept_last = None  # the restart's state at the time of the last kept snapshot
            self.times.append(t)
            return
        self._kept_last = None
        fields = snapshot(model)
        with deferred_interrupt(), _output_errors(self.out):
            if "vtk" in self.formats:
                name = f"fields/fields_{len(self.entries):05d}.vti"
                write_vti(self.out / name, fields, (self.grid.dx, self.grid.dy), t, self.provenance)
                self.entries.append((t, name))
                write_pvd(self.out / "fields.pvd", self.entries, self.provenance)
            if self.netcdf is not None:
                self.netcdf.append(t, fields)
            self.times.append(t)

    @property
    def frames(self) -> int:
        return len(self.times)
