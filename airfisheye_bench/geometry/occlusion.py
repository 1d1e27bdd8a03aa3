"""LiDAR-to-fisheye projection with occlusion correction (paper, III-C) and its baselines (z-buffer, HPR).

The camera and the LiDAR sit at different places, so a LiDAR point can project into the image although the
camera cannot see it: something nearer *to the camera* hides it. :func:`occlusion_mask` tells, per point,
whether it projects into the image and is not occluded. Methods (options in :func:`occlusion_mask`):

``ordering``  The paper's algorithm (III-C), compiled (numba); :func:`ordering_reference` is the plain loop.
``zbuffer``   Per-pixel nearest range, then a window test: a point is dropped if the nearest range in the
              window around its pixel is nearer by more than a margin. By default the window is half the
              LiDAR's angular spacing (its vertical resolution), converted to pixels with the image scale
              at the point's pixel: the widest gap an occluder's samples leave in the image. The margin is
              relative: ``tan(max_incidence_deg)`` times the window's half-angle, the range change across
              the window of a surface seen at up to ``max_incidence_deg`` (87 deg) from its normal, so that
              ground and walls at grazing angles are not taken for occluders.
``hpr``       Hidden Point Removal (Katz, Tal, Basri 2007, "Direct visibility of point sets"): the points
              are flipped about a sphere centred on the camera, ``p -> p + 2 (R - |p|) p / |p|``, and a point
              is visible iff its image is a vertex of the convex hull of the flipped points and the camera
              centre (``scipy.spatial.ConvexHull``). ``R = radius * max |p|``: a larger ``radius`` keeps more
              points (it tolerates a steeper dip behind a nearer neighbour); the paper of Katz et al. takes
              ``R`` large against the scene. Default 1000, measured on the analytic scenes of
              ``scripts/bench_lidar.py`` (100: recall 0.89-0.97; 1000: 0.97-0.996 at precision >= 0.99;
              10000 keeps nearly every hidden point).
``none``      Projection only.

The ordering algorithm, step by step, with the interpretation decisions of this implementation:

1. Organise the scan into ``I_LiDAR`` (:func:`~airfisheye_bench.geometry.lidar.organize_scan`): row ``i``
   is ring ``i`` (the channel nearest the point's elevation), its points in ascending LiDAR azimuth;
   column ``j`` is the azimuth sector ``j`` of width ``HFOV / N_PC``. *Decided here*: the paper places
   every return in a cell of an ``N_C x N_PC`` matrix, which presumes that the beams sit on known azimuths.
   A real spinning LiDAR's beams have an arbitrary azimuth phase every frame (and per ring), jitter and
   dropped returns; binning them into cells either makes two returns collide in one cell (the loser would
   go untested: measured recall 0.59 with the beams on the cell edges, 0.94 with a random phase per ring and
   0.1-cell jitter, on a 64 x 2048 scan seen by a 512^2 fisheye) or needs the phase estimated. So each
   return keeps its own place along its row (its rank in azimuth: the row order is exactly the paper's
   "ascending order of theta from left to right"), and a column cell may hold zero, one or two returns of
   a ring. Every return of the sensor is tested, whatever the phase, jitter, dropouts and point order;
   only points no beam can have returned (at the origin, more than half a channel spacing outside the
   vertical FOV) are not, and are reported not visible. Returns outside a partial HFOV are organised in
   the sectors beyond it and tested too. *Decided here*: a 360 deg ring is a circle, but a row is a line;
   it is cut on the sector edge nearest the middle of the widest azimuth gap between the in-image returns
   (where the camera sees nothing), so that an occluder is compared with the points it hides wherever the
   sensor's +-180 deg lies.
2. ``I_proj``: the returns that project into the image (``camera.project`` valid). The others are left out,
   so points outside the image are neither tested nor hide anything.
3. Translate to the camera, do not rotate (the paper's second observation). ``(theta~, phi~)`` are the
   spherical angles of ``p - c``, with ``c = -R^T t`` the camera centre in the LiDAR frame: the point seen
   from the camera centre *along the LiDAR's axes*. Only in those axes do the azimuth/elevation orders agree
   with the column/row order of ``I_LiDAR`` when nothing is occluded (the camera's own axes measure angles
   about another pole, and the orders are unrelated). ``theta~`` is unwrapped to stay within pi of the
   point's LiDAR azimuth, so the +-180 deg seam cannot reorder a row. ``r~ = |p - c|`` is the range from the
   camera.
4. Visit the points by ascending ``r~`` (ties: lower point index first). ``theta_final``/``phi_final`` start
   empty (NaN); the nearest point is kept. A point at ``(i, j)`` is kept, and written into both matrices, iff
   (1) its ``theta~`` is strictly greater than every kept ``theta~`` in row ``i`` left of it and strictly
   smaller than every one right of it, and (2) its ``phi~`` is strictly greater than every kept ``phi~``
   below row ``i`` and strictly smaller than every one above it, in its column ``j``. Rejected points are
   not written, so they never block others ("fill ... with values of each non-occluded point").

   As in III-C: condition (1) spans the whole row, ``[0, j)`` and ``(j, end]`` (the text is explicit).
   Condition (2) is read column-wise: the text says "every entry below the i-th row", column ``j`` is the
   vertical counterpart of condition (1)'s row, and elevations in different columns have no order after the
   translation. Two returns of one ring in the same column are not compared by (2) (they are by (1)); a
   point above or below them must clear both.

   Options for what the text leaves open (it defers "other minor details" to code that is not public):

   * "within LiDAR vertical resolution (VFOV/(N_C-1))" read as a tolerance: ``elevation_tolerance = t`` (in
     vertical resolutions ``res``) rejects a point only if a kept entry below it has ``phi >= phi~ + t * res``
     (or one above has ``phi <= phi~ - t * res``). ``t > 0`` lets the order break by up to ``t`` rows;
     ``t < 0`` demands a clearance of ``|t|`` rows, so that a point just past an occluder's last sample (whose
     true edge lies up to a row further) is removed as well.
   * read as a neighbourhood: ``elevation_window`` (rows either side of ``i``); likewise ``azimuth_window``
     (places either side along the row, about one column each) narrows condition (1).

   The defaults are the literal reading (whole row, whole column, ``t = 0``). Measured on analytic box scenes
   (64 x 2048 scan, 1536^2 image; ``python scripts/bench_lidar.py --variants``): ``t = +1`` and narrow windows
   only keep more hidden points, at about the same recall; ``t = -0.25`` keeps 2.5-5x fewer hidden points when
   the camera is below or above the LiDAR, at the price of dropping some visible ones (fewer errors in all for
   a vertical or mixed camera offset, more for a purely sideways one).

Known limits of the ordering test: only points in the same row or column are compared, so a hidden point in
the unsampled band between an occluder's last sample and its true edge survives (mostly with a vertical camera
offset: rows are ~1 deg apart, columns ~0.13 deg), and so does a diagonal occlusion (camera offset sideways
*and* vertically, the occluder's corner crossing neither the point's row nor its column). A very near, thin
object (large parallax) removes the points between its LiDAR and its camera azimuth, even where they are
visible around it.

Three implementations of steps 1 and 4 return the same mask (the tests compare them):

* ``numba`` (used by :func:`occlusion_mask`): step 1 in O(N) (a counting sort into (ring, sector) buckets
  instead of a lexsort), step 4 as the sequential loop itself, made cheap by looking up only the *nearest*
  kept entry on each side (kept entries increase along a row / column; see ``_kernels.ordering_keep``).
  Angles (``np.arctan2``, a SIMD routine whose last bits a compiled ``atan2`` does not reproduce) and the
  visiting order (``np.argsort``) stay in numpy, shared with the other implementations, so all of them see
  the same inputs.
* ``vectorised`` (:class:`_OrderingSolver`, numpy): a point's fate depends only on *kept* nearer points that
  conflict with it (same row/column, order broken); most points conflict with none, and the few that do are
  resolved by splitting them by distance (see the class docstring). Kept as a cross-check and for the
  benchmark's old-vs-new comparison.
* ``loop`` (:func:`ordering_reference`): the text of III-C, line by line.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import torch

from airfisheye_bench.geometry import _kernels
from airfisheye_bench.geometry._arrays import ArrayLike
from airfisheye_bench.geometry.cameras import CameraModel as FisheyeCamera  # any model (old name)
from airfisheye_bench.geometry.lidar import (
    LidarSpec,
    ScanLayout,
    as_points64,
    column_range,
    layout_from_angles,
    like,
    spherical_coordinates,
)
from airfisheye_bench.geometry.transforms import check_rigid

OCCLUSION_METHODS = ("ordering", "zbuffer", "hpr", "none")

#: Every method's options and their defaults (see :func:`occlusion_mask`).
OCCLUSION_OPTIONS: dict[str, dict[str, Any]] = {
    "ordering": {"azimuth_window": None, "elevation_window": None, "elevation_tolerance": 0.0},
    "zbuffer": {"kernel": None, "threshold": None, "relative": True, "max_incidence_deg": 87.0},
    "hpr": {"radius": 1000.0},
    "none": {},
}


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
    camera: FisheyeCamera,
    spec: LidarSpec | None = None,
    method: str = "ordering",
    **options: Any,
) -> ArrayLike:
    """Which LiDAR points project into the image *and* are seen by the camera.

    Args:
        points_lidar: ``[N, 3]`` points in the LiDAR frame (numpy or torch, floating, finite).
        T_cam_lidar: ``[4, 4]`` rigid transform mapping LiDAR-frame points to the camera frame.
        camera: The fisheye camera.
        spec: The LiDAR that recorded the scan (used by ``ordering``); ``None`` means the paper's sensor,
            ``LidarSpec()``.
        method: ``"ordering"`` (paper, III-C), ``"zbuffer"``, ``"hpr"`` or ``"none"``; see the module
            docstring.
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

    Returns:
        ``bool [N]`` mask, numpy or torch like ``points_lidar``.

    Example:
        >>> import numpy as np
        >>> from airfisheye_bench.geometry import FisheyeCamera, CAM_FROM_FLU, make_transform
        >>> spec = LidarSpec(channels=16, points_per_channel=256)
        >>> wall = 10.0 * spec.beam_directions(torch.float64).reshape(-1, 3).numpy()  # a 10 m sphere
        >>> T = make_transform(CAM_FROM_FLU, np.zeros(3))  # camera at the LiDAR, looking along x
        >>> camera = FisheyeCamera(256, 256)
        >>> visible = occlusion_mask(wall, T, camera, spec)
        >>> in_view = occlusion_mask(wall, T, camera, spec, method="none")
        >>> bool(visible.any()), bool((visible == in_view).all())  # camera at the LiDAR: nothing hidden
        (True, True)
    """
    return project_lidar(points_lidar, T_cam_lidar, camera, spec, method, **options).mask


def project_lidar(
    points_lidar: ArrayLike,
    T_cam_lidar: ArrayLike,
    camera: FisheyeCamera,
    spec: LidarSpec | None = None,
    method: str = "ordering",
    **options: Any,
) -> LidarProjection:
    """Project a scan into the image: pixel coordinates, camera ranges and the visibility mask of every point.

    Arguments as for :func:`occlusion_mask`.

    Example:
        >>> import numpy as np
        >>> from airfisheye_bench.geometry import FisheyeCamera, CAM_FROM_FLU, make_transform
        >>> T = make_transform(CAM_FROM_FLU, np.zeros(3))
        >>> point = np.array([[5.0, 0.0, 0.0]])
        >>> uv, rng, mask = project_lidar(point, T, FisheyeCamera(64, 64), method="none")
        >>> uv.tolist(), rng.tolist(), mask.tolist()
        ([[31.5, 31.5]], [5.0], [True])
    """
    points = as_points64(points_lidar, "points_lidar")
    T = _as_transform64(T_cam_lidar)
    if not isinstance(camera, FisheyeCamera):
        raise ValueError(f"camera must be a FisheyeCamera, got {type(camera).__name__}")
    if spec is None:
        spec = LidarSpec()
    elif not isinstance(spec, LidarSpec):
        raise ValueError(f"spec must be a LidarSpec or None, got {type(spec).__name__}")
    opts = check_occlusion_options(method, options)

    proj = _project(points, T, camera)
    if method == "ordering":
        mask = _ordering_mask(points, T, proj, spec, opts, "numba")
    elif method == "zbuffer":
        mask = _zbuffer_mask(proj, camera, spec, **opts)
    elif method == "hpr":
        mask = _hpr_mask(points, T, proj, **opts)
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
    camera: FisheyeCamera,
    spec: LidarSpec | None = None,
    method: str = "ordering",
    max_depth: float = 120.0,
    mirror: bool = False,
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
        >>> from airfisheye_bench.geometry import FisheyeCamera, CAM_FROM_FLU, make_transform
        >>> T = make_transform(CAM_FROM_FLU, np.zeros(3))
        >>> pts = np.array([[7.0, 0.0, 0.0], [5.0, 0.0, 0.0], [200.0, 50.0, 0.0]])
        >>> depth = lidar_depth_map(pts, T, FisheyeCamera(64, 64), method="none")
        >>> depth.shape, float(depth.max()), int((depth > 0).sum())  # nearest of the two; 200 m is too far
        ((64, 64), 5.0, 1)
    """
    if not (isinstance(max_depth, (int, float)) and math.isfinite(max_depth) and max_depth > 0):
        raise ValueError(f"max_depth must be a positive number of metres, got {max_depth!r}")
    uv, rng, mask = project_lidar(points_lidar, T_cam_lidar, camera, spec, method, **options)
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
    pix = _pixel_index(np.take(uv, keep, axis=0), camera)
    _kernels.scatter_min(rng[keep].astype(np.float32), pix, depth)
    depth[np.isinf(depth)] = 0.0
    return like(depth.reshape(camera.height, camera.width), points_lidar)


