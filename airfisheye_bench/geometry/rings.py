"""The ring (channel) of every return: from the data where it says so, else estimated, robustly.

Four sources, best first (docs/design.md, "Rings", says which file format gives which):

``field``         The sensor's own ring (nuScenes ``.pcd.bin``, ROS drivers' ``ring`` in PCD / PLY): passed through
                  (:func:`~airfisheye_bench.geometry.lidar_layout.check_rings`).
``firing_order``  The order of the points (KITTI ``.bin`` stores each laser's revolution contiguously, top laser
                  first, starting near azimuth 0 and wrapping once at +-180 deg): the scan is cut into one block
                  per revolution of a laser, and the blocks are matched to the channel table in order
                  (:func:`rings_from_firing_order`). Near returns keep their laser's ring whatever their
                  elevation, and a laser with no return at all does not shift the others.
``column_order``  The order of the points, column by column (a nuScenes sweep exported without its ring field, a
                  driver's packets where every firing is kept, no-returns included): each column holds every laser
                  once, in one fixed sequence, so point ``i`` is fired by the laser of slot ``i mod channels``; the
                  slots are matched to the channel table by their returns' median elevation
                  (:func:`rings_from_column_order`). Returns moved after they were measured (a sweep compensated
                  for the vehicle's motion) keep their laser's ring.
``channel_table`` Each point's elevation against the channel table, measured from where each channel's beam
                  starts (:func:`~airfisheye_bench.geometry.lidar_layout.rings_from_elevation`): exact beyond a few
                  metres; near returns of a sensor whose beam origins are not described, or of a sweep compensated
                  for the vehicle's motion, can land in a neighbouring ring.
"""

from __future__ import annotations

import math

import numpy as np

from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.lidar_layout import channel_residuals, check_rings, rings_from_elevation

RING_SOURCES = ("field", "firing_order", "column_order", "channel_table")


def firing_blocks(
    az: np.ndarray, full_turn: bool = True, jump_deg: float = 20.0, min_turn_deg: float = 30.0
) -> np.ndarray | None:
    """Cut a scan stored in firing order into revolutions of one laser each: the block index of every point.

    The points of a laser follow the rotation. ``full_turn`` (a 360 deg sensor): a step against the rotation by
    more than ``jump_deg`` is a gap without returns (the sky above a drone, a laser that sees only part of the
    scene), so the rotation is unwrapped forward, and a new block starts where it passes the start azimuth (0)
    again, at least ``min_turn_deg`` after the block began (a laser's first returns may lie a few degrees before
    0: its azimuth offset, the scan's phase). Otherwise (a partial field of view) a new block also
    starts where the azimuth jumps back by more than ``jump_deg``. ``None`` if the order shows no rotation (the
    points are not in firing order).
    """
    n = len(az)
    if n < 2:
        return None
    step = np.remainder(np.diff(az) + math.pi, 2.0 * math.pi) - math.pi
    direction = np.sign(np.median(step))
    if direction == 0:
        return None
    step *= direction  # positive along a laser's revolution
    back = step < -math.radians(jump_deg)
    if full_turn:
        step = np.where(back, step + 2.0 * math.pi, step)
        back[:] = False
    # rotation from azimuth 0, unwrapped: a block starts where it passes a multiple of a turn
    turned = np.concatenate([[0.0], np.cumsum(step)]) + np.remainder(direction * az[0], 2.0 * math.pi)
    lap = np.floor(turned / (2.0 * math.pi))
    jumped = np.concatenate([[False], back])
    candidates = np.flatnonzero(np.concatenate([[False], np.diff(lap) > 0]) | jumped)
    starts = [0]
    for k in candidates:
        if jumped[k] or turned[k] - turned[starts[-1]] > math.radians(min_turn_deg):
            starts.append(int(k))
    if len(starts) < 2:
        return None
    block = np.zeros(n, dtype=np.int64)
    block[np.asarray(starts[1:])] = 1
    return np.cumsum(block)


