"""A LiDAR scan organised into the paper's index matrix ``I_LiDAR`` (III-C, first step): each point's channel
(from the data, or from its elevation against the channel table) and its place along the row.

The beam pattern these functions read is :class:`~airfisheye_bench.geometry.lidar.LidarSpec`'s.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from airfisheye_bench.geometry import numba_kernels
from airfisheye_bench.geometry._arrays import ArrayLike
from airfisheye_bench.geometry.lidar import LidarSpec, as_points64, like, spherical_coordinates

__all__ = [
    "ScanLayout",
    "channel_residuals",
    "channels_exhaustive",
    "check_rings",
    "column_range",
    "layout_from_angles",
    "organize_scan",
    "rings_from_elevation",
]


# ---------------------------------------------------------------------- a point's channel from its elevation
_CHUNK = 16384  # points per block of the [points x channels] residuals (a few MB)


def check_rings(rings: object, n_points: int, spec: LidarSpec, name: str = "rings") -> np.ndarray:
    """A given per-point ring as ``int64 [N]``: integers in ``[-1, channels)`` (-1: no ring), one per point.

    Example:
        >>> check_rings([0, 3, -1], 3, LidarSpec(channels=4)).tolist()
        [0, 3, -1]
    """
    arr = np.asarray(rings.detach().cpu().numpy() if hasattr(rings, "detach") else rings)
    if arr.shape != (n_points,):
        raise ValueError(f"{name} must have one ring per point, shape ({n_points},), got {arr.shape}")
    integral = np.issubdtype(arr.dtype, np.integer) or (
        np.isfinite(arr).all() and (arr == np.round(arr)).all()
    )
    if arr.size and not integral:
        raise ValueError(f"{name} must be integers, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    if arr.size and (arr.min() < -1 or arr.max() >= spec.channels):
        raise ValueError(
            f"{name} must lie in [0, {spec.channels}) (the spec's channels; -1 for none), got "
            f"[{int(arr.min())}, {int(arr.max())}]"
        )
    return arr


def channel_residuals(r: np.ndarray, el: np.ndarray, spec: LidarSpec) -> np.ndarray:
    """``[N, N_C]`` elevation (radians) of each point seen from each channel's beam origin, minus the channel's.

    Where a channel's beam starts ``(radial, tangential, vertical)`` off the centre, a point at horizontal
    distance ``rho`` and height ``z`` has, seen from there, the elevation ``atan2(z - vertical, rho - radial)``
    (the tangential offset changes ``rho`` by ``tangential^2 / 2 rho``: neglected).
    """
    z, rho = r * np.sin(el), r * np.cos(el)
    radial, _, vertical = spec.channel_origins().T
    table = spec.channel_elevations()
    return np.arctan2(z[:, None] - vertical, np.maximum(rho[:, None] - radial, 1e-6)) - table


def rings_from_elevation(r: np.ndarray, el: np.ndarray, spec: LidarSpec) -> np.ndarray:
    """The channel nearest each point's elevation (``channel_table`` source); ``int64 [N]``, -1 for none.

    -1 for a point at the origin or more than half a channel spacing beyond the lowest / highest channel: no
    beam of the sensor can have returned it. Uniform channels from the centre: ``rint((el - lower) / res)``
    (what ``organize_scan`` has always done); a table: its nearest entry; beam origins off the centre: the
    channel whose beam, from its own origin, points nearest the point.

    Example:
        >>> spec = LidarSpec(elevations_deg=(-10.0, -2.0, 0.0, 1.0), points_per_channel=8)
        >>> rings_from_elevation(np.ones(4), np.radians([-9.0, -1.2, 0.8, 2.0]), spec).tolist()
        [0, 1, 3, -1]
    """
    r, el = np.asarray(r, dtype=np.float64), np.asarray(el, dtype=np.float64)
    if spec.is_uniform:
        ring = np.rint((el - math.radians(spec.vfov_deg[0])) / spec.vertical_resolution)
        return np.where((r > 0) & (ring >= 0) & (ring < spec.channels), ring, -1).astype(np.int64)
    table = spec.channel_elevations()
    below, above = (table[1] - table[0]) / 2.0, (table[-1] - table[-2]) / 2.0
    if spec.beam_origins_m is None:
        ring = np.searchsorted((table[1:] + table[:-1]) / 2.0, el)
        offside = (el < table[0] - below) | (el > table[-1] + above)
    else:
        ring, miss = _nearest_from_origins(r, el, spec)
        offside = ((ring == 0) & (miss < -below)) | ((ring == spec.channels - 1) & (miss > above))
    return np.where((r > 0) & ~offside, ring, -1).astype(np.int64)


def _nearest_from_origins(r: np.ndarray, el: np.ndarray, spec: LidarSpec) -> tuple[np.ndarray, np.ndarray]:
    """The channel whose beam, from its own origin, points nearest each point, and that residual (radians).

    A fixed point instead of all ``N x N_C`` residuals (compiled, ``numba_kernels.nearest_channel``): the table's
    nearest channel seen from the mean origin, then from the origin of the channel found (three rounds: origins
    differ by centimetres, so the channel settles), then the best of it and its two neighbours.
    ``channels_exhaustive`` checks it against the full search in the tests.
    """
    table = spec.channel_elevations()
    tan_mids = np.tan((table[1:] + table[:-1]) / 2.0)  # elevations within +-90 deg: tan keeps their order
    origins = spec.channel_origins()
    ring, residual = np.empty(len(r), dtype=np.int64), np.empty(len(r))
    numba_kernels.nearest_channel(
        r * np.sin(el),
        r * np.cos(el),
        tan_mids,
        table,
        origins[:, 0].copy(),
        origins[:, 2].copy(),
        ring,
        residual,
    )
    return ring, residual


def channels_exhaustive(r: np.ndarray, el: np.ndarray, spec: LidarSpec) -> np.ndarray:
    """The nearest channel seen from each channel's origin by testing all of them (the reference, O(N x N_C))."""
    ring = np.empty(len(r), dtype=np.int64)
    for start in range(0, len(r), _CHUNK):
        part = slice(start, start + _CHUNK)
        ring[part] = np.argmin(np.abs(channel_residuals(r[part], el[part], spec)), axis=1)
    return ring