def ordering_reference(
    points_lidar: ArrayLike,
    T_cam_lidar: ArrayLike,
    camera: FisheyeCamera,
    spec: LidarSpec | None = None,
    **options: Any,
) -> ArrayLike:
    """The ordering method as a plain loop over the points, written to follow the text of III-C line by line.

    Slow (a Python loop); it exists to check the fast implementation (``method="ordering"``), which must
    return the same mask. Arguments as for :func:`occlusion_mask` with ``method="ordering"``.
    """
    return _ordering(points_lidar, T_cam_lidar, camera, spec, "loop", **options)


def _ordering(
    points_lidar: ArrayLike,
    T_cam_lidar: ArrayLike,
    camera: FisheyeCamera,
    spec: LidarSpec | None,
    implementation: str,
    **options: Any,
) -> ArrayLike:
    """The ``ordering`` mask computed by one of :data:`_ORDERING_IMPLEMENTATIONS` (tests and benchmarks)."""
    if implementation not in _ORDERING_IMPLEMENTATIONS:
        raise ValueError(
            f"implementation must be one of {sorted(_ORDERING_IMPLEMENTATIONS)}, got {implementation!r}"
        )
    points = as_points64(points_lidar, "points_lidar")
    T = _as_transform64(T_cam_lidar)
    if not isinstance(camera, FisheyeCamera):
        raise ValueError(f"camera must be a FisheyeCamera, got {type(camera).__name__}")
    spec = LidarSpec() if spec is None else spec
    if not isinstance(spec, LidarSpec):
        raise ValueError(f"spec must be a LidarSpec or None, got {type(spec).__name__}")
    opts = check_occlusion_options("ordering", options)
    mask = _ordering_mask(points, T, _project(points, T, camera), spec, opts, implementation)
    return like(mask, points_lidar)


