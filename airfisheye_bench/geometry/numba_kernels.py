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
def lidar_layout(
    r,
    az,
    el,
    lower,
    v_res,
    edge,
    h_res,
    n_c,
    wrap_last,
    first_col,
    n_cols,
    ring_given,
    ring,
    position,
    column,
):  # pragma: no cover - compiled
    """Step 1 of III-C: ring, rank in azimuth within the ring and azimuth sector of every point.

    Exactly ``lidar_layout.layout_from_angles``: the same float64 operations (no fastmath), and the same order
    (ring, azimuth, point index) found in O(N) instead of a lexsort: a counting sort into (ring, sector)
    buckets, stable in the point index, then an insertion sort by azimuth inside each bucket (a sector holds
    one or two points of a ring; the sector grows with the azimuth, so the bucket order is the azimuth order).

    Args:
        r, az, el: ``[N]`` range, azimuth and elevation of the points (``lidar.spherical_coordinates``).
        lower, v_res: Elevation of channel 0 and the channel spacing (radians).
        edge, h_res: Azimuth where sector 0 starts and the sector width (radians).
        n_c: Channels.
        wrap_last: Clamp the sector to ``wrap_last`` (a 360 deg sensor: azimuth +pi is the last sector); -1: no.
        first_col, n_cols: Sectors span ``[first_col, first_col + n_cols)`` (``lidar_layout.column_range``).
        ring_given: ``ring`` holds every point's ring already (-1: none; a ring field or an estimate from a
            channel table); otherwise it is the nearest of the evenly spaced channels.
        ring, position, column: ``int64 [N]`` outputs (``ring`` an input too with ``ring_given``).

    Returns:
        The length of the longest ring (0 for no point).
    """
    n = r.shape[0]
    count = np.zeros(n_c * n_cols + 1, np.int64)
    bucket = np.empty(n, np.int64)
    for p in range(n):
        i = float(ring[p]) if ring_given else np.rint((el[p] - lower) / v_res)
        j = np.floor((az[p] - edge) / h_res)
        if wrap_last >= 0 and j > wrap_last:
            j = float(wrap_last)
        column[p] = int(j)
        if r[p] > 0 and i >= 0 and i < n_c:
            ring[p] = int(i)
            bucket[p] = int(i) * n_cols + int(j) - first_col
            count[bucket[p] + 1] += 1
        else:
            ring[p] = -1
            position[p] = -1
            bucket[p] = -1
    for b in range(n_c * n_cols):
        count[b + 1] += count[b]
    start = count.copy()
    order = np.empty(count[-1], np.int64)
    for p in range(n):
        b = bucket[p]
        if b >= 0:
            order[count[b]] = p
            count[b] += 1
    for b in range(n_c * n_cols):  # insertion sort by azimuth; strict > keeps equal azimuths in index order
        for k in range(start[b] + 1, start[b + 1]):
            p = order[k]
            m = k - 1
            while m >= start[b] and az[order[m]] > az[p]:
                order[m + 1] = order[m]
                m -= 1
            order[m + 1] = p
    longest = 0
    for i in range(n_c):
        first = start[i * n_cols]
        for k in range(first, start[(i + 1) * n_cols]):
            position[order[k]] = k - first
        longest = max(longest, start[(i + 1) * n_cols] - first)
    return longest


@njit(cache=True, nogil=True)
def _search_left(sorted_values, x):  # pragma: no cover - compiled
    """``np.searchsorted(sorted_values, x)`` (side left) for one value."""
    lo, hi = 0, sorted_values.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if sorted_values[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, nogil=True)
