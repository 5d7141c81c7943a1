"""VTK XML ImageData (.vti) snapshots and their .pvd time-series index, for ParaView.

Written with NumPy only: cell data in base64 "binary" inline format (an 8-byte little-endian
byte count, then the little-endian data, encoded together, as VTK expects for uncompressed data).
Scalars are CellData arrays; the velocity is a 3-component vector "velocity" (u, v, 0). The
simulated time is FieldData "TimeValue". Provenance is an XML comment holding JSON
(``granrs.io.provenance.xml_comment``). ``read_vti`` and ``read_pvd`` read them back.
"""

from __future__ import annotations

import base64
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Optional
from xml.sax.saxutils import quoteattr

import numpy as np

from .outputs import atomic_write
from .provenance import from_xml, xml_comment

_VTK_TYPES: dict[np.dtype, str] = {
    np.dtype("<f8"): "Float64",
    np.dtype("<f4"): "Float32",
    np.dtype("uint8"): "UInt8",
    np.dtype("<i4"): "Int32",
    np.dtype("<i8"): "Int64",
}
_NP_TYPES: dict[str, np.dtype] = {v: k for k, v in _VTK_TYPES.items()}


def _data_array(name: str, data: np.ndarray, components: int = 1) -> str:
    data = np.ascontiguousarray(data)
    if data.dtype.kind == "f":
        data = data.astype("<f8")
    elif data.dtype.kind in "iu" and data.dtype.itemsize > 1:
        data = data.astype("<i8")
    raw = data.tobytes()
    encoded = base64.b64encode(np.array([len(raw)], dtype="<u8").tobytes() + raw).decode("ascii")
    return (
        f'        <DataArray type="{_VTK_TYPES[data.dtype]}" Name={quoteattr(name)} '
        f'NumberOfComponents="{components}" NumberOfTuples="{data.size // components}" format="binary">\n'
        f"          {encoded}\n        </DataArray>\n"
    )


def _atomic_write(path: Path, text: str) -> None:
    """Writes through a temporary file and a rename, so a reader never sees half a file."""
    atomic_write(path, lambda f: f.write(text))


def write_vti(path, fields: dict, spacing: tuple[float, float], time: float, provenance: Optional[dict] = None) -> Path:
    """Writes cell-centred fields (each (ny, nx), rows along y) on the grid [0, nx dx] × [0, ny dy];
    "u" and "v", when both present, become the vector "velocity"."""
    path = Path(path)
    ny, nx = next(iter(fields.values())).shape
    dx, dy = spacing
    parts = ['<?xml version="1.0"?>\n']
    if provenance is not None:
        parts.append(xml_comment(provenance) + "\n")
    parts.append(
        '<VTKFile type="ImageData" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n'
        f'  <ImageData WholeExtent="0 {nx} 0 {ny} 0 0" Origin="0 0 0" Spacing="{dx!r} {dy!r} {dx!r}">\n'
        "    <FieldData>\n" + _data_array("TimeValue", np.array([time], dtype=float)) + "    </FieldData>\n"
        f'    <Piece Extent="0 {nx} 0 {ny} 0 0">\n      <CellData Scalars="phi" Vectors="velocity">\n'
    )
    for name, arr in fields.items():
        if name in ("u", "v") and "u" in fields and "v" in fields:
            continue
        parts.append(_data_array(name, arr))
    if "u" in fields and "v" in fields:
        vel = np.stack([fields["u"], fields["v"], np.zeros_like(fields["u"])], axis=-1)
        parts.append(_data_array("velocity", vel, components=3))
    parts.append("      </CellData>\n    </Piece>\n  </ImageData>\n</VTKFile>\n")
    _atomic_write(path, "".join(parts))
    return path


def write_pvd(path, entries: list[tuple[float, str]], provenance: Optional[dict] = None) -> Path:
    """Writes the .pvd collection of (time, relative file name) entries."""
    path = Path(path)
    lines = ['<?xml version="1.0"?>']
    if provenance is not None:
        lines.append(xml_comment(provenance))
    lines += ['<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">', "  <Collection>"]
    lines += [f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>' for t, f in entries]
    lines += ["  </Collection>", "</VTKFile>", ""]
    _atomic_write(path, "\n".join(lines))
    return path


def _find(parent: ET.Element, path: str) -> ET.Element:
    """The element at ``path`` under ``parent``; a file without it is not one ``write_vti`` or
    ``write_pvd`` wrote."""
    found = parent.find(path)
    if found is None:
        raise ValueError(f"not a VTK file written by granrs: no <{path}> in <{parent.tag}>")
    return found


def _attr(elem: ET.Element, name: str) -> str:
    """The attribute ``name`` of ``elem`` (an error naming it when missing)."""
    value = elem.get(name)
    if value is None:
        raise ValueError(f"not a VTK file written by granrs: <{elem.tag}> has no attribute {name!r}")
    return value


def _decode(elem: ET.Element, count: int) -> np.ndarray:
    dtype = _NP_TYPES[_attr(elem, "type")]
    comps = int(elem.get("NumberOfComponents", "1"))
    if elem.get("format") == "ascii":
        return np.array((elem.text or "").split(), dtype=dtype).reshape(count, comps)
    raw = base64.b64decode("".join((elem.text or "").split()))
    nbytes = int(np.frombuffer(raw[:8], dtype="<u8")[0])
    return np.frombuffer(raw[8 : 8 + nbytes], dtype=dtype).reshape(count, comps)


def read_vti(path) -> dict:
    """Reads a .vti written by ``write_vti``: {"time", "spacing", "origin", "shape" (ny, nx),
    "fields": {name: (ny, nx) or (ny, nx, 3) array}, "provenance"}."""
    text = Path(path).read_text(encoding="utf-8")
    root = ET.fromstring(text)
    image = _find(root, "ImageData")
    ext = [int(e) for e in _attr(image, "WholeExtent").split()]
    nx, ny = ext[1] - ext[0], ext[3] - ext[2]
    fields = {}
    for arr in _find(_find(image, "Piece"), "CellData"):
        data = _decode(arr, nx * ny)
        fields[_attr(arr, "Name")] = data.reshape(ny, nx) if data.shape[1] == 1 else data.reshape(ny, nx, data.shape[1])
    time_elem = image.find("FieldData/DataArray[@Name='TimeValue']")
    return {
        "time": float(_decode(time_elem, 1)[0, 0]) if time_elem is not None else None,
        "spacing": tuple(float(s) for s in _attr(image, "Spacing").split()),
        "origin": tuple(float(s) for s in _attr(image, "Origin").split()),
        "shape": (ny, nx),
        "fields": fields,
        "provenance": from_xml(text),
    }


def read_pvd(path) -> list[tuple[float, Path]]:
    """(time, absolute path) of each dataset of a .pvd file."""
    path = Path(path)
    root = ET.parse(path).getroot()
    return [(float(_attr(d, "timestep")), path.parent / _attr(d, "file")) for d in _find(root, "Collection")]