# ---------------------------------------------------------------------------------------------- shared steps
def _as_transform64(T: Any, name: str = "T_cam_lidar") -> np.ndarray:
    if not isinstance(T, (np.ndarray, torch.Tensor)):
        raise ValueError(f"{name} must be a 4x4 numpy array or torch tensor, got {type(T).__name__}")
    if tuple(T.shape) != (4, 4):
        raise ValueError(f"{name} must have shape [4, 4], got {tuple(T.shape)}")
    if isinstance(T, torch.Tensor):
        T = T.detach().to("cpu", torch.float64).numpy()
    elif not np.issubdtype(T.dtype, np.number) or np.issubdtype(T.dtype, np.complexfloating):
        raise ValueError(f"{name} must be real-valued, got dtype {T.dtype}")
    T = np.asarray(T, dtype=np.float64)
    check_rigid(T, name)
    return T


def check_occlusion_options(method: str, options: dict[str, Any]) -> dict[str, Any]:
    """Validate ``options`` for ``method``; returns them completed with the defaults.

    Raises:
        ValueError: naming the unknown method, the unknown option(s) and the allowed ones, or the option
            with a bad value and what was expected.

    Example:
        >>> check_occlusion_options("hpr", {"radius": 100})
        {'radius': 100}
        >>> check_occlusion_options("zbuffer", {"size": 3})
        Traceback (most recent call last):
        ...
        ValueError: unknown option(s) ['size'] for method 'zbuffer'; allowed: ['kernel', ...]
    """
    if method not in OCCLUSION_METHODS:
        raise ValueError(f"method must be one of {OCCLUSION_METHODS}, got {method!r}")
    allowed = OCCLUSION_OPTIONS[method]
    unknown = set(options) - set(allowed)
    if unknown:
        raise ValueError(
            f"unknown option(s) {sorted(unknown)} for method {method!r}; allowed: {sorted(allowed)}"
        )
    opts = {**allowed, **options}
    for name in ("azimuth_window", "elevation_window"):
        if name in opts and opts[name] is not None and not (_is_int(opts[name]) and opts[name] >= 0):
            raise ValueError(f"{name} must be None or a non-negative integer, got {opts[name]!r}")
    if "elevation_tolerance" in opts and not _is_real(opts["elevation_tolerance"]):
        raise ValueError(f"elevation_tolerance must be a finite number, got {opts['elevation_tolerance']!r}")
    if "kernel" in opts and not (
        opts["kernel"] is None
        or (_is_int(opts["kernel"]) and opts["kernel"] >= 1 and opts["kernel"] % 2 == 1)
    ):
        raise ValueError(f"kernel must be None or a positive odd integer, got {opts['kernel']!r}")
    if "threshold" in opts and not (opts["threshold"] is None or _is_nonneg(opts["threshold"])):
        raise ValueError(f"threshold must be None or a non-negative number, got {opts['threshold']!r}")
    if "max_incidence_deg" in opts and not (
        _is_real(opts["max_incidence_deg"]) and 0 <= opts["max_incidence_deg"] < 90
    ):
        raise ValueError(f"max_incidence_deg must be a number in [0, 90), got {opts['max_incidence_deg']!r}")
    if "radius" in opts and not (_is_real(opts["radius"]) and opts["radius"] > 1):
        raise ValueError(
            f"radius must be a number > 1 (a multiple of the farthest point's range), got {opts['radius']!r}"
        )
    if "relative" in opts and not isinstance(opts["relative"], bool):
        raise ValueError(f"relative must be a bool, got {opts['relative']!r}")
    if method == "zbuffer" and opts["threshold"] is None and not opts["relative"]:
        raise ValueError(
            "relative=False needs a threshold in metres (threshold=None derives a relative margin)"
        )
    return opts