def nearest_channel(z, rho, tan_mids, table, radial, vertical, ring, residual):  # pragma: no cover - compiled
    """The channel whose beam, from its own origin, points nearest each point (``lidar_layout._nearest_from_origins``).

    The table's nearest channel seen from the mean origin, then three rounds seen from the origin of the channel
    found, then the best of it and its two neighbours by the elevation residual (``residual``, radians; only
    computed where a neighbour also claims the point or the channel is the lowest / highest, 0 elsewhere).
    """
    n_c = table.shape[0]
    r_mean = radial.mean()
    v_mean = vertical.mean()
    for p in range(z.shape[0]):
        c = _search_left(tan_mids, (z[p] - v_mean) / max(rho[p] - r_mean, 1e-6))
        for _ in range(3):
            c = _search_left(tan_mids, (z[p] - vertical[c]) / max(rho[p] - radial[c], 1e-6))
        # the neighbours matter only where they claim the point too (seen from their own origins it lies in
        # their cell): decide by the elevation residual there; the residual is needed at the table's ends
        claims = 0
        for d in range(-1, 2):
            k = c + d
            if 0 <= k < n_c:
                t = (z[p] - vertical[k]) / max(rho[p] - radial[k], 1e-6)
                if (k == 0 or tan_mids[k - 1] < t) and (k == n_c - 1 or t <= tan_mids[k]):
                    claims += 1
        best = min(max(c, 0), n_c - 1)
        best_res = 0.0
        if claims > 1 or best == 0 or best == n_c - 1:
            best_res = np.inf
            for d in range(-1, 2):
                k = min(max(c + d, 0), n_c - 1)
                res = np.arctan2(z[p] - vertical[k], max(rho[p] - radial[k], 1e-6)) - table[k]
                if abs(res) < abs(best_res):
                    best, best_res = k, res
        ring[p] = best
        residual[p] = best_res


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
def ordering_keep(
    row, pos, col, theta, phi, n_c, row_len, n_cols, az_win, el_win, tol, keep
):  # pragma: no cover - compiled
    """Step 4 of III-C: the sequential loop of ``occlusion.ordering.ordering_loop``, with the same result.

    Points come in visiting order (ascending camera range), each at its own place ``(row, pos)`` of a row
    and in a column ``col`` that may hold several points of one row. A point is kept iff its ``theta`` is
    strictly greater than every kept ``theta`` left of it in its row and smaller than every one right of it
    (within ``az_win`` places), and its ``phi`` likewise in its column against the rows below / above
    (within ``el_win`` rows, with ``tol``).

    Why a nearest-neighbour lookup is exact: two kept entries of a line in different places, within one
    window of each other, were compared when the later one was kept, so kept values strictly increase along
    a line within any window (also for ``tol < 0``, which only demands more clearance). The extreme kept value
    left / below a point within its window is then the nearest kept one; a column cell keeps the largest and
    smallest ``phi`` of its points. For ``tol > 0`` a column need not be increasing, so every kept cell of
    the window is tested (columns are short: ``N_C`` cells).

    Args:
        row, pos, col: ``int64 [M]`` ring, place along the ring (all ``(row, pos)`` different), column
            (``0 <= col < n_cols``).
        theta, phi: ``float64 [M]`` azimuth / elevation seen from the camera centre (LiDAR axes).
        n_c, row_len, n_cols: Rows, places per row and columns.
        az_win, el_win: Window half-widths in places / rows (``row_len`` / ``n_c`` for the whole line).
        tol: Elevation tolerance in radians (see ``occlusion``).
        keep: ``bool [M]`` output.
    """
    row_words = (row_len + 63) >> 6  # words per row bitset
    col_words = (n_c + 63) >> 6
    row_bits = np.zeros(n_c * row_words, np.uint64)
    col_bits = np.zeros(n_cols * col_words, np.uint64)
    theta_final = np.empty(n_c * row_len)  # row-major; read only where a bit is set
    phi_max = np.full(n_cols * n_c, -np.inf)  # column-major: a column is contiguous
    phi_min = np.full(n_cols * n_c, np.inf)
    for k in range(row.shape[0]):
        keep[k] = False
        i = row[k]
        j = pos[k]
        th = theta[k]
        ph = phi[k]
        # (1) row i: the nearest kept entry left of j must be smaller, the nearest right of j greater.
        rb, rw = i * row_len, i * row_words
        c = _last_set(row_bits, rw, max(0, j - az_win), j)
        if c >= 0 and theta_final[rb + c] >= th:
            continue
        c = _first_set(row_bits, rw, j + 1, min(row_len, j + az_win + 1))
        if c >= 0 and theta_final[rb + c] <= th:
            continue
        # (2) column: entries below row i must be below phi + tol, entries above must be above phi - tol.
        jc = col[k]
        cb, cw = jc * n_c, jc * col_words
        lo, hi = max(0, i - el_win), min(n_c, i + el_win + 1)
        if tol > 0.0:  # every kept cell of the window (row i's own cell is not compared)
            c = _first_set(col_bits, cw, lo, hi)
            while c >= 0:
                if (c < i and phi_max[cb + c] >= ph + tol) or (c > i and phi_min[cb + c] <= ph - tol):
                    break
                c = _first_set(col_bits, cw, c + 1, hi)
            if c >= 0:
                continue
        else:
            c = _last_set(col_bits, cw, lo, i)
            if c >= 0 and phi_max[cb + c] >= ph + tol:
                continue
            c = _first_set(col_bits, cw, i + 1, hi)
            if c >= 0 and phi_min[cb + c] <= ph - tol:
                continue
        keep[k] = True
        _set(row_bits, rw, j)
        theta_final[rb + j] = th
        _set(col_bits, cw, i)
        phi_max[cb + i] = max(phi_max[cb + i], ph)
        phi_min[cb + i] = min(phi_min[cb + i], ph)


