"""LiDAR scan files in the formats real sensors and datasets write: :func:`load_scan` reads any of them.

==================  =================================================  =========================================
format              contents                                           rings
==================  =================================================  =========================================
KITTI ``.bin``      float32 ``[N, 4]``: x y z reflectance; LiDAR       none in the file; the order is the firing
                    frame (x forward, y left, z up)                    order (``firing_order=True``)
nuScenes            float32 ``[N, 5]``: x y z intensity ring; frame    the ``ring`` column
``.pcd.bin``        x right, y forward, z up: turned here by +90 deg
                    about z into x forward, y left
PCD (``.pcd``)      v0.7 header (``FIELDS SIZE TYPE COUNT WIDTH        a ``ring`` field where the driver wrote
                    HEIGHT VIEWPOINT POINTS DATA``), ``ascii``,        one (ROS Velodyne / Ouster drivers)
                    ``binary`` or ``binary_compressed`` (PCL's
                    default: LZF, field by field); VIEWPOINT (the
                    sensor's pose) is undone; HEIGHT > 1 is an
                    organised cloud
PLY (``.ply``)      ``ascii`` or ``binary_little_endian``, element     a ``ring`` property where present
                    ``vertex`` of scalar properties
``.npy``            ``[N, 3|4|5]`` x y z [intensity [ring]], or an     the 5th column
                    organised ``[H, W, 3|4|5]``
``.npz``            arrays ``points`` ``[N, 3]`` (or ``xyz``), and     ``ring`` / ``rings``
                    optional ``intensity``, ``ring`` / ``rings``
==================  =================================================  =========================================

Field names are matched without case; ``i``, ``reflectance`` and ``reflectivity`` read as intensity, ``laser_id``
and ``channel`` as ring; every other field (time stamps, colour, normals, curvature, ``_`` padding...) is skipped
(its bytes per its SIZE / TYPE / COUNT or PLY type). No x, y or z, a size that does not fit the fields, a
non-finite coordinate (outside an organised cloud, whose empty cells are NaN or zero by convention: those are
dropped and counted in ``no_returns``) is one :class:`~airfisheye_bench.io.errors.DatasetFormatError` naming the
file.

Example:
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "000000.bin"
    >>> np.array([[10.0, 0.0, -1.7, 0.3], [0.0, 5.0, -1.7, 0.9]], dtype=np.float32).tofile(path)
    >>> scan = load_scan(path)
    >>> scan.points.shape, scan.rings, scan.firing_order, scan.format
    ((2, 3), None, True, 'kitti_bin')
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.lzf import lzf_decompress

SCAN_SUFFIXES = (".pcd.bin", ".bin", ".pcd", ".ply", ".npy", ".npz")

_INTENSITY = ("intensity", "i", "reflectance", "reflectivity", "remission")
_RING = ("ring", "rings", "laser_id", "channel")


@dataclass
class Scan:
    """One LiDAR scan as read from a file (:func:`load_scan`).

    Attributes:
        points: ``float64 [N, 3]`` x y z in the LiDAR frame (x forward, y left, z up), metres.
        intensity: ``float32 [N]`` intensity / reflectance as the file stores it, or ``None``.
        rings: ``int64 [N]`` the ring the sensor reported (0 = the lowest beam), or ``None``.
        firing_order: Whether the points are stored in firing order, each laser's revolution contiguous (KITTI
            ``.bin``): the rings can then be recovered from the order (``geometry.rings``).
        no_returns: Empty cells of an organised cloud (NaN or all-zero) that were dropped.
        path: The file.
        format: ``kitti_bin``, ``nuscenes_bin``, ``pcd``, ``ply``, ``npy`` or ``npz``.
    """

    points: np.ndarray
    intensity: np.ndarray | None
    rings: np.ndarray | None
    firing_order: bool
    no_returns: int
    path: Path
    format: str
    extra: dict[str, np.ndarray] = field(default_factory=dict)


def scan_format(path: str | Path) -> str | None:
    """The format :func:`load_scan` reads ``path`` as, from its name; ``None`` if it is not a scan file."""
    name = Path(path).name.lower()
    for suffix, fmt in (
        (".pcd.bin", "nuscenes_bin"),
        (".bin", "kitti_bin"),
        (".pcd", "pcd"),
        (".ply", "ply"),
        (".npy", "npy"),
        (".npz", "npz"),
    ):
        if name.endswith(suffix):
            return fmt
    return None


def load_scan(path: str | Path) -> Scan:
    """Read a LiDAR scan file (format by its name; see the module docstring).

    Raises:
        DatasetFormatError: The file is missing, not a scan format, or malformed (naming the file and why).
    """
    path = Path(path)
    fmt = scan_format(path)
    if fmt is None:
        raise DatasetFormatError(path, f"not a LiDAR scan file: expected one of {', '.join(SCAN_SUFFIXES)}")
    if not path.is_file():
        raise DatasetFormatError(path, "no such LiDAR scan file")
    try:
        reader = _READERS[fmt]
        points, intensity, rings, no_returns = reader(path)
    except DatasetFormatError:
        raise
    except (OSError, ValueError, KeyError, IndexError, UnicodeDecodeError) as err:
        raise DatasetFormatError(path, f"cannot read it as {fmt} ({type(err).__name__}: {err})") from None
    points = np.asarray(points, dtype=np.float64)
    if not np.isfinite(points).all():
        bad = int((~np.isfinite(points).all(axis=1)).sum())
        raise DatasetFormatError(path, f"{bad} point(s) with NaN or infinite coordinates")
    if intensity is not None:
        intensity = np.asarray(intensity, dtype=np.float32)
    if rings is not None:
        rings = np.asarray(rings)
        if rings.size and not np.array_equal(rings, np.round(rings)):
            raise DatasetFormatError(path, "the ring field holds non-integer values")
        rings = rings.astype(np.int64)
        if rings.size and rings.min() < 0:
            raise DatasetFormatError(path, f"the ring field holds negative values ({int(rings.min())})")
    return Scan(points, intensity, rings, fmt == "kitti_bin", no_returns, path, fmt)


# ------------------------------------------------------------------------------------------ the readers
def _read_float_records(path: Path, width: int, what: str) -> np.ndarray:
    size = path.stat().st_size
    if size % (4 * width):
        raise DatasetFormatError(
            path,
            f"{size} bytes is not a whole number of {what} records (float32 x {width} = {4 * width} bytes each)",
        )
    return np.fromfile(path, dtype="<f4").reshape(-1, width)


def _read_kitti(path: Path):
    data = _read_float_records(path, 4, "KITTI (x, y, z, reflectance)")
    return data[:, :3], data[:, 3], None, 0


def _read_nuscenes(path: Path):
    data = _read_float_records(path, 5, "nuScenes (x, y, z, intensity, ring)")
    # nuScenes LIDAR_TOP: x right, y forward, z up. Ours: x forward, y left, z up: (x, y) -> (y, -x).
    points = np.stack([data[:, 1], -data[:, 0], data[:, 2]], axis=1)
    return points, data[:, 3], data[:, 4], 0


def _columns(path: Path, names: list[str], columns: list[np.ndarray | None]):
    """x y z, intensity, ring from named columns; other fields (colour, normals, curvature...) are ignored."""
    lookup: dict[str, np.ndarray] = {}
    for name, col in zip(names, columns, strict=True):
        key = _field_kind(name)
        if key is not None and col is not None:
            lookup.setdefault(key, col)
    missing = [k for k in ("x", "y", "z") if k not in lookup]
    if missing:
        raise DatasetFormatError(path, f"no field {', '.join(missing)}: a scan needs x, y and z")
    points = np.stack([np.asarray(lookup[k], dtype=np.float64) for k in "xyz"], axis=1)
    return points, lookup.get("intensity"), lookup.get("ring")


def _field_kind(name: str) -> str | None:
    """``x`` / ``y`` / ``z`` / ``intensity`` / ``ring`` for a field the reader uses, ``None`` for any other."""
    key = name.lower()
    if key in ("x", "y", "z"):
        return key
    if key in _INTENSITY:
        return "intensity"
    return "ring" if key in _RING else None


def _drop_no_returns(points, intensity, rings, organised: bool):
    """In an organised cloud empty cells (NaN / all zero) are no-returns: dropped and counted."""
    if not organised:
        return points, intensity, rings, 0
    empty = ~np.isfinite(points).all(axis=1) | ~points.any(axis=1)
    keep = ~empty
    pick = (lambda a: None if a is None else np.asarray(a)[keep]) if empty.any() else (lambda a: a)
    return points[keep], pick(intensity), pick(rings), int(empty.sum())


_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4", ("I", 8): "i8"}
_PCD_TYPES.update({("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("U", 8): "u8"})
_PCD_KEYS = ("VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA")


def _read_pcd(path: Path):
    raw = path.read_bytes()
    header: dict[str, list[str]] = {}
    offset = 0
    while "DATA" not in header:
        end = raw.find(b"\n", offset)
        if end < 0:
            raise DatasetFormatError(path, "PCD header ends before its DATA line")
        line = raw[offset:end].decode("ascii").strip()
        offset = end + 1
        if not line or line.startswith("#"):
            continue
        key, *values = line.split()
        if key.upper() not in _PCD_KEYS:
            raise DatasetFormatError(
                path, f"unknown PCD header line {key!r}; expected {', '.join(_PCD_KEYS)}"
            )
        header[key.upper()] = values
    for key in ("FIELDS", "SIZE", "TYPE", "WIDTH", "HEIGHT", "POINTS"):
        if key not in header:
            raise DatasetFormatError(path, f"PCD header has no {key} line")
    names = header["FIELDS"]
    counts = [int(c) for c in header.get("COUNT", ["1"] * len(names))]
    sizes, types = [int(s) for s in header["SIZE"]], [t.upper() for t in header["TYPE"]]
    if not len(names) == len(sizes) == len(types) == len(counts):
        raise DatasetFormatError(path, "PCD FIELDS, SIZE, TYPE and COUNT must have one entry per field")
    width, height, n = int(header["WIDTH"][0]), int(header["HEIGHT"][0]), int(header["POINTS"][0])
    if width * height != n:
        raise DatasetFormatError(path, f"PCD WIDTH x HEIGHT = {width * height} but POINTS = {n}")
    dtype = []
    for name, size, typ, count in zip(names, sizes, types, counts, strict=True):
        if (typ, size) not in _PCD_TYPES:
            raise DatasetFormatError(path, f"PCD field {name!r}: unsupported TYPE {typ} with SIZE {size}")
        dtype.append((f"{name}#{len(dtype)}", "<" + _PCD_TYPES[(typ, size)], (count,) if count > 1 else ()))
    dtype = np.dtype(dtype)
    mode = header["DATA"][0].lower()
    if mode == "ascii":
        text = raw[offset:].decode("ascii").split()
        values = np.array(text, dtype=np.float64)
        per_point = sum(counts)
        if values.size != n * per_point:
            raise DatasetFormatError(path, f"{values.size} ASCII values for {n} points x {per_point} values")
        values = values.reshape(n, per_point)
        starts = np.cumsum([0, *counts])
        columns = [values[:, starts[k]] for k in range(len(names))]
    elif mode == "binary":
        body = raw[offset:]
        if len(body) != n * dtype.itemsize:
            raise DatasetFormatError(
                path,
                f"{len(body)} bytes of binary data for {n} points x {dtype.itemsize} bytes ({' '.join(names)})",
            )
        data = np.frombuffer(body, dtype=dtype, count=n)
        columns = [np.asarray(data[f]).reshape(n, -1)[:, 0] for f in dtype.names]
    elif mode == "binary_compressed":
        columns = _pcd_compressed_columns(path, raw[offset:], dtype, n)
    else:
        raise DatasetFormatError(
            path, f"PCD DATA {mode!r} is not supported; expected ascii, binary or binary_compressed"
        )
    points, intensity, rings = _columns(path, names, columns)
    points, intensity, rings, dropped = _drop_no_returns(points, intensity, rings, height > 1)
    viewpoint = [float(v) for v in header.get("VIEWPOINT", [0, 0, 0, 1, 0, 0, 0])]
    if len(viewpoint) != 7:
        raise DatasetFormatError(path, "PCD VIEWPOINT must be tx ty tz qw qx qy qz")
    if viewpoint != [0, 0, 0, 1, 0, 0, 0]:  # the sensor's pose in the cloud's frame: back to the sensor frame
        t, (w, x, y, z) = np.array(viewpoint[:3]), viewpoint[3:]
        R = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        points = (points - t) @ R
    return points, intensity, rings, dropped


def _pcd_compressed_columns(path: Path, body: bytes, dtype: np.dtype, n: int) -> list[np.ndarray | None]:
    """The first value of every field of a PCD ``DATA binary_compressed`` body (``None`` for ``_`` padding).

    PCL's layout (``pcl::PCDWriter::writeBinaryCompressed`` / ``PCDReader::readBodyBinary`` in io/src/pcd_io.cpp):
    uint32 compressed size, uint32 uncompressed size, then LZF data that holds the fields one after the other
    (all points' x, then all y, ...: compresses better than point by point); ``_`` padding fields are not stored.
    """
    if len(body) < 8:
        raise DatasetFormatError(path, "PCD binary_compressed data ends before its two uint32 sizes")
    packed, unpacked = (int(v) for v in np.frombuffer(body[:8], dtype="<u4"))
    stored = [(name, dtype.fields[name][0]) for name in dtype.names if name.split("#")[0] != "_"]
    expected = n * sum(t.itemsize for _, t in stored)
    if unpacked != expected or len(body) < 8 + packed:
        raise DatasetFormatError(
            path,
            f"PCD binary_compressed sizes {packed} / {unpacked} bytes (packed / unpacked) do not fit {len(body) - 8} "
            f"bytes of data and {expected} bytes for {n} points",
        )
    try:
        buf = lzf_decompress(body[8 : 8 + packed], unpacked)
    except ValueError as err:
        raise DatasetFormatError(path, f"PCD binary_compressed data is corrupt ({err})") from None
    planes: dict[str, np.ndarray] = {}
    start = 0
    for name, typ in stored:  # typ: the field's scalar type, with a (COUNT,) shape where COUNT > 1
        count = typ.itemsize // typ.base.itemsize
        plane = np.frombuffer(buf, dtype=typ.base, count=n * count, offset=start)
        planes[name] = plane.reshape(n, count)[:, 0]
        start += n * typ.itemsize
    return [planes.get(name) for name in dtype.names]


_PLY_TYPES = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "uint": "u4"}
_PLY_TYPES.update({"float": "f4", "double": "f8", "int8": "i1", "uint8": "u1", "int16": "i2", "uint16": "u2"})
_PLY_TYPES.update({"int32": "i4", "uint32": "u4", "float32": "f4", "float64": "f8"})


def _read_ply(path: Path):
    raw = path.read_bytes()
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise DatasetFormatError(path, "not a PLY file (no 'ply' magic or no end_header)")
    lines = raw[:end].decode("ascii").splitlines()[1:]
    body = raw[raw.index(b"\n", end) + 1 :]
    fmt, elements = None, []
    for line in lines:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property":
            if words[1] == "list":
                raise DatasetFormatError(
                    path, f"PLY list property {words[-1]!r}: a scan has scalar properties only"
                )
            if words[1] not in _PLY_TYPES:
                raise DatasetFormatError(path, f"PLY property {words[2]!r}: unknown type {words[1]!r}")
            elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
    if fmt not in ("ascii", "binary_little_endian"):
        raise DatasetFormatError(
            path, f"PLY format {fmt!r} is not supported; expected ascii or binary_little_endian"
        )
    if not elements or elements[0][0] != "vertex" or any(count for _, count, _ in elements[1:]):
        raise DatasetFormatError(path, "a PLY scan holds one element, vertex (others must be empty)")
    _, n, props = elements[0]
    names = [p for p, _ in props]
    if fmt == "ascii":
        values = np.array(body.decode("ascii").split(), dtype=np.float64)
        if values.size != n * len(props):
            raise DatasetFormatError(
                path, f"{values.size} ASCII values for {n} vertices x {len(props)} properties"
            )
        columns = list(values.reshape(n, len(props)).T)
    else:
        dtype = np.dtype([(f"{p}#{k}", "<" + t) for k, (p, t) in enumerate(props)])
        if len(body) != n * dtype.itemsize:
            raise DatasetFormatError(
                path, f"{len(body)} bytes of binary data for {n} vertices x {dtype.itemsize} bytes"
            )
        data = np.frombuffer(body, dtype=dtype, count=n)
        columns = [data[f] for f in dtype.names]
    points, intensity, rings = _columns(path, names, columns)
    return points, intensity, rings, 0


def _read_npy(path: Path):
    data = np.load(path, allow_pickle=False)
    organised = data.ndim == 3
    if organised:
        data = data.reshape(-1, data.shape[-1])
    if data.ndim != 2 or data.shape[1] not in (3, 4, 5) or not np.issubdtype(data.dtype, np.number):
        raise DatasetFormatError(
            path,
            f"a .npy scan is numeric [N, 3|4|5] (x y z [intensity [ring]]) or [H, W, 3|4|5], got {data.shape}",
        )
    names = ["x", "y", "z", "intensity", "ring"][: data.shape[1]]
    points, intensity, rings = _columns(path, names, list(data.T))
    return _drop_no_returns(points, intensity, rings, organised)


def _read_npz(path: Path):
    with np.load(path, allow_pickle=False) as archive:
        arrays = {k: archive[k] for k in archive.files}
    xyz = arrays.pop("points", arrays.pop("xyz", None))
    if xyz is None or xyz.ndim != 2 or xyz.shape[1] != 3:
        raise DatasetFormatError(path, "a .npz scan has an array 'points' (or 'xyz') of shape [N, 3]")
    names, columns = ["x", "y", "z"], list(xyz.T)
    for key, value in arrays.items():
        if _field_kind(key) is None:  # colour, normals...: not read, whatever their shape
            continue
        if value.shape != (len(xyz),):
            raise DatasetFormatError(
                path, f"array {key!r} has shape {value.shape}; expected one value per point"
            )
        names.append(key)
        columns.append(value)
    points, intensity, rings = _columns(path, names, columns)
    return points, intensity, rings, 0


_READERS = {
    "kitti_bin": _read_kitti,
    "nuscenes_bin": _read_nuscenes,
    "pcd": _read_pcd,
    "ply": _read_ply,
    "npy": _read_npy,
    "npz": _read_npz,
}

# ------------------------------------------------------------------------------------------ writers (tests, tools)


def write_pcd(
    path: str | Path,
    points: np.ndarray,
    intensity: np.ndarray | None = None,
    rings: np.ndarray | None = None,
    binary: bool = True,
    height: int = 1,
) -> None:
    """Write a PCD v0.7 file (``x y z [intensity] [ring]``, float32 / uint16 ring) as a sensor driver would.

    ``height > 1`` writes an organised cloud (``points`` then holds ``height * width`` cells, NaN for none).
    """
    n = len(points)
    cols = [("x", "F", 4), ("y", "F", 4), ("z", "F", 4)]
    data = [np.asarray(points, dtype=np.float32)[:, k] for k in range(3)]
    if intensity is not None:
        cols.append(("intensity", "F", 4))
        data.append(np.asarray(intensity, dtype=np.float32))
    if rings is not None:
        cols.append(("ring", "U", 2))
        data.append(np.asarray(rings, dtype=np.uint16))
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
        f"FIELDS {' '.join(c[0] for c in cols)}\nSIZE {' '.join(str(c[2]) for c in cols)}\n"
        f"TYPE {' '.join(c[1] for c in cols)}\nCOUNT {' '.join('1' for _ in cols)}\n"
        f"WIDTH {n // height}\nHEIGHT {height}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n"
        f"DATA {'binary' if binary else 'ascii'}\n"
    )
    if binary:
        rec = np.empty(n, dtype=[(c[0], "<u2" if c[1] == "U" else "<f4") for c in cols])
        for (name, *_), col in zip(cols, data, strict=True):
            rec[name] = col
        body = rec.tobytes()
    else:
        rows = zip(*(col.tolist() for col in data), strict=True)
        body = "".join(" ".join(repr(v) for v in row) + "\n" for row in rows).encode()
    Path(path).write_bytes(header.encode("ascii") + body)


def write_ply(
    path: str | Path,
    points: np.ndarray,
    intensity: np.ndarray | None = None,
    rings: np.ndarray | None = None,
    binary: bool = True,
) -> None:
    """Write a PLY file with one ``vertex`` element (``x y z [intensity] [ring]``)."""
    cols = [("x", "float", np.asarray(points)[:, 0]), ("y", "float", np.asarray(points)[:, 1])]
    cols.append(("z", "float", np.asarray(points)[:, 2]))
    if intensity is not None:
        cols.append(("intensity", "float", intensity))
    if rings is not None:
        cols.append(("ring", "ushort", rings))
    fmt = "binary_little_endian" if binary else "ascii"
    header = f"ply\nformat {fmt} 1.0\nelement vertex {len(points)}\n"
    header += "".join(f"property {t} {name}\n" for name, t, _ in cols) + "end_header\n"
    if binary:
        rec = np.empty(len(points), dtype=[(name, "<" + _PLY_TYPES[t]) for name, t, _ in cols])
        for name, _, col in cols:
            rec[name] = col
        body = rec.tobytes()
    else:
        rows = zip(*(np.asarray(c[2]).tolist() for c in cols), strict=True)
        body = "".join(" ".join(repr(v) for v in row) + "\n" for row in rows).encode()
    Path(path).write_bytes(header.encode("ascii") + body)


__all__ = ["SCAN_SUFFIXES", "Scan", "load_scan", "scan_format", "write_pcd", "write_ply"]
