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
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros  # LLVM ctlz / cttz


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


# -------------------------------------------------------------------------- LiDAR: organisation and ordering
@njit(cache=True, nogil=True)
def lidar_cells(
    r, az, el, lower, az0, v_res, h_res, n_c, n_pc, wraps, cell, index
):  # pragma: no cover - compiled
    """Step 1 of III-C: the cell of every point and ``I_LiDAR``, exactly as ``lidar.cells_from_angles``.

    The same float64 operations in the same order (no fastmath), so the cells and collision winners are
    bit-identical to numpy's. One pass replaces two ``np.minimum.at`` reductions: visiting the points in index
    order with a strict ``<`` leaves the lowest index among the points nearest to a cell centre.

    Args:
        r, az, el: ``[N]`` range, azimuth and elevation of the points (``lidar.spherical_coordinates``).
        lower, az0: Elevation of channel 0 and azimuth of column 0 (radians).
        v_res, h_res: Vertical and horizontal resolution (radians).
        n_c, n_pc: Channels and points per channel.
        wraps: The azimuth wraps around (360 deg sensor): column ``N_PC`` is column 0.
        cell: ``int64 [N]`` output, ``row * N_PC + col`` or -1 outside the FOV.
        index: ``int64 [N_C * N_PC]`` output, the point in each cell or -1.
    """
    best = np.full(n_c * n_pc, np.inf)
    index[:] = -1
    for p in range(r.shape[0]):
        cell[p] = -1
        fi = (el[p] - lower) / v_res
        fj = (az[p] - az0) / h_res
        i = np.rint(fi)
        j = np.rint(fj)
        dj = fj - j  # offset from the column centre, taken before the wrap (as numpy does)
        if wraps:
            j = float(int(j) % n_pc)
        if not (r[p] > 0 and i >= 0 and i < n_c and j >= 0 and j < n_pc):
            continue
        c = int(i) * n_pc + int(j)
        cell[p] = c
        score = (fi - i) * (fi - i) + dj * dj
        if score < best[c]:
            best[c] = score
            index[c] = p


_ALL = np.uint64(0xFFFFFFFFFFFFFFFF)


# Kept cells of a line are bits of uint64 words: finding the nearest one is a count-leading/trailing-zeros
# on a word plus a scan over the (at most N / 64) words in between. A cell-by-cell scan took ~280 steps per
# lookup on a 64 x 2048 scan (lines are sparse while the nearest points are being visited). All bit
# arithmetic stays in uint64: numba would promote a uint64/int64 mix to float64. The helpers are left to LLVM
# to inline: numba's own ``inline="always"`` made the loop 3-5x slower.
@njit(cache=True, nogil=True)
def _last_set(words, w0, lo, hi):  # pragma: no cover - compiled
    """Largest ``c`` in ``[lo, hi)`` whose bit is set in the bitset starting at ``words[w0]``, or -1."""
    if hi <= lo:
        return -1
    w = (hi - 1) >> 6
    m = words[w0 + w] & (_ALL >> np.uint64(63 - ((hi - 1) & 63)))
    while m == 0:
        w -= 1
        if w < lo >> 6:
            return -1
        m = words[w0 + w]
    c = (w << 6) + 63 - int(leading_zeros(m))
    return c if c >= lo else -1


@njit(cache=True, nogil=True)
def _first_set(words, w0, lo, hi):  # pragma: no cover - compiled
    """Smallest ``c`` in ``[lo, hi)`` whose bit is set in the bitset starting at ``words[w0]``, or -1."""
    if hi <= lo:
        return -1
    w = lo >> 6
    m = words[w0 + w] & (_ALL << np.uint64(lo & 63))
    while m == 0:
        w += 1
        if w > (hi - 1) >> 6:
            return -1
        m = words[w0 + w]
    c = (w << 6) + int(trailing_zeros(m))
    return c if c < hi else -1


@njit(cache=True, nogil=True)
def _set(words, w0, c):  # pragma: no cover - compiled
    words[w0 + (c >> 6)] |= np.uint64(1) << np.uint64(c & 63)