@njit(cache=True, nogil=True)
def zbuffer_keep(depth, width, pix, rng, radius, relative, threshold, keep):  # pragma: no cover - compiled
    """The z-buffer test: is each point within the margin of the nearest range in its own window?

    ``depth`` is the per-pixel nearest range ``[H * W]`` (+inf: empty). Point ``k`` at pixel ``pix[k]`` is
    kept iff ``rng[k] <= m * (1 + threshold)`` (``relative``) or ``rng[k] <= m + threshold``, with ``m`` the
    minimum of ``depth`` over the ``(2 r + 1)^2`` pixels around it, ``r = radius[k]`` (clipped at the image
    border). A window per point, so that it can follow the image scale at the point's pixel.
    """
    height = depth.shape[0] // width
    for k in range(pix.shape[0]):
        r = radius[k]
        v0, u0 = divmod(pix[k], width)
        m = np.inf
        for v in range(max(0, v0 - r), min(height, v0 + r + 1)):
            base = v * width
            for u in range(max(0, u0 - r), min(width, u0 + r + 1)):
                if depth[base + u] < m:
                    m = depth[base + u]
        limit = m * (np.float32(1.0) + threshold[k]) if relative else m + threshold[k]
        keep[k] = rng[k] <= limit


@njit(cache=True, nogil=True)
def scatter_min(values, target, out):  # pragma: no cover - compiled
    """``out[t[k]] = min(out[t[k]], values[k])`` for ``t = target``: ``np.minimum.at`` in one pass (exact)."""
    for k in range(target.shape[0]):
        t = target[k]
        if values[k] < out[t]:
            out[t] = values[k]


@njit(cache=True, nogil=True)
def newton_radtan(x, y, xd, yd, k1, k2, p1, p2, k3, k4, k5, k6, max_steps):  # pragma: no cover - compiled
    """Polish ``(x, y)`` in place so that OpenCV's radial-tangential distortion of it gives ``(xd, yd)``.

    Newton's method on the 2x2 system (analytic, symmetric Jacobian), per point until the residual is below 1e-15
    or ``max_steps``; non-finite starts are left alone. Float64 ``[N]`` arrays. Non-zero ``k4, k5, k6``: the
    rational model, the radial factor divided by ``1 + k4 r^2 + k5 r^4 + k6 r^6``.
    """
    rational = k4 != 0.0 or k5 != 0.0 or k6 != 0.0
    for i in range(x.shape[0]):
        a, b = x[i], y[i]
        if not (np.isfinite(a) and np.isfinite(b)):
            continue
        for _ in range(max_steps):
            r2 = a * a + b * b
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            d_radial = 2.0 * (k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3))
            if rational:
                den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
                radial = radial / den
                d_radial = (d_radial - radial * 2.0 * (k4 + r2 * (2.0 * k5 + r2 * 3.0 * k6))) / den
            ex = a * radial + 2.0 * p1 * a * b + p2 * (r2 + 2.0 * a * a) - xd[i]
            ey = b * radial + p1 * (r2 + 2.0 * b * b) + 2.0 * p2 * a * b - yd[i]
            if abs(ex) <= 1e-15 and abs(ey) <= 1e-15:
                break
            j11 = radial + a * a * d_radial + 2.0 * p1 * b + 6.0 * p2 * a
            j12 = a * b * d_radial + 2.0 * p1 * a + 2.0 * p2 * b
            j22 = radial + b * b * d_radial + 6.0 * p1 * b + 2.0 * p2 * a
            det = j11 * j22 - j12 * j12
            a, b = a - (j22 * ex - j12 * ey) / det, b - (j11 * ey - j12 * ex) / det
        x[i], y[i] = a, b
