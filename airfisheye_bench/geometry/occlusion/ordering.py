"""The paper's ordering method (III-C): the problem (steps 1-3) and the compiled and literal solvers (step 4).

docs/design.md, "LiDAR and occlusion", states the algorithm and every reading of the text decided here. The
numpy solver is :mod:`~airfisheye_bench.geometry.occlusion.ordering_vectorised`; the three implementations are
registered in :data:`~airfisheye_bench.geometry.occlusion.api.ORDERING_IMPLEMENTATIONS`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from airfisheye_bench.geometry import numba_kernels
from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.lidar_layout import ScanLayout, column_range, rings_from_elevation
from airfisheye_bench.geometry.occlusion.projection import Projection


@dataclass
class OrderingProblem:
    """The points of ``I_proj`` in visiting order (ascending camera range), with their places and angles."""

    ids: np.ndarray  # point indices
    row: np.ndarray  # ring
    pos: np.ndarray  # place along the ring (rank in LiDAR azimuth)
    col: np.ndarray  # azimuth sector, shifted to start at 0
    theta: np.ndarray  # theta~: azimuth seen from the camera centre in the LiDAR's axes (unwrapped)
    phi: np.ndarray  # phi~: elevation seen from the camera centre in the LiDAR's axes
    shape: tuple[int, int, int]  # (rows N_C, places per row, columns)


Layout = Callable[[np.ndarray, np.ndarray, np.ndarray, LidarSpec, np.ndarray | None], ScanLayout]
Solver = Callable[[OrderingProblem, int | None, int | None, float], np.ndarray]


def ordering_problem(
    points: np.ndarray,
    T: np.ndarray,
    proj: Projection,
    spec: LidarSpec,
    layout: Layout,
    rings: np.ndarray | None = None,
) -> OrderingProblem:
    """Steps 1-3 of III-C: the in-image returns in visiting order with their places in ``I_LiDAR`` and their
    angles seen from the camera. ``rings``: every point's ring where known (checked), else estimated from the
    channel table."""
    # Steps 1-2: I_LiDAR, then I_proj (the returns that project into the image).
    r, az, el = spherical_coordinates(points)
    if rings is None and not spec.is_uniform:
        rings = rings_from_elevation(r, el, spec)
    cut = widest_gap(az, proj.valid, spec.horizontal_resolution) if spec.hfov_deg == 360.0 else None
    if cut is not None:
        az = turn(az, cut)
    ring, position, column = layout(r, az, el, spec, rings)
    ids = np.flatnonzero((ring >= 0) & proj.valid)
    # Visiting order: ascending range from the camera, ties to the lower point index (a stable sort only when
    # needed: it is ten times slower than the default one).
    rng = proj.range[ids]
    order = np.argsort(rng)
    ranked = rng[order]
    if np.any(ranked[1:] == ranked[:-1]):
        order = np.argsort(rng, kind="stable")
    ids = ids[order]
    # Step 3: translate to the camera centre c = -R^T t, keeping the LiDAR's axes.
    centre = -T[:3, :3].T @ T[:3, 3]
    az = az[ids]
    # np.take gathers rows ~4x faster than fancy indexing (the same values).
    _, az_cam, el_cam = spherical_coordinates(np.take(points, ids, axis=0) - centre)
    if cut is not None:  # measured from the same cut as the rows' azimuths
        az_cam = turn(az_cam, cut)
    # theta = az + (remainder(az_cam - az + pi, 2 pi) - pi), the same operations in place
    theta = np.subtract(az_cam, az, out=az_cam)
    theta += math.pi
    np.remainder(theta, 2.0 * math.pi, out=theta)
    theta -= math.pi
    theta += az
    first_col, n_cols = column_range(spec)
    row_len = int(position.max()) + 1 if len(position) else 0
    return OrderingProblem(
        ids,
        ring[ids],
        position[ids],
        column[ids] - first_col,
        theta,
        el_cam,
        (spec.channels, row_len, n_cols),
    )


def widest_gap(az: np.ndarray, in_image: np.ndarray, sector: float) -> float | None:
    """The sector edge nearest the middle of the widest azimuth gap between the in-image points.

    ``None`` for fewer than two in-image points. On a sector edge (``-pi + k * sector``), so that turning the
    azimuths moves whole sectors and the column test compares the same returns wherever the cut falls.

    A row of ``I_LiDAR`` is a line from -pi to +pi, but a 360 deg ring is a circle: an occluder on one side of
    the line's ends would never be compared with the points it hides on the other. The camera sees a part of
    the ring only (unless it looks along the LiDAR's vertical axis), so the line is cut where it sees nothing.
    """
    seen = np.sort(az[in_image])
    if len(seen) < 2:
        return None
    gaps = np.diff(seen, append=seen[0] + 2.0 * math.pi)
    widest = int(np.argmax(gaps))
    middle = float(seen[widest] + 0.5 * gaps[widest])
    return -math.pi + round((middle + math.pi) / sector) * sector


def turn(az: np.ndarray, cut: float) -> np.ndarray:
    """Azimuths measured so that ``cut`` falls on -pi (the start of every row)."""
    return np.remainder(az - cut, 2.0 * math.pi) - math.pi


def layout_numba(
    r: np.ndarray, az: np.ndarray, el: np.ndarray, spec: LidarSpec, rings: np.ndarray | None = None
) -> ScanLayout:
    """:func:`~airfisheye_bench.geometry.lidar_layout.layout_from_angles` in O(N), compiled (the same result)."""
    n = len(r)
    position, column = (np.empty(n, dtype=np.int64) for _ in range(2))
    if rings is None and not spec.is_uniform:
        rings = rings_from_elevation(r, el, spec)
    ring = np.empty(n, dtype=np.int64) if rings is None else np.array(rings, dtype=np.int64)
    first_col, n_cols = column_range(spec)
    wrap_last = spec.points_per_channel - 1 if spec.hfov_deg == 360.0 else -1
    numba_kernels.lidar_layout(
        r,
        az,
        el,
        math.radians(spec.vfov_deg[0]),
        spec.vertical_resolution,
        spec.azimuth_edge,
        spec.horizontal_resolution,
        spec.channels,
        wrap_last,
        first_col,
        n_cols,
        rings is not None,
        ring,
        position,
        column,
    )
    return ScanLayout(ring, position, column)


def ordering_numba(prob: OrderingProblem, aw: int | None, ew: int | None, tol: float) -> np.ndarray:
    """Step 4 of III-C as one compiled sequential loop; the same result as :func:`ordering_loop`."""
    n_c, row_len, n_cols = prob.shape
    keep = np.empty(len(prob.ids), dtype=bool)
    az_win = row_len if aw is None else min(aw, row_len)
    el_win = n_c if ew is None else min(ew, n_c)
    numba_kernels.ordering_keep(
        prob.row, prob.pos, prob.col, prob.theta, prob.phi, n_c, row_len, n_cols, az_win, el_win, tol, keep
    )
    return keep


def ordering_loop(prob: OrderingProblem, aw: int | None, ew: int | None, tol: float) -> np.ndarray:
    """Step 4 of III-C, literally: one point at a time, nearest first (the reference implementation).

    A column cell may hold several kept points of one ring: "every entry below / above" is then every one of
    them, i.e. the largest / smallest, which ``phi_max`` / ``phi_min`` hold.
    """
    n_c, row_len, n_cols = prob.shape
    theta_final = np.full((n_c, row_len), np.nan)
    phi_max = np.full((n_c, n_cols), -np.inf)
    phi_min = np.full((n_c, n_cols), np.inf)
    keep = np.zeros(len(prob.ids), dtype=bool)
    for k in range(len(prob.ids)):  # R_cam in ascending order
        i, j, jc = int(prob.row[k]), int(prob.pos[k]), int(prob.col[k])
        theta, phi = prob.theta[k], prob.phi[k]
        # (1) row i of theta_final: greater than every entry in [0, j), smaller than every entry in (j, end].
        left = theta_final[i, 0 if aw is None else max(0, j - aw) : j]
        right = theta_final[i, j + 1 : row_len if aw is None else j + aw + 1]
        if np.any(left[~np.isnan(left)] >= theta) or np.any(right[~np.isnan(right)] <= theta):
            continue
        # (2) column jc: greater than every entry below row i, smaller than every entry above.
        below = phi_max[0 if ew is None else max(0, i - ew) : i, jc]
        above = phi_min[i + 1 : n_c if ew is None else i + ew + 1, jc]
        if np.any(below >= phi + tol) or np.any(above <= phi - tol):
            continue
        keep[k] = True
        theta_final[i, j] = theta
        phi_max[i, jc] = max(phi_max[i, jc], phi)
        phi_min[i, jc] = min(phi_min[i, jc], phi)
    return keep


__all__ = [
    "Layout",
    "OrderingProblem",
    "Solver",
    "layout_numba",
    "ordering_loop",
    "ordering_numba",
    "ordering_problem",
]