def _is_int(x: Any) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def _is_real(x: Any) -> bool:
    return (
        isinstance(x, (int, float, np.floating, np.integer)) and not isinstance(x, bool) and math.isfinite(x)
    )


def _is_nonneg(x: Any) -> bool:
    return _is_real(x) and x >= 0


@dataclass
class _Projection:
    uv: np.ndarray  # [N, 2] float64
    range: np.ndarray  # [N] distance from the camera centre
    valid: np.ndarray  # [N] projects into the image


def _project(points: np.ndarray, T: np.ndarray, camera: FisheyeCamera) -> _Projection:
    if len(points) == 0:
        return _Projection(np.empty((0, 2)), np.empty(0), np.empty(0, dtype=bool))
    # Camera-frame coordinates as contiguous rows [3, N], written out per coordinate: numpy's matmul of an
    # [N, 3] by a 3 x 3 matrix is ~50x slower than three matrix-vector products. Rows keep the element-wise
    # maths below (and in camera.project, which gets the transposed view) on contiguous vectors.
    x, y, z = (points @ T[k, :3] + T[k, 3] for k in range(3))
    uv, valid = camera.project(np.stack([x, y, z]).T)
    valid &= camera.in_image(uv)  # project() answers for the lens; the image bounds are the caller's
    rng = x * x
    rng += y * y
    rng += z * z
    return _Projection(np.asarray(uv), np.sqrt(rng, out=rng), np.asarray(valid))


