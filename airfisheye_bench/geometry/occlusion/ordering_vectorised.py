"""Step 4 of the ordering method in numpy: exactly the mask of the sequential loop, without a Python loop per point.

Kept as a cross-check of the compiled solver and for the benchmark's old-vs-new comparison.
"""

from __future__ import annotations

import numpy as np

from airfisheye_bench.geometry.occlusion.ordering import OrderingProblem


def ordering_vectorised(prob: OrderingProblem, aw: int | None, ew: int | None, tol: float) -> np.ndarray:
    """Step 4 of III-C, vectorised; returns exactly what :func:`ordering_loop` returns."""
    return _OrderingSolver(prob, aw, ew, tol).run()


# A conflict between two points: same row (column) and their theta~ (phi~) out of the I_LiDAR order. The
# sequential algorithm keeps a point iff no *kept* nearer point conflicts with it (conflicts are symmetric).
_MARGIN = 1e-9  # radians: conflict *detection* may flag extra pairs (harmless), it must never miss one


class _KeptCells:
    """Kept cells of an ``n_lines x line_len`` matrix: the nearest kept cell before / after one on its line.

    Cells are keyed ``line * line_len + position`` (rows for row-major keys, columns for column-major keys)
    and held as sorted keys, so a neighbour is one binary search away. A key may be added more than once
    (a column cell holding several points of a ring); its neighbours are the nearest *other* kept cells.
    Large batches are merged through a dense occupancy mask; small ones go to a short second sorted array,
    so adding them does not copy the long one.
    """

    def __init__(self, n_lines: int, line_len: int) -> None:
        self.line_len = line_len
        self.occupied = np.zeros(n_lines * line_len, dtype=bool)
        self.main = np.empty(0, dtype=np.int64)  # sorted
        self.extra = np.empty(0, dtype=np.int64)  # sorted, short
        self.limit = max(64, len(self.occupied) // 64)

    def add(self, keys: np.ndarray) -> None:
        if len(self.extra) + len(keys) > self.limit:
            self.occupied[self.extra] = True
            self.occupied[keys] = True
            self.main = np.flatnonzero(self.occupied)
            self.extra = np.empty(0, dtype=np.int64)
        else:
            keys = np.sort(keys)
            self.extra = np.insert(self.extra, np.searchsorted(self.extra, keys), keys)

    def neighbours(self, keys: np.ndarray, window: int | None) -> tuple[np.ndarray, ...]:
        """``(before, has_before, after, has_after)`` for each key, limited to ``window`` cells if given."""
        line = keys // self.line_len
        before = np.full(len(keys), -1, dtype=np.int64)
        after = np.full(len(keys), len(self.occupied), dtype=np.int64)
        for kept in (self.main, self.extra):
            if len(kept) == 0:
                continue
            pos = np.searchsorted(kept, keys)
            cand = kept[np.maximum(pos - 1, 0)]
            before = np.where((pos > 0) & (cand // self.line_len == line), np.maximum(before, cand), before)
            pos = np.searchsorted(kept, keys, side="right")
            cand = kept[np.minimum(pos, len(kept) - 1)]
            after = np.where(
                (pos < len(kept)) & (cand // self.line_len == line), np.minimum(after, cand), after
            )
        has_before, has_after = before >= 0, after < len(self.occupied)
        if window is not None:
            has_before &= keys - before <= window
            has_after &= after - keys <= window
        return np.maximum(before, 0), has_before, np.minimum(after, len(self.occupied) - 1), has_after


class _OrderingSolver:
    """Vectorised step 4 of III-C, exactly equal to :func:`ordering_loop`.

    ``_solve(S)`` decides a distance-sorted set ``S`` of points given the kept set ``K`` of the points nearer
    than all of them (plus kept points that conflict with none of them, which change nothing):

    1. Points that conflict with ``K`` are rejected. ``K`` is a subset of the final kept set, in which every
       row (within the azimuth window) is strictly increasing in ``theta~``, so "greater than every kept entry
       to the left" is "greater than the nearest kept entry to the left". Likewise for columns when
       ``elevation_tolerance == 0``; otherwise the exact column max/min is taken.
    2. Of the rest, the points that conflict with no other point of ``S`` are kept: nothing the sequential
       loop could have kept before them conflicts with them.
    3. The remaining, mutually conflicting points are split by distance into a nearer and a farther half,
       solved in that order (the farther half is tested against what the nearer half kept).

    Each pass is a handful of array operations over its set. In scans of real scenes few points conflict, so
    there are few passes (tens for a 64 x 2048 scan), the first one handling almost every point.
    """

    def __init__(self, prob: OrderingProblem, aw: int | None, ew: int | None, tol: float) -> None:
        self.n_c, self.row_len, self.n_cols = prob.shape
        self.row, self.col, self.theta, self.phi = prob.row, prob.col, prob.theta, prob.phi
        self.aw, self.ew, self.tol = aw, ew, tol
        self.row_key = self.row * self.row_len + prob.pos  # row-major place, one point each
        self.col_key = self.col * self.n_c + self.row  # column-major cell, possibly several points
        self.theta_final = np.full(self.n_c * self.row_len, np.nan)  # row-major
        self.phi_max = np.full(self.n_cols * self.n_c, -np.inf)  # column-major, per cell
        self.phi_min = np.full(self.n_cols * self.n_c, np.inf)
        self.kept_rows = _KeptCells(self.n_c, self.row_len)
        self.kept_cols = _KeptCells(self.n_cols, self.n_c)
        self.keep = np.zeros(len(prob.ids), dtype=bool)
        self.passes = 0

    def run(self) -> np.ndarray:
        """Decide every point; returns the keep mask in visiting order."""
        self._solve(np.arange(len(self.keep)), tested=True)
        return self.keep

    def _solve(self, S: np.ndarray, tested: bool = False) -> None:
        self.passes += 1
        C = S if tested else S[~self._violates_kept(S)]
        if len(C) <= 1:
            self._insert(C)
            return
        flag = self._conflicted(C)
        self._insert(C[~flag])
        D = C[flag]
        if len(D):
            half = len(D) // 2
            # The points just kept conflict with no member of D, so the nearer half needs no new test.
            self._solve(D[:half], tested=True)
            self._solve(D[half:])

    # -- step 1: conflicts with the kept set
    def _violates_kept(self, S: np.ndarray) -> np.ndarray:
        th, ph = self.theta[S], self.phi[S]
        b, hb, a, ha = self.kept_rows.neighbours(self.row_key[S], self.aw)
        bad = (hb & (self.theta_final[b] >= th)) | (ha & (self.theta_final[a] <= th))
        if self.tol == 0.0:
            b, hb, a, ha = self.kept_cols.neighbours(self.col_key[S], self.ew)
            return bad | (hb & (self.phi_max[b] >= ph)) | (ha & (self.phi_min[a] <= ph))
        # With a tolerance a kept column need not be monotone: take the exact max below / min above.
        r, c = self.row[S][:, None], self.col[S][:, None] * self.n_c
        offsets = np.arange(1, (self.n_c if self.ew is None else min(self.ew, self.n_c)) + 1)
        below, above = r - offsets, r + offsets
        below = np.where(below >= 0, self.phi_max[c + np.clip(below, 0, self.n_c - 1)], -np.inf)
        above = np.where(above < self.n_c, self.phi_min[c + np.clip(above, 0, self.n_c - 1)], np.inf)
        max_below = below.max(axis=1, initial=-np.inf)
        min_above = above.min(axis=1, initial=np.inf)
        return bad | (max_below >= ph + self.tol) | (min_above <= ph - self.tol)

    # -- step 2: conflicts inside the set (windows ignored: flagging a superset is safe)
    def _conflicted(self, C: np.ndarray) -> np.ndarray:
        rows = _out_of_order(self.row_key[C], self.theta[C], self.row_len, 0.0, self.n_c * self.row_len)
        cols = _out_of_order(self.col_key[C], self.phi[C], self.n_c, self.tol, None)
        return rows | cols

    def _insert(self, F: np.ndarray) -> None:
        if len(F) == 0:
            return
        self.keep[F] = True
        self.theta_final[self.row_key[F]] = self.theta[F]
        np.maximum.at(self.phi_max, self.col_key[F], self.phi[F])
        np.minimum.at(self.phi_min, self.col_key[F], self.phi[F])
        self.kept_rows.add(self.row_key[F])
        self.kept_cols.add(self.col_key[F])


def _out_of_order(
    keys: np.ndarray, values: np.ndarray, line_len: int, tol: float, n_cells: int | None
) -> np.ndarray:
    """Flag the cells that have another cell of the set on their line with a value out of order.

    "Out of order" by more than ``tol - margin`` (a superset of the exact test: points sharing a cell may flag
    each other). ``keys`` are cells ``line * line_len + position``, distinct if ``n_cells`` (their number) is
    given; one ascending scan covers every line at once, the lines being separated by offsets larger than any
    value difference.
    """
    if n_cells is not None and len(keys) * 16 > n_cells:  # counting sort: distinct cells of a small matrix
        slot = np.full(n_cells, -1, dtype=np.int64)
        slot[keys] = np.arange(len(keys))
        order = slot[slot >= 0]
    else:
        order = np.argsort(keys)
    span = float(values.max() - values.min()) + 2.0 * abs(tol) + 1.0
    v = values[order] + (keys[order] // line_len) * span
    before_max = np.maximum.accumulate(v)
    after_min = np.minimum.accumulate(v[::-1])[::-1]
    flag = np.zeros(len(v), dtype=bool)
    flag[1:] = before_max[:-1] >= v[1:] + tol - _MARGIN
    flag[:-1] |= after_min[1:] <= v[:-1] - tol + _MARGIN
    out = np.empty_like(flag)
    out[order] = flag
    return out


__all__ = ["ordering_vectorised"]