# ---------------------------------------------------------------------- organisation (step 1 of III-C)
class ScanLayout(NamedTuple):
    """Where each point of a scan sits in ``I_LiDAR`` (see :func:`organize_scan`); ``int64 [N]`` arrays.

    Attributes:
        ring: Channel (row of ``I_LiDAR``, 0 = the lowest beam), or -1 for a point no beam of the sensor can
            have returned (at the origin, or more than half a channel spacing outside the vertical FOV), or
            given -1.
        position: Rank of the point in azimuth within its ring (its place along the row; -1 where ``ring`` is).
        column: Azimuth sector, ``floor((azimuth + HFOV/2) / (HFOV/N_PC))``: the spec's column ``j`` covers
            ``[-HFOV/2 + j * res, -HFOV/2 + (j + 1) * res)``. Points outside a partial HFOV get the sectors
            beyond ``[0, N_PC)`` (negative or ``>= N_PC``), so that they are organised (and tested) too.
    """

    ring: ArrayLike
    position: ArrayLike
    column: ArrayLike


def column_range(spec: LidarSpec) -> tuple[int, int]:
    """``(first, count)`` of the azimuth sectors that :class:`ScanLayout` can hold for this spec.

    ``first`` is the sector of azimuth ``-pi`` (<= 0), ``count`` the number of sectors up to ``+pi``.
    """
    if spec.hfov_deg == 360.0:
        return 0, spec.points_per_channel
    edge, res = spec.azimuth_edge, spec.horizontal_resolution
    first = math.floor((-math.pi - edge) / res)
    return first, math.floor((math.pi - edge) / res) - first + 1


def layout_from_angles(
    r: np.ndarray, az: np.ndarray, el: np.ndarray, spec: LidarSpec, rings: np.ndarray | None = None
) -> ScanLayout:
    """:func:`organize_scan` from the points' spherical coordinates (see :func:`spherical_coordinates`).

    The numpy reference of the compiled ``numba_kernels.lidar_layout`` (bit-identical: the same float64
    operations); numpy in, numpy out. ``rings``: every point's ring (checked), else :func:`rings_from_elevation`.
    """
    ring = rings_from_elevation(r, el, spec) if rings is None else np.asarray(rings, dtype=np.int64).copy()
    ring[r <= 0] = -1
    column = np.floor((az - spec.azimuth_edge) / spec.horizontal_resolution)
    if spec.hfov_deg == 360.0:
        column = np.minimum(column, spec.points_per_channel - 1)  # azimuth +pi exactly: the last sector
    # Rank in azimuth within the ring; lexsort is stable, so equal azimuths keep the lower index first.
    order = np.lexsort((az, ring))
    ranked = ring[order]
    position = np.empty(len(r), dtype=np.int64)
    position[order] = np.arange(len(r)) - np.searchsorted(ranked, ranked)
    position[ring < 0] = -1
    return ScanLayout(ring, position, column.astype(np.int64))


def organize_scan(points_lidar: ArrayLike, spec: LidarSpec, rings: ArrayLike | None = None) -> ScanLayout:
    """Organise a LiDAR scan into the paper's ``I_LiDAR`` (III-C, first step), wherever its beams sit.

    Row ``i`` of ``I_LiDAR`` is ring ``i`` with its points in ascending azimuth; column ``j`` is the spec's
    azimuth sector ``j``. The ring is the one the data gives (``rings``: a sensor's ring field, or an estimate
    from the firing order, :mod:`~airfisheye_bench.geometry.rings`), else the channel nearest the point's
    elevation seen from its beam's origin (:func:`rings_from_elevation`). No point competes for a cell: a real
    scan's beams sit at an arbitrary azimuth phase (per frame, per ring), with jitter and dropped returns, so a
    sector may hold zero, one or two points of a ring, and every one of them keeps its place. The result does
    not depend on the order of the points.

    Args:
        points_lidar: ``[N, 3]`` points in the LiDAR frame (numpy or torch, floating, finite).
        spec: The sensor that recorded the scan (channel table, sector width).
        rings: Optional ``[N]`` ring of every point (integers in ``[-1, channels)``; -1: none).

    Returns:
        :class:`ScanLayout` of ``int64 [N]`` arrays, numpy or torch like the input.

    Example:
        >>> import torch
        >>> spec = LidarSpec(channels=4, points_per_channel=8)
        >>> beams = spec.beam_directions(torch.float64).reshape(-1, 3)
        >>> layout = organize_scan(10.0 * beams.flip(0), spec)  # points listed in reverse order
        >>> [int(v[0]) for v in layout], [int(v[31]) for v in layout]  # (ring, position, column)
        ([3, 7, 7], [0, 0, 0])
        >>> given = organize_scan(10.0 * beams.flip(0), spec, rings=np.repeat([3, 2, 1, 0], 8))
        >>> bool((given.ring == layout.ring).all())
        True
    """
    if not isinstance(spec, LidarSpec):
        raise ValueError(f"spec must be a LidarSpec, got {type(spec).__name__}")
    points = as_points64(points_lidar, "points_lidar")
    if rings is not None:
        rings = check_rings(rings, len(points), spec)
    layout = layout_from_angles(*spherical_coordinates(points), spec, rings)
    return ScanLayout(*(like(v, points_lidar) for v in layout))