def _pixel_index(uv: np.ndarray, camera: FisheyeCamera) -> np.ndarray:
    """Flat index of the pixel whose centre is nearest to ``uv`` (pixel centres at integer ``u, v``)."""
    col = np.clip(np.rint(uv[:, 0]), 0, camera.width - 1).astype(np.int64)
    row = np.clip(np.rint(uv[:, 1]), 0, camera.height - 1).astype(np.int64)
    return row * camera.width + col


# ---------------------------------------------------------------------------------------------- z-buffer
@functools.lru_cache(maxsize=4)  # a few cameras at a time (the served one, a benchmark's sizes)
def _pixels_per_radian(camera: FisheyeCamera) -> np.ndarray:
    """Image scale ``[H * W]`` (float32, pixels per radian) at every pixel: the camera model's largest local
    scale (``CameraModel.pixels_per_radian``; for a radial lens the larger of ``f r'(theta)`` and
    ``f r(theta) / sin(theta)``)."""
    return camera.pixels_per_radian().reshape(-1).to(torch.float32).numpy()


def _zbuffer_mask(
    proj: _Projection,
    camera: FisheyeCamera,
    spec: LidarSpec,
    kernel: int | None,
    threshold: float | None,
    relative: bool,
    max_incidence_deg: float,
) -> np.ndarray:
    ids = np.flatnonzero(proj.valid)
    pix = _pixel_index(np.take(proj.uv, ids, axis=0), camera)
    rng = proj.range[ids].astype(np.float32)
    depth = np.full(camera.height * camera.width, np.inf, dtype=np.float32)
    _kernels.scatter_min(rng, pix, depth)  # per-pixel nearest
    scale = _pixels_per_radian(camera)[pix]
    if kernel is None:  # half the LiDAR's angular spacing, in pixels at each point's pixel
        spacing = max(spec.vertical_resolution, spec.horizontal_resolution)
        radius = np.rint(0.5 * spacing * scale).astype(np.int64)
    else:
        radius = np.full(len(ids), kernel // 2, dtype=np.int64)
    if threshold is None:  # a surface up to the grazing incidence, across the window's half-angle
        slope = math.tan(math.radians(max_incidence_deg))
        margin = (slope * (radius + 0.5) / scale).astype(np.float32)
    else:
        margin = np.full(len(ids), threshold, dtype=np.float32)
    keep = np.empty(len(ids), dtype=bool)
    _kernels.zbuffer_keep(depth, camera.width, pix, rng, radius, relative, margin, keep)
    mask = np.zeros(len(proj.valid), dtype=bool)
    mask[ids] = keep
    return mask


# ---------------------------------------------------------------------------------------------- HPR
def _hpr_mask(points: np.ndarray, T: np.ndarray, proj: _Projection, radius: float) -> np.ndarray:
    """Hidden Point Removal (Katz, Tal, Basri 2007) on the points that project into the image."""
    from scipy.spatial import ConvexHull, QhullError  # imported here: only this method needs scipy

    ids = np.flatnonzero(proj.valid & (proj.range > 0))
    mask = np.zeros(len(points), dtype=bool)
    if len(ids) < 4:  # no 3-D hull: nothing can hide anything
        mask[ids] = True
        return mask
    p = np.take(points, ids, axis=0) - (-T[:3, :3].T @ T[:3, 3])  # relative to the camera centre
    norm = proj.range[ids, None]
    # Spherical flipping about a sphere of radius R around the viewpoint: p -> p + 2 (R - |p|) p / |p|.
    flipped = p * ((2.0 * radius * norm.max()) / norm - 1.0)
    try:
        hull = ConvexHull(np.concatenate([flipped, np.zeros((1, 3))]))
    except QhullError:  # degenerate (coplanar) input: no point is behind another
        mask[ids] = True
        return mask
    vertices = hull.vertices[hull.vertices < len(ids)]
    mask[ids[vertices]] = True
    return mask


# ---------------------------------------------------------------------------------------------- ordering
@dataclass
class _OrderingProblem:
    """The points of ``I_proj`` in visiting order (ascending camera range), with their places and angles."""

    ids: np.ndarray  # point indices
    row: np.ndarray  # ring
    pos: np.ndarray  # place along the ring (rank in LiDAR azimuth)
    col: np.ndarray  # azimuth sector, shifted to start at 0
    theta: np.ndarray  # theta~: azimuth seen from the camera centre in the LiDAR's axes (unwrapped)
    phi: np.ndarray  # phi~: elevation seen from the camera centre in the LiDAR's axes
    shape: tuple[int, int, int]  # (rows N_C, places per row, columns)


_Layout = Callable[[np.ndarray, np.ndarray, np.ndarray, LidarSpec], ScanLayout]
_Solver = Callable[[_OrderingProblem, int | None, int | None, float], np.ndarray]


def _ordering_mask(
    points: np.ndarray,
    T: np.ndarray,
    proj: _Projection,
    spec: LidarSpec,
    opts: dict[str, Any],
    implementation: str,
) -> np.ndarray:
    layout, solver = _ORDERING_IMPLEMENTATIONS[implementation]
    prob = _ordering_problem(points, T, proj, spec, layout)
    tolerance = float(opts["elevation_tolerance"]) * spec.vertical_resolution
    keep = solver(prob, opts["azimuth_window"], opts["elevation_window"], tolerance)
    mask = np.zeros(len(points), dtype=bool)
    mask[prob.ids[keep]] = True
    return mask


def _ordering_problem(
    points: np.ndarray, T: np.ndarray, proj: _Projection, spec: LidarSpec, layout: _Layout
) -> _OrderingProblem:
    # Steps 1-2: I_LiDAR, then I_proj (the returns that project into the image).
    r, az, el = spherical_coordinates(points)
    cut = _widest_gap(az, proj.valid, spec.horizontal_resolution) if spec.hfov_deg == 360.0 else None
    if cut is not None:
        az = _turn(az, cut)
    ring, position, column = layout(r, az, el, spec)
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
        az_cam = _turn(az_cam, cut)
    # theta = az + (remainder(az_cam - az + pi, 2 pi) - pi), the same operations in place
    theta = np.subtract(az_cam, az, out=az_cam)
    theta += math.pi
    np.remainder(theta, 2.0 * math.pi, out=theta)
    theta -= math.pi
    theta += az
    first_col, n_cols = column_range(spec)
    row_len = int(position.max()) + 1 if len(position) else 0
    return _OrderingProblem(
        ids,
        ring[ids],
        position[ids],
        column[ids] - first_col,
        theta,
        el_cam,
        (spec.channels, row_len, n_cols),
    )


def _widest_gap(az: np.ndarray, in_image: np.ndarray, sector: float) -> float | None:
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


def _turn(az: np.ndarray, cut: float) -> np.ndarray:
    """Azimuths measured so that ``cut`` falls on -pi (the start of every row)."""
    return np.remainder(az - cut, 2.0 * math.pi) - math.pi


def _layout_numba(r: np.ndarray, az: np.ndarray, el: np.ndarray, spec: LidarSpec) -> ScanLayout:
    """:func:`~airfisheye_bench.geometry.lidar.layout_from_angles` in O(N), compiled (the same result)."""
    n = len(r)
    ring, position, column = (np.empty(n, dtype=np.int64) for _ in range(3))
    first_col, n_cols = column_range(spec)
    wrap_last = spec.points_per_channel - 1 if spec.hfov_deg == 360.0 else -1
    _kernels.lidar_layout(
        r,
        az,
        el,
        math.radians(spec.vfov_deg[0]),
        spec.vertical_resolution,
        -math.radians(spec.hfov_deg) / 2.0,
        spec.horizontal_resolution,
        spec.channels,
        wrap_last,
        first_col,
        n_cols,
        ring,
        position,
        column,
    )
    return ScanLayout(ring, position, column)


def _ordering_numba(prob: _OrderingProblem, aw: int | None, ew: int | None, tol: float) -> np.ndarray:
    """Step 4 of III-C as one compiled sequential loop; the same result as :func:`_ordering_loop`."""
    n_c, row_len, n_cols = prob.shape
    keep = np.empty(len(prob.ids), dtype=bool)
    az_win = row_len if aw is None else min(aw, row_len)
    el_win = n_c if ew is None else min(ew, n_c)
    _kernels.ordering_keep(
        prob.row, prob.pos, prob.col, prob.theta, prob.phi, n_c, row_len, n_cols, az_win, el_win, tol, keep
    )
    return keep


def _ordering_loop(prob: _OrderingProblem, aw: int | None, ew: int | None, tol: float) -> np.ndarray:
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


def _ordering_vectorised(prob: _OrderingProblem, aw: int | None, ew: int | None, tol: float) -> np.ndarray:
    """Step 4 of III-C, vectorised; returns exactly what :func:`_ordering_loop` returns."""
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
    """Vectorised step 4 of III-C, exactly equal to :func:`_ordering_loop`.

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

    def __init__(self, prob: _OrderingProblem, aw: int | None, ew: int | None, tol: float) -> None:
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


#: name -> (step 1, step 4); every one gives the same mask.
_ORDERING_IMPLEMENTATIONS: dict[str, tuple[_Layout, _Solver]] = {
    "numba": (_layout_numba, _ordering_numba),
    "vectorised": (layout_from_angles, _ordering_vectorised),
    "loop": (layout_from_angles, _ordering_loop),
}

__all__ = [
    "OCCLUSION_METHODS",
    "OCCLUSION_OPTIONS",
    "LidarProjection",
    "check_occlusion_options",
    "lidar_depth_map",
    "occlusion_mask",
    "ordering_reference",
    "project_lidar",
]