@njit(cache=True, nogil=True)
def ordering_keep(row, col, theta, phi, n_c, n_pc, az_win, el_win, tol, keep):  # pragma: no cover - compiled
    """Step 4 of III-C: the sequential loop of ``occlusion._ordering_loop``, with the same result.

    Points come in visiting order (ascending camera range), one per cell. A point is kept iff its ``theta`` is
    strictly greater than every kept ``theta`` left of it in its row and smaller than every one right of it
    (within ``az_win`` columns), and its ``phi`` likewise in its column against the rows below / above
    (within ``el_win`` rows, with ``tol``).

    Why a nearest-neighbour lookup is exact: two kept cells of a line within one window of each other were
    compared when the later one was kept, so kept values are strictly increasing along a line within any
    window (also for ``tol < 0``, which only demands more clearance). The extreme kept value left / below a
    point within its window is then the nearest kept one. For ``tol > 0`` a column need not be increasing, so
    every kept entry of the window is tested (columns are short: ``N_C`` cells).

    Args:
        row, col: ``int64 [M]`` cell of each point (channel, column), all different.
        theta, phi: ``float64 [M]`` azimuth / elevation seen from the camera centre (LiDAR axes).
        n_c, n_pc: Shape of ``I_LiDAR``.
        az_win, el_win: Window half-widths in columns / rows (``n_pc`` / ``n_c`` for the whole line).
        tol: Elevation tolerance in radians (see ``occlusion``).
        keep: ``bool [M]`` output.
    """
    row_words = (n_pc + 63) >> 6  # words per row bitset
    col_words = (n_c + 63) >> 6
    row_bits = np.zeros(n_c * row_words, np.uint64)
    col_bits = np.zeros(n_pc * col_words, np.uint64)
    theta_final = np.empty(n_c * n_pc)  # row-major; read only where a bit is set
    phi_final = np.empty(n_pc * n_c)  # column-major: a column is contiguous
    for k in range(row.shape[0]):
        keep[k] = False
        i = row[k]
        j = col[k]
        th = theta[k]
        ph = phi[k]
        # (1) row i: the nearest kept entry left of j must be smaller, the nearest right of j greater.
        rb, rw = i * n_pc, i * row_words
        c = _last_set(row_bits, rw, max(0, j - az_win), j)
        if c >= 0 and theta_final[rb + c] >= th:
            continue
        c = _first_set(row_bits, rw, j + 1, min(n_pc, j + az_win + 1))
        if c >= 0 and theta_final[rb + c] <= th:
            continue
        # (2) column j: entries below row i must be below phi + tol, entries above must be above phi - tol.
        cb, cw = j * n_c, j * col_words
        lo, hi = max(0, i - el_win), min(n_c, i + el_win + 1)
        if tol > 0.0:  # every kept entry of the window (row i is not among them: one point per cell)
            c = _first_set(col_bits, cw, lo, hi)
            while c >= 0:
                v = phi_final[cb + c]
                if (c < i and v >= ph + tol) or (c > i and v <= ph - tol):
                    break
                c = _first_set(col_bits, cw, c + 1, hi)
            if c >= 0:
                continue
        else:
            c = _last_set(col_bits, cw, lo, i)
            if c >= 0 and phi_final[cb + c] >= ph + tol:
                continue
            c = _first_set(col_bits, cw, i + 1, hi)
            if c >= 0 and phi_final[cb + c] <= ph - tol:
                continue
        keep[k] = True
        _set(row_bits, rw, j)
        theta_final[rb + j] = th
        _set(col_bits, cw, i)
        phi_final[cb + i] = ph


@njit(cache=True, nogil=True)
def scatter_min(values, target, out):  # pragma: no cover - compiled
    """``out[t[k]] = min(out[t[k]], values[k])`` for ``t = target``: ``np.minimum.at`` in one pass (exact)."""
    for k in range(target.shape[0]):
        t = target[k]
        if values[k] < out[t]:
            out[t] = values[k]
