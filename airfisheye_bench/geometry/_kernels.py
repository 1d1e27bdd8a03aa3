"""Fused CPU kernels (numba) for the geometry hot paths.

Eager torch needs several full passes (gather, convert, multiply-add, round, scatter) per remap; one fused loop over
the output pixels is several times faster on CPU and allocates nothing. Kernels are compiled on first use and
cached on disk (``cache=True``).

Two source layouts are served: *interleaved* ``[B, L, C]`` (channels last, as images come out of a decoder: one
cache line holds every channel of a texel) and *planar* ``[B, C, L]``. ``L = 5 * S * S`` is the stacked faces.
The tables are pixel-major (``[P, T]``) so one pixel's taps share cache lines.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def gather_interleaved(src, pixels, index, weight, out, is_int, lo, hi):  # pragma: no cover - compiled
    """``out[b, c, pixels[p]] = sum_t weight[p, t] * src[b, index[p, t], c]``; ``src`` is ``[B, L, C]``.

    ``out`` is ``[B, C, H*W]``, pre-filled by the caller. Integer outputs are rounded half up, clamped to ``[lo, hi]``.
    """
    n_batch, _, n_chan = src.shape
    n_pix, taps = index.shape
    acc = np.zeros(n_chan, dtype=np.float32)
    for b in range(n_batch):
        for p in range(n_pix):
            acc[:] = 0.0
            for t in range(taps):
                i = index[p, t]
                w = weight[p, t]
                for c in range(n_chan):
                    acc[c] += w * np.float32(src[b, i, c])
            q = pixels[p]
            for c in range(n_chan):
                v = acc[c]
                if is_int:
                    v = min(max(np.floor(v + np.float32(0.5)), lo), hi)
                out[b, c, q] = v


@njit(cache=True, nogil=True)
def gather_planar(src, pixels, index, weight, out, is_int, lo, hi):  # pragma: no cover - compiled
    """``out[b, c, pixels[p]] = sum_t weight[p, t] * src[b, c, index[p, t]]``; ``src`` is ``[B, C, L]``."""
    n_batch, n_chan, _ = src.shape
    n_pix, taps = index.shape
    for b in range(n_batch):
        for p in range(n_pix):
            q = pixels[p]
            for c in range(n_chan):
                v = np.float32(0.0)
                for t in range(taps):
                    v += weight[p, t] * np.float32(src[b, c, index[p, t]])
                if is_int:
                    v = min(max(np.floor(v + np.float32(0.5)), lo), hi)
                out[b, c, q] = v
