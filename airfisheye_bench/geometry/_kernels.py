"""Fused CPU kernels (numba) for the geometry hot paths.

Eager torch needs several full passes (gather, convert, multiply-add, round, scatter) per remap; one fused loop over
the output pixels is several times faster on CPU and allocates nothing. Kernels are compiled on first use and
cached on disk (``cache=True``).

Sources are the stacked faces, ``L = 5 * S * S`` texels, either *planar* ``[B, C, L]`` or *interleaved*
``[B, L, 3]`` (channels last, as images come out of a decoder: one cache line holds a texel's three channels).
Tables are pixel-major (``[P, T]``) so one pixel's taps share cache lines.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def copy_nearest(src, pixels, index, out):  # pragma: no cover - compiled
    """``out[b, c, pixels[p]] = src[b, c, index[p]]``: an exact copy, any dtype. ``src`` is planar ``[B, C, L]``."""
    n_batch, n_chan, _ = src.shape
    for b in range(n_batch):
        for c in range(n_chan):
            for p in range(index.shape[0]):
                out[b, c, pixels[p]] = src[b, c, index[p]]


@njit(cache=True, nogil=True)
def blend_planar(src, pixels, index, weight, out, is_int, lo, hi):  # pragma: no cover - compiled
    """``out[b, c, pixels[p]] = sum_t weight[p, t] * src[b, c, index[p, t]]`` (float32 maths).

    ``out`` is ``[B, C, H*W]``, pre-filled by the caller. Integer outputs are rounded half up, clamped to ``[lo, hi]``.
    """
    n_batch, n_chan, _ = src.shape
    n_pix, taps = index.shape
    for b in range(n_batch):
        for c in range(n_chan):
            for p in range(n_pix):
                v = np.float32(0.0)
                for t in range(taps):
                    v += weight[p, t] * np.float32(src[b, c, index[p, t]])
                if is_int:
                    v = min(max(np.floor(v + np.float32(0.5)), lo), hi)
                out[b, c, pixels[p]] = v


# fastmath lets LLVM reorder the four-tap sums (a last-bit difference at most, then rounded to the output dtype).
@njit(cache=True, nogil=True, fastmath=True)
def blend_interleaved3(src, pixels, index, weight, out, is_int, lo, hi):  # pragma: no cover - compiled
    """:func:`blend_planar` for an interleaved three-channel source ``[B, L, 3]`` (RGB), with scalar accumulators."""
    n_batch = src.shape[0]
    n_pix, taps = index.shape
    half = np.float32(0.5) if is_int else np.float32(0.0)
    for b in range(n_batch):
        for p in range(n_pix):
            r = half
            g = half
            bl = half
            for t in range(taps):
                i = index[p, t]
                w = weight[p, t]
                r += w * np.float32(src[b, i, 0])
                g += w * np.float32(src[b, i, 1])
                bl += w * np.float32(src[b, i, 2])
            q = pixels[p]
            if is_int:
                r = min(max(np.floor(r), lo), hi)
                g = min(max(np.floor(g), lo), hi)
                bl = min(max(np.floor(bl), lo), hi)
            out[b, 0, q] = r
            out[b, 1, q] = g
            out[b, 2, q] = bl