def rings_from_firing_order(
    r: np.ndarray, az: np.ndarray, el: np.ndarray, spec: LidarSpec, top_first: bool | None = None
) -> np.ndarray | None:
    """Rings from the storage order (``firing_order`` source): ``int64 [N]``, or ``None`` if there is none.

    The scan is cut into one block per laser revolution (:func:`firing_blocks`). With one block per channel the
    order alone assigns them (top laser first, or last if that fits the elevations better), so a biased channel
    table (beam origins not described) cannot shift them. Otherwise the blocks are matched to the channels in
    order by dynamic programming: block ``b + 1`` gets a lower ring than block ``b`` (``top_first``;
    ``None`` tries both and keeps the better match), and the match minimises, over each block's returns beyond
    2 m (all of them if it has none), their capped elevation residual to the channel (seen from its beam origin).
    A block may skip channels (a laser that returned nothing) and two consecutive blocks may share one (a
    revolution cut twice), at a penalty. ``None`` when the order holds fewer than 2 or more than 4 x channels
    blocks, or when the blocks' far returns do not share one elevation each: the points are not in KITTI's firing
    order.

    Example:
        >>> spec = LidarSpec(channels=3, points_per_channel=90, hfov_deg=360.0, vfov_deg=(-2.0, 2.0))
        >>> az = np.tile(np.linspace(0.0, 2 * np.pi, 90, endpoint=False), 3)
        >>> az = np.remainder(az + np.pi, 2 * np.pi) - np.pi  # each laser: from 0 round to 0, wrapping at 180
        >>> el = np.radians(np.repeat([2.0, 0.0, -2.0], 90))  # top laser first
        >>> rings_from_firing_order(np.full(270, 10.0), az, el, spec)[::90].tolist()
        [2, 1, 0]
    """
    # Returns within a metre (self-hits, zeros standing for no return) have unreliable azimuths: the blocks are
    # cut on the others, and each of them joins the block of the return stored before it.
    steady = r * np.cos(el) > 1.0
    steady_block = firing_blocks(az[steady], full_turn=spec.hfov_deg == 360.0)
    if steady_block is None:
        return None
    block = np.zeros(len(r), dtype=np.int64)
    block[steady] = steady_block
    block = np.maximum.accumulate(np.where(steady, block, 0))
    n_blocks = int(block[-1]) + 1
    if n_blocks > 4 * spec.channels:
        return None
    if not _blocks_hold_one_laser(r, el, block, n_blocks, spec):
        return None
    cost = _block_costs(r, el, block, n_blocks, spec)
    options = (True, False) if top_first is None else (top_first,)
    if n_blocks == spec.channels:  # one revolution per laser: the order alone says which is which
        forced = np.arange(n_blocks)
        matches = [
            (float(cost[forced, forced[::-1] if top else forced].sum()), forced[::-1] if top else forced)
            for top in options
        ]
    else:  # lasers without a return, or revolutions cut twice: the elevations decide
        matches = [_match_in_order(cost, top) for top in options]
    best = min(matches, key=lambda m: m[0])
    ring = _refine_boundaries(r, el, best[1][block], spec)
    return np.where(r > 0, ring, -1).astype(np.int64)


