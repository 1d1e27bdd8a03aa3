"""LZF decompression (liblzf's format, which PCL uses for PCD ``DATA binary_compressed``), in numpy.

The stream is a sequence of tokens, each starting with a control byte ``c``:

* ``c < 32``: a literal run, the next ``c + 1`` bytes are copied as they are;
* otherwise a back-reference: copy ``length`` bytes from ``offset`` bytes before the output's end, where
  ``length = (c >> 5) + 2`` (``c >> 5 == 7``: ``next byte + 9``) and ``offset = ((c & 0x1f) << 8) + next byte + 1``.
  A reference may overlap the bytes it produces (offset < length repeats a pattern).

Only the token boundaries need a sequential walk (one cheap Python step per token); the copies are resolved at
once: every output byte points either at an input byte (literal) or at an earlier output byte (reference), and
pointer doubling follows the chains in ``log2(depth)`` vectorised rounds.

Example:
    >>> lzf_decompress(bytes([2]) + b"abc" + bytes([0b0100_0000, 2]), 7)  # "abc", then 4 bytes from 3 back
    b'abcabca'
"""

from __future__ import annotations

import numpy as np


def lzf_decompress(data: bytes, size: int) -> bytes:
    """Decompress an LZF stream into exactly ``size`` bytes.

    Raises:
        ValueError: The stream is truncated, references data before its start, or does not decode to ``size``.
    """
    n = len(data)
    starts: list[int] = []
    append = starts.append
    i = 0
    while i < n:  # the only sequential part: where each token starts
        append(i)
        c = data[i]
        i += c + 2 if c < 32 else (3 if c >= 224 else 2)
    if i != n:
        raise ValueError(f"LZF stream truncated: its last token needs {i - n} more byte(s)")
    src = np.frombuffer(data, dtype=np.uint8)
    pos = np.asarray(starts, dtype=np.int64)
    ctrl = src[pos].astype(np.int64)
    literal = ctrl < 32
    long_ref = ctrl >= 224
    # A reference's first operand byte: its length byte (long) or its offset's low byte (short).
    b1 = src[np.minimum(pos + 1, n - 1)].astype(np.int64)
    b2 = src[np.minimum(pos + 2, n - 1)].astype(np.int64)
    lengths = np.where(literal, ctrl + 1, np.where(long_ref, b1 + 9, (ctrl >> 5) + 2))
    offsets = ((ctrl & 0x1F) << 8) + np.where(long_ref, b2, b1) + 1
    total = int(lengths.sum())
    if total != size:
        raise ValueError(f"LZF stream decodes to {total} bytes, expected {size}")
    out_start = np.cumsum(lengths) - lengths
    token = np.repeat(np.arange(len(pos)), lengths)
    k = np.arange(total, dtype=np.int64) - out_start[token]  # index of each output byte inside its token
    is_lit = literal[token]
    # ptr[j]: j itself for a literal byte, the output byte it copies for a reference byte.
    ptr = np.arange(total, dtype=np.int64)
    ref = ~is_lit
    ptr[ref] -= offsets[token[ref]]
    if ref.any() and ptr[ref].min() < 0:
        raise ValueError("LZF back-reference before the start of the output")
    values = np.zeros(total, dtype=np.uint8)
    values[is_lit] = src[pos[token[is_lit]] + 1 + k[is_lit]]
    todo = np.flatnonzero(ref)  # reference bytes whose pointer is not yet a literal
    while todo.size:
        ptr[todo] = ptr[ptr[todo]]
        todo = todo[~is_lit[ptr[todo]]]
    return values[ptr].tobytes()


__all__ = ["lzf_decompress"]
