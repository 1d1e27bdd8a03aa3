"""Files in PCL's own layouts, written here to test the readers against: an LZF compressor and PCD
``DATA binary_compressed``.

Sources: liblzf's format as PCL vendors it (github:PointCloudLibrary/pcl io/src/lzf.cpp, the comment above
``lzfCompress``: ``000LLLLL`` literal of L+1 bytes, ``LLLooooo oooooooo`` back-reference of L+2 bytes at offset
o+1, ``111ooooo LLLLLLLL oooooooo`` one of L+9 bytes) and ``pcl::PCDWriter::writeBinaryCompressed``
(io/src/pcd_io.cpp): uint32 compressed size, uint32 uncompressed size, then the LZF data of the fields laid out
one after the other (all x, then all y, ...), ``_`` padding fields left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def lzf_compress(data: bytes) -> bytes:
    """A greedy LZF compressor: the longest match of the last position with the same 3 bytes, within liblzf's
    limits (offset <= 8192, length <= 264); literal runs of at most 32 bytes."""
    out = bytearray()
    literal = bytearray()
    last: dict[bytes, int] = {}
    i, n = 0, len(data)

    def flush() -> None:
        while literal:
            chunk = literal[:32]
            out.append(len(chunk) - 1)
            out.extend(chunk)
            del literal[:32]

    while i < n:
        key = data[i : i + 3]
        j = last.get(key) if len(key) == 3 else None
        if len(key) == 3:
            last[key] = i
        if j is None or i - j > 8192:
            literal.append(data[i])
            i += 1
            continue
        length, limit = 3, min(264, n - i)
        while (
            length < limit and data[j + length] == data[i + length]
        ):  # may overlap i: LZF copies byte by byte
            length += 1
        flush()
        off, code = i - j - 1, length - 2
        if code < 7:
            out.append((code << 5) | (off >> 8))
        else:
            out.extend((0xE0 | (off >> 8), code - 7))
        out.append(off & 0xFF)
        i += length
    flush()
    return bytes(out)


def write_pcd_binary_compressed(
    path: str | Path,
    fields: list[tuple[str, str, np.ndarray]],
    height: int = 1,
    viewpoint: str = "0 0 0 1 0 0 0",
) -> None:
    """A PCD v0.7 file with ``DATA binary_compressed`` as PCL writes it.

    ``fields``: ``(name, numpy dtype such as '<f4', values [N] or [N, COUNT])``; ``_`` fields are padding,
    declared in the header but not stored (as PCL does).
    """
    n = len(fields[0][2])
    types = {"f": "F", "i": "I", "u": "U"}
    names, sizes, kinds, counts, planes = [], [], [], [], []
    for name, dtype, values in fields:
        arr = np.asarray(values).astype(dtype).reshape(n, -1)
        names.append(name)
        sizes.append(str(arr.dtype.itemsize))
        kinds.append(types[arr.dtype.kind])
        counts.append(str(arr.shape[1]))
        if name != "_":
            planes.append(np.ascontiguousarray(arr).tobytes())
    raw = b"".join(planes)
    packed = lzf_compress(raw)
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
        f"FIELDS {' '.join(names)}\nSIZE {' '.join(sizes)}\nTYPE {' '.join(kinds)}\nCOUNT {' '.join(counts)}\n"
        f"WIDTH {n // height}\nHEIGHT {height}\nVIEWPOINT {viewpoint}\nPOINTS {n}\nDATA binary_compressed\n"
    )
    sizes_le = np.array([len(packed), len(raw)], dtype="<u4").tobytes()
    Path(path).write_bytes(header.encode("ascii") + sizes_le + packed)
