"""What callers use: the visibility mask of a scan, its projection, its sparse depth map, and ``ordering`` by name.

docs/design.md, "LiDAR and occlusion", explains every method; :mod:`.options` holds their options.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
import torch

from airfisheye_bench.geometry import numba_kernels
from airfisheye_bench.geometry._arrays import ArrayLike
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.lidar import LidarSpec, as_points64, like
from airfisheye_bench.geometry.lidar_layout import check_rings, layout_from_angles
from airfisheye_bench.geometry.occlusion.hpr import hpr_mask
from airfisheye_bench.geometry.occlusion.options import Occlusion, check_occlusion_options
from airfisheye_bench.geometry.occlusion.ordering import (
    Layout,
    Solver,
    layout_numba,
    ordering_loop,
    ordering_numba,
    ordering_problem,
)
from airfisheye_bench.geometry.occlusion.ordering_vectorised import ordering_vectorised
from airfisheye_bench.geometry.occlusion.projection import (
    Projection,
    as_transform64,
    pixel_index,
    project_points,
)
from airfisheye_bench.geometry.occlusion.zbuffer import zbuffer_mask


class LidarProjection(NamedTuple):
    """Per-point result of :func:`project_lidar` (numpy or torch like the input points).

    Attributes:
        uv: ``[N, 2]`` pixel coordinates ``(u, v)`` (meaningful where the point projects into the image).
        range: ``[N]`` Euclidean distance from the camera centre in metres.
        mask: ``[N]`` bool, projects into the image and is not occluded.
    """

    uv: ArrayLike
    range: ArrayLike
    mask: ArrayLike


# ---------------------------------------------------------------------------------------------- public API
def occlusion_mask(
    points_lidar: ArrayLike,
    T_cam_lidar: ArrayLike,
    camera: CameraModel,
    spec: LidarSpec | None = None,
    method: str | Occlusion = "ordering",
    rings: ArrayLike | None = None,
    **options: Any,
) -> ArrayLike:
    """Which LiDAR points project into the image *and* are seen by the camera.

    Args:
        points_lidar: ``[N, 3]`` points in the LiDAR frame (numpy or torch, floating, finite).
        T_cam_lidar: ``[4, 4]`` rigid transform mapping LiDAR-frame points to the camera frame.
        camera: The fisheye camera.
        spec: The LiDAR that recorded the scan (used by ``ordering``); ``None`` means the paper's sensor,
            ``LidarSpec()``.
        method: ``"ordering"`` (paper, III-C), ``"zbuffer"``, ``"hpr"`` or ``"none"``; see docs/design.md
            ("LiDAR and occlusion"). Or an :class:`Occlusion`, the method with its options checked when it was
            built: taken as it is (no ``options`` then), so a caller projecting many scans checks them once.
        **options: Per method (:data:`OCCLUSION_OPTIONS` holds the defaults). ``ordering``:
            ``azimuth_window`` (places either side along the row, default ``None`` = whole row),
            ``elevation_window`` (rows either side, default ``None`` = whole column), ``elevation_tolerance``
            (signed, in vertical resolutions: > 0 tolerates, < 0 demands a clearance; default 0).
            ``zbuffer``: ``kernel`` (odd window size in pixels; default ``None``: derived per pixel from the
            LiDAR's angular spacing and the image scale), ``threshold`` (margin; default ``None``: derived,
            relative), ``relative`` (``threshold`` is a fraction of the window's nearest range rather than
            metres; default True; False needs a ``threshold``), ``max_incidence_deg`` (steepest surface
            the derived margin accepts, default 87). ``hpr``: ``radius`` (flipping sphere radius as a
            multiple of the farthest point's range from the camera, > 1; default 1000).
        rings: Optional ``[N]`` ring of every point (a sensor's ring field, or an estimate from the firing order;
            integers in ``[-1, channels)``), used by ``ordering`` instead of estimating it from the elevation.

    Returns:
        ``bool [N]`` mask, numpy or torch like ``points_lidar``.

    Example:
        >>> import numpy as np
        >>> from airfisheye_bench.geometry import ideal_camera, CAM_FROM_FLU, make_transform
        >>> spec = LidarSpec(channels=16, points_per_channel=256)
        >>> wall = 10.0 * spec.beam_directions(torch.float64).reshape(-1, 3).numpy()  # a 10 m sphere
        >>> T = make_transform(CAM_FROM_FLU, np.zeros(3))  # camera at the LiDAR, looking along x
        >>> camera = ideal_camera(256, 256)
        >>> visible = occlusion_mask(wall, T, camera, spec)
        >>> in_view = occlusion_mask(wall, T, camera, spec, method="none")
        >>> bool(visible.any()), bool((visible == in_view).all())  # camera at the LiDAR: nothing hidden
        (True, True)
    """
    return project_lidar(points_lidar, T_cam_lidar, camera, spec, method, rings, **options).mask


def project_lidar(
    points_lidar: ArrayLike,
    T_cam_lidar: ArrayLike,
    camera: CameraModel,
    spec: LidarSpec | None = None,
    method: str | Occlusion = "ordering",
    rings: ArrayLike | None = None,
    **options: Any,
) -> LidarProjection:
    """Project a scan into the image: pixel coordinates, camera ranges and the visibility mask of every point.

    Arguments as for :func:`occlusion_mask`.

    Example:
        >>> import numpy as np
        >>> from airfisheye_bench.geometry import ideal_camera, CAM_FROM_FLU, make_transform
        >>> T = make_transform(CAM_FROM_FLU, np.zeros(3))
        >>> point = np.array([[5.0, 0.0, 0.0]])
        >>> uv, rng, mask = project_lidar(point, T, ideal_camera(64, 64), method="none")
        >>> uv.tolist(), rng.tolist(), mask.tolist()
        ([[31.5, 31.5]], [5.0], [True])
    """
    points = as_points64(points_lidar, "points_lidar")
    T = as_transform64(T_cam_lidar)
    if not isinstance(camera, CameraModel):
        raise ValueError(f"camera must be a CameraModel, got {type(camera).__name__}")
    if spec is None:
        spec = LidarSpec()
    elif not isinstance(spec, LidarSpec):
        raise ValueError(f"spec must be a LidarSpec or None, got {type(spec).__name__}")
    if isinstance(method, Occlusion):
        if options:
            raise ValueError(
                f"give the options inside the Occlusion, not also as keywords: {sorted(options)}"
            )
        occlusion = method
    else:
        occlusion = Occlusion(method, options)
    method, opts = occlusion.method, occlusion.options
    ring = None if rings is None else check_rings(rings, len(points), spec)

    proj = project_points(points, T, camera)
    if method == "ordering":
        mask = solve_ordering(points, T, proj, spec, opts, "numba", ring)
    elif method == "zbuffer":
        mask = zbuffer_mask(proj, camera, spec, **opts)
    elif method == "hpr":
        mask = hpr_mask(points, T, proj, **opts)
    else:
        mask = proj.valid.copy()

    dtype = points_lidar.dtype
    if isinstance(points_lidar, torch.Tensor):
        uv = torch.from_numpy(proj.uv).to(points_lidar.device, dtype)
        rng = torch.from_numpy(proj.range).to(points_lidar.device, dtype)
        return LidarProjection(uv, rng, like(mask, points_lidar))
    return LidarProjection(proj.uv.astype(dtype, copy=False), proj.range.astype(dtype, copy=False), mask)


def lidar_depth_map(
    points_lidar: ArrayLike,
    T_cam_lidar: ArrayLike,
    camera: CameraModel,
    spec: LidarSpec | None = None,
    method: str | Occlusion = "ordering",
    max_depth: float = 120.0,
    mirror: bool = False,
    rings: ArrayLike | None = None,
    **options: Any,
) -> ArrayLike:
    """Sparse LiDAR range map ``[H, W]`` (float32 metres from the camera centre, 0 = no point).

    Visible points (see :func:`occlusion_mask`) within ``max_depth`` are written to their nearest pixel; where
    several land on one pixel the nearest wins (an exact min-reduction, independent of the points' order).
    ``mirror`` writes each point at its mirror image about the principal point's column, ``u -> 2 cx - u``: the
    horizontal-flip augmentation applied to the points themselves, exact for any ``cx`` (a flip of the finished
    map about the frame's centre is not, unless ``cx = (W - 1) / 2``). Visibility is decided before mirroring: a
    mirror moves the image, not the scene.

    Example:
        >>> import numpy as np
        >>> from airfisheye_bench.geometry import ideal_camera, CAM_FROM_FLU, make_transform
        >>> T = make_transform(CAM_FROM_FLU, np.zeros(3))
        >>> pts = np.array([[7.0, 0.0, 0.0], [5.0, 0.0, 0.0], [200.0, 50.0, 0.0]])
        >>> depth = lidar_depth_map(pts, T, ideal_camera(64, 64), method="none")
        >>> depth.shape, float(depth.max()), int((depth > 0).sum())  # nearest of the two; 200 m is too far
        ((64, 64), 5.0, 1)
    """
    if not (isinstance(max_depth, (int, float)) and math.isfinite(max_depth) and max_depth > 0):
        raise ValueError(f"max_depth must be a positive number of metres, got {max_depth!r}")
    uv, rng, mask = project_lidar(points_lidar, T_cam_lidar, camera, spec, method, rings, **options)
    if isinstance(mask, torch.Tensor):
        uv, rng, mask = uv.cpu().numpy(), rng.cpu().numpy(), mask.cpu().numpy()
    keep = mask & (rng <= max_depth)
    if mirror:
        uv = uv.copy()  # project_lidar's array may be shared with the caller
        uv[:, 0] = 2.0 * camera.cx - uv[:, 0]
        # The frame's bounds as in project(): an off-centre cx mirrors some points past them.
        keep &= (uv[:, 0] >= -0.5) & (uv[:, 0] <= camera.width - 0.5)
    keep = np.flatnonzero(keep)
    depth = np.full(camera.height * camera.width, np.inf, dtype=np.float32)
    pix = pixel_index(np.take(uv, keep, axis=0), camera)
    numba_kernels.scatter_min(rng[keep].astype(np.float32), pix, depth)
    depth[np.isinf(depth)] = 0.0
    return like(depth.reshape(camera.height, camera.width), points_lidar)


def ordering_reference(
    points_lidar: ArrayLike,
    T_cam_lidar: ArrayLike,
    camera: CameraModel,
    spec: LidarSpec | None = None,
    rings: ArrayLike | None = None,
    **options: Any,
) -> ArrayLike:
    """The ordering method as a plain loop over the points, written to follow the text of III-C line by line.

    Slow (a Python loop); it exists to check the fast implementation (``method="ordering"``), which must
    return the same mask. Arguments as for :func:`occlusion_mask` with ``method="ordering"``.
    """
    return ordering_mask(points_lidar, T_cam_lidar, camera, spec, "loop", rings, **options)


def ordering_mask(
    points_lidar: ArrayLike,
    T_cam_lidar: ArrayLike,
    camera: CameraModel,
    spec: LidarSpec | None = None,
    implementation: str = "numba",
    rings: ArrayLike | None = None,
    **options: Any,
) -> ArrayLike:
    """The ``ordering`` mask computed by one of :data:`ORDERING_IMPLEMENTATIONS` (tests and benchmarks).

    ``"numba"`` is what :func:`occlusion_mask` runs, ``"vectorised"`` the numpy solver, ``"loop"`` the text of
    III-C line by line (:func:`ordering_reference`); all three return the same mask.

    Example:
        >>> import numpy as np
        >>> from airfisheye_bench.geometry import ideal_camera, CAM_FROM_FLU, make_transform
        >>> spec = LidarSpec(channels=8, points_per_channel=64)
        >>> wall = 10.0 * spec.beam_directions(torch.float64).reshape(-1, 3).numpy()
        >>> T = make_transform(CAM_FROM_FLU, np.array([0.0, 0.0, 0.3]))
        >>> masks = [ordering_mask(wall, T, ideal_camera(64, 64), spec, name) for name in ORDERING_IMPLEMENTATIONS]
        >>> all((m == masks[0]).all() for m in masks)
        True
    """
    if implementation not in ORDERING_IMPLEMENTATIONS:
        raise ValueError(
            f"implementation must be one of {sorted(ORDERING_IMPLEMENTATIONS)}, got {implementation!r}"
        )
    points = as_points64(points_lidar, "points_lidar")
    T = as_transform64(T_cam_lidar)
    if not isinstance(camera, CameraModel):
        raise ValueError(f"camera must be a CameraModel, got {type(camera).__name__}")
    spec = LidarSpec() if spec is None else spec
    if not isinstance(spec, LidarSpec):
        raise ValueError(f"spec must be a LidarSpec or None, got {type(spec).__name__}")
    opts = check_occlusion_options("ordering", options)
    ring = None if rings is None else check_rings(rings, len(points), spec)
    mask = solve_ordering(points, T, project_points(points, T, camera), spec, opts, implementation, ring)
    return like(mask, points_lidar)


def solve_ordering(
    points: np.ndarray,
    T: np.ndarray,
    proj: Projection,
    spec: LidarSpec,
    opts: dict[str, Any],
    implementation: str,
    rings: np.ndarray | None = None,
) -> np.ndarray:
    """Steps 1-4 of the ordering method on validated inputs; the mask over all points."""
    layout, solver = ORDERING_IMPLEMENTATIONS[implementation]
    prob = ordering_problem(points, T, proj, spec, layout, rings)
    tolerance = float(opts["elevation_tolerance"]) * spec.vertical_resolution
    keep = solver(prob, opts["azimuth_window"], opts["elevation_window"], tolerance)
    mask = np.zeros(len(points), dtype=bool)
    mask[prob.ids[keep]] = True
    return mask


#: name -> (step 1, step 4) of the ordering method; every one gives the same mask.
ORDERING_IMPLEMENTATIONS: dict[str, tuple[Layout, Solver]] = {
    "numba": (layout_numba, ordering_numba),
    "vectorised": (layout_from_angles, ordering_vectorised),
    "loop": (layout_from_angles, ordering_loop),
}

__all__ = [
    "ORDERING_IMPLEMENTATIONS",
    "LidarProjection",
    "lidar_depth_map",
    "occlusion_mask",
    "ordering_mask",
    "ordering_reference",
    "project_lidar",
]