def _refine_boundaries(r: np.ndarray, el: np.ndarray, ring: np.ndarray, spec: LidarSpec) -> np.ndarray:
    """Move each cut between two lasers' runs to where the elevations change from one channel to the other.

    A laser's revolution starts near azimuth 0, but not exactly there (its azimuth offset, the scan's phase):
    the cut found from the azimuth alone can leave a few degrees of one laser in its neighbour's run. Around
    each cut (a window of an eighth of the shorter run) the split minimises the summed capped residuals of the
    points before it to the first ring and after it to the second.
    """
    cuts = np.flatnonzero(np.diff(ring)) + 1
    if len(cuts) == 0:
        return ring
    ring = ring.copy()
    edges = np.concatenate([[0], cuts, [len(ring)]])
    cap = 3.0 * spec.vertical_resolution
    # A run whose far returns sit off their channel (a table that misses beam origins or calibration) cannot
    # place the cut better than the azimuth did: its cuts are left alone.
    bias = np.zeros(len(edges) - 1)
    far = r * np.cos(el) > 5.0
    for k in range(len(edges) - 1):
        ids = np.arange(edges[k], edges[k + 1])
        ids = ids[far[ids]][:: max(1, int(far[ids].sum()) // 256)]
        if len(ids):
            bias[k] = float(np.median(channel_residuals(r[ids], el[ids], spec)[:, ring[edges[k]]]))
    for k in range(1, len(edges) - 1):
        cut = edges[k]
        w = max(1, min(edges[k] - edges[k - 1], edges[k + 1] - edges[k]) // 8)
        lo, hi = cut - w, cut + w
        a, b = ring[cut - 1], ring[cut]
        if max(abs(bias[k - 1]), abs(bias[k])) > 0.1 * spec.vertical_resolution:
            continue
        res = np.minimum(np.abs(channel_residuals(r[lo:hi], el[lo:hi], spec)[:, [a, b]]), cap)
        # cost of splitting at lo + s: points [lo, lo + s) to a, [lo + s, hi) to b
        before = np.concatenate([[0.0], np.cumsum(res[:, 0])])
        after = np.concatenate([np.cumsum(res[::-1, 1])[::-1], [0.0]])
        split = lo + int(np.argmin(before + after))
        ring[lo:split], ring[split:hi] = a, b
    return ring


def _blocks_hold_one_laser(
    r: np.ndarray, el: np.ndarray, block: np.ndarray, n_blocks: int, spec: LidarSpec
) -> bool:
    """Whether the blocks look like single lasers: the far returns of a block share one elevation.

    A file whose order is not KITTI's (another laser order, another start azimuth) cuts into blocks that mix
    lasers: their far returns spread over many channel spacings. Seen from the lasers' mean beam origin, a laser's
    returns beyond 5 m lie within a degree or so; the median block's interquartile range must stay under three
    mean channel spacings.
    """
    radial, _, vertical = spec.channel_origins().mean(axis=0)
    rho = r * np.cos(el)
    seen = np.arctan2(r * np.sin(el) - vertical, np.maximum(rho - radial, 1e-6))
    far = rho > 5.0
    spreads = []
    for b in np.unique(block[far]):
        values = seen[far & (block == b)]
        if len(values) >= 8:
            q1, q3 = np.percentile(values, [25, 75])
            spreads.append(q3 - q1)
    return bool(spreads) and float(np.median(spreads)) < 3.0 * spec.vertical_resolution


def _block_costs(
    r: np.ndarray, el: np.ndarray, block: np.ndarray, n_blocks: int, spec: LidarSpec
) -> np.ndarray:
    """``[B, N_C]``: for each block, the summed capped residual of (up to 64 of) its returns to each channel."""
    cap = 3.0 * spec.vertical_resolution
    far = r * np.cos(el) > 2.0
    cost = np.zeros((n_blocks, spec.channels))
    starts = np.searchsorted(block, np.arange(n_blocks + 1))
    picks = []
    for b in range(n_blocks):
        ids = np.arange(starts[b], starts[b + 1])
        ids = ids[far[ids]] if far[ids].any() else ids
        picks.append(
            ids[np.linspace(0, len(ids) - 1, min(64, len(ids))).astype(np.int64)] if len(ids) else ids
        )
    ids = np.concatenate(picks)
    owner = np.repeat(np.arange(n_blocks), [len(p) for p in picks])
    residual = np.minimum(np.abs(channel_residuals(r[ids], el[ids], spec)), cap)
    np.add.at(cost, owner, residual)
    counts = np.array([max(len(p), 1) for p in picks], dtype=np.float64)
    return cost / counts[:, None] * np.sqrt(counts)[:, None]  # mean residual, weighted by evidence


def _match_in_order(cost: np.ndarray, top_first: bool) -> tuple[float, np.ndarray]:
    """Channels for the blocks, monotone in block order, minimising the summed cost (a repeat costs extra)."""
    c = cost if not top_first else cost[:, ::-1]  # make the order ascending in the column index
    n_blocks, n_c = c.shape
    repeat = float(np.median(c)) if c.size else 0.0
    total = c[0].copy()
    choice = np.zeros((n_blocks, n_c), dtype=np.int64)  # previous block's column
    for b in range(1, n_blocks):
        # previous column strictly lower (prefix minimum up to j - 1), or the same column with a penalty
        prefix = np.minimum.accumulate(total)
        arg = _prefix_argmin(total)
        strict = np.concatenate([[np.inf], prefix[:-1]])
        strict_arg = np.concatenate([[0], arg[:-1]])
        same = total + repeat
        take_same = same < strict
        choice[b] = np.where(take_same, np.arange(n_c), strict_arg)
        total = np.where(take_same, same, strict) + c[b]
    cols = np.empty(n_blocks, dtype=np.int64)
    cols[-1] = int(np.argmin(total))
    for b in range(n_blocks - 1, 0, -1):
        cols[b - 1] = choice[b, cols[b]]
    rings = n_c - 1 - cols if top_first else cols
    return float(total.min()), rings


def rings_from_column_order(
    r: np.ndarray, el: np.ndarray, spec: LidarSpec, columns: int = 16
) -> np.ndarray | None:
    """Rings from a column-major storage order (``column_order`` source): ``int64 [N]``, or ``None``.

    A file that keeps every firing (nuScenes ``.pcd.bin``: 32 x 1084 points, no-returns included) stores the scan
    column by column, each column holding every laser once in one fixed sequence (nuScenes: ring order; a Velodyne
    packet: the laser IDs' firing order, which interleaves the HDL-32E's banks). Point ``i`` then belongs to slot
    ``i mod channels``, whatever its elevation: the slots are ranked by the median elevation of their returns beyond
    2 m (seen from the lasers' mean beam origin) and the rank is the ring; slots without such returns are left to the
    channel table, and the others matched to the channels in order (:func:`_match_in_order`). The order is taken only
    where it holds everywhere (:func:`_order_holds`): every slot's returns beyond 10 m lie within half a channel
    spacing of their channel (median), and in every run of ``columns`` columns they fit their slots' rings better
    than those of the slots beside them. A file with a point missing (returns dropped, a cropped scan) shifts the
    slots and fails this: ``None``, and the table decides.

    Example:
        >>> spec = LidarSpec(channels=3, points_per_channel=90, hfov_deg=360.0, vfov_deg=(-2.0, 2.0))
        >>> el = np.radians(np.tile([0.0, -2.0, 2.0], 90))  # every column: the middle, lower, upper laser
        >>> rings_from_column_order(np.full(270, 20.0), el, spec)[:3].tolist()
        [1, 0, 2]
    """
    n_c, n = spec.channels, len(r)
    if n < 2 * columns * n_c:
        return None
    rho, z = r * np.cos(el), r * np.sin(el)
    radial, _, vertical = spec.channel_origins().mean(axis=0)
    seen = np.arctan2(z - vertical, np.maximum(rho - radial, 1e-6))
    slots = _by_slot(np.where(rho > 2.0, seen, np.nan), n_c)  # [columns, slot]
    median = _nanmedian_rows(slots.T)  # a slot without returns beyond 2 m: NaN
    known = np.flatnonzero(np.isfinite(median))
    if len(known) < n_c // 2:
        return None
    known = known[np.argsort(median[known], kind="stable")]
    ring_of_slot = np.full(n_c, -1, dtype=np.int64)
    if len(known) == n_c:  # every laser returned: the rank is the ring
        ring_of_slot[known] = np.arange(n_c)
    else:
        table = spec.channel_elevations()
        cost = np.minimum(np.abs(median[known, None] - table[None, :]), 3.0 * spec.vertical_resolution)
        ring_of_slot[known] = _match_in_order(cost, top_first=False)[1]
    if not _order_holds(r, el, ring_of_slot, spec, n_c * columns):
        return None
    ring = ring_of_slot[np.arange(n) % n_c]
    unknown = ring < 0
    if unknown.any():
        ring[unknown] = rings_from_elevation(r[unknown], el[unknown], spec)
    return np.where(r > 0, ring, -1).astype(np.int64)


def _by_slot(values: np.ndarray, width: int) -> np.ndarray:
    """``values`` padded with NaN to whole rows of ``width`` and reshaped to ``[rows, width]``."""
    rows = -(-len(values) // width)
    padded = np.full(rows * width, np.nan)
    padded[: len(values)] = values
    return padded.reshape(rows, width)


def _order_holds(r: np.ndarray, el: np.ndarray, ring_of_slot: np.ndarray, spec: LidarSpec, run: int) -> bool:
    """Whether the slots' rings fit the returns beyond 10 m: every slot's, and every run of ``run`` points' phase.

    Residuals are seen from each channel's beam origin, in half the spacing to its nearest neighbour, on returns
    beyond 10 m only: a sweep compensated for the vehicle's motion moves near returns by up to a channel spacing
    (nuScenes, 9 m/s: the ground 5 m ahead by 1.1 deg), far ones by a fraction of it. A slot's median must stay
    under 1 (its channel, not a neighbour's: a table that does not fit fails here). In every run with 8 such returns
    or more, the slots' rings must fit better than those of the slots one before or after: a point missing before
    the run shifts its phase by one, and then a neighbouring slot's ring fits.
    """
    n_c, n = spec.channels, len(r)
    table = spec.channel_elevations()
    gap = np.diff(table)
    half = np.minimum(np.concatenate([gap[:1], gap]), np.concatenate([gap, gap[-1:]])) / 2.0
    radial, _, vertical = spec.channel_origins().T
    far = np.flatnonzero(r * np.cos(el) > 10.0)
    if len(far) == 0:
        return False
    rho, z, slot = r[far] * np.cos(el[far]), r[far] * np.sin(el[far]), far % n_c

    def scaled(shift: int) -> np.ndarray:
        """Every point's residual in half-spacings to the ring of the slot ``shift`` beside its own (NaN: not far)."""
        ring = ring_of_slot[(slot + shift) % n_c]
        k = np.maximum(ring, 0)
        out = np.full(n, np.nan)
        out[far] = np.where(
            ring >= 0,
            (np.arctan2(z - vertical[k], np.maximum(rho - radial[k], 1e-6)) - table[k]) / half[k],
            np.nan,
        )
        return out

    # The slots first: a file stored in another order (ring by ring) fails here, before the runs are measured.
    fit = scaled(0)
    per_slot = _nanmedian_rows(_by_slot(fit, n_c).T)  # slots without far returns: NaN, skipped
    if np.isnan(per_slot).all() or np.nanmax(np.abs(per_slot)) >= 1.0:
        return False
    counted = np.isfinite(_by_slot(fit, run)).sum(axis=1) >= 8  # runs without 8 far returns are skipped
    if not counted.any():
        return False
    per_run = np.stack([_nanmedian_rows(np.abs(_by_slot(f, run))) for f in (fit, scaled(-1), scaled(1))])
    return bool((per_run[0, counted] < np.fmin(per_run[1, counted], per_run[2, counted])).all())


def _nanmedian_rows(values: np.ndarray) -> np.ndarray:
    """``np.nanmedian(values, axis=1)`` to the bit, in one sort rather than a Python call per row (NaN: no values).

    Example:
        >>> _nanmedian_rows(np.array([[3.0, np.nan, 1.0, 2.0], [4.0, 1.0, np.nan, np.nan], [np.nan] * 4])).tolist()
        [2.0, 2.5, nan]
    """
    ordered = np.sort(values, axis=1)  # NaN sorts last
    count = (~np.isnan(ordered)).sum(axis=1)
    rows = np.arange(len(ordered))
    lo, hi = ordered[rows, np.maximum(count - 1, 0) // 2], ordered[rows, count // 2]
    return np.where(count > 0, (lo + hi) / 2.0, np.nan)


def _prefix_argmin(values: np.ndarray) -> np.ndarray:
    idx = np.arange(len(values))
    best = np.minimum.accumulate(values)
    return np.maximum.accumulate(np.where(values == best, idx, 0))


def resolve_rings(
    points: np.ndarray, spec: LidarSpec, rings: np.ndarray | None = None, firing_order: bool = False
) -> tuple[np.ndarray, str]:
    """Every point's ring and where it came from (one of :data:`RING_SOURCES`), the best source first.

    Args:
        points: ``float64 [N, 3]`` in the order of the file.
        spec: The sensor.
        rings: The file's ring field, if it has one (checked against the spec).
        firing_order: The file keeps the firing order (KITTI ``.bin``); falls back to the column order, then the
            channel table, when the order shows no revolutions. Any file's order is tried as a column order
            (:func:`rings_from_column_order`: it holds only where every firing was kept).

    Example:
        >>> spec = LidarSpec(channels=4, points_per_channel=8)
        >>> pts = 10.0 * spec.beam_directions().reshape(-1, 3).double().numpy()
        >>> ring, source = resolve_rings(pts, spec)
        >>> source, ring[::8].tolist()
        ('channel_table', [0, 1, 2, 3])
    """
    if rings is not None:
        return check_rings(rings, len(points), spec), "field"
    r, az, el = spherical_coordinates(points)
    if firing_order:
        ordered = rings_from_firing_order(r, az, el, spec)
        if ordered is not None:
            return ordered, "firing_order"
    by_column = rings_from_column_order(r, el, spec)
    if by_column is not None:
        return by_column, "column_order"
    return rings_from_elevation(r, el, spec), "channel_table"


__all__ = [
    "RING_SOURCES",
    "firing_blocks",
    "resolve_rings",
    "rings_from_column_order",
    "rings_from_firing_order",
]
