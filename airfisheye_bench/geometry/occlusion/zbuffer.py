"""The z-buffer baseline: per-pixel nearest range, then a window test (docs/design.md, "LiDAR and occlusion")."""

from __future__ import annotations

import functools
import math

import numpy as np
import torch

from airfisheye_bench.geometry import numba_kernels
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.occlusion.projection import Projection, pixel_index


@functools.lru_cache(maxsize=4)  # a few cameras at a time (the served one, a benchmark's sizes)
def _pixels_per_radian(camera: CameraModel) -> np.ndarray:
    """Image scale ``[H * W]`` (float32, pixels per radian) at every pixel: the camera model's largest local
    scale (``CameraModel.pixels_per_radian``; for a radial lens the larger of ``f r'(theta)`` and
    ``f r(theta) / sin(theta)``)."""
    return camera.pixels_per_radian().reshape(-1).to(torch.float32).numpy()


def _window_radius(spec: LidarSpec, scale: np.ndarray) -> np.ndarray:
    """Half the LiDAR's angular spacing in pixels at an image scale (pixels per radian), rounded: the derived
    window's radius."""
    spacing = max(spec.vertical_resolution, spec.horizontal_resolution)
    return np.rint(0.5 * spacing * scale).astype(np.int64)


def derived_window_radius(camera: CameraModel, spec: LidarSpec) -> np.ndarray:
    """``int64 [H, W]``: the radius of the z-buffer's derived window (``kernel=None``) at every pixel.

    Example:
        >>> from airfisheye_bench.geometry import ideal_camera
        >>> r = derived_window_radius(ideal_camera(128, 128), LidarSpec())
        >>> r.shape, int(r.min()) >= 0
        ((128, 128), True)
    """
    return _window_radius(spec, _pixels_per_radian(camera)).reshape(camera.height, camera.width)


def zbuffer_mask(
    proj: Projection,
    camera: CameraModel,
    spec: LidarSpec,
    kernel: int | None,
    threshold: float | None,
    relative: bool,
    max_incidence_deg: float,
) -> np.ndarray:
    ids = np.flatnonzero(proj.valid)
    pix = pixel_index(np.take(proj.uv, ids, axis=0), camera)
    rng = proj.range[ids].astype(np.float32)
    depth = np.full(camera.height * camera.width, np.inf, dtype=np.float32)
    numba_kernels.scatter_min(rng, pix, depth)  # per-pixel nearest
    scale = _pixels_per_radian(camera)[pix]
    # kernel=None: half the LiDAR's angular spacing, in pixels at each point's pixel
    radius = _window_radius(spec, scale) if kernel is None else np.full(len(ids), kernel // 2, dtype=np.int64)
    if threshold is None:  # a surface up to the grazing incidence, across the window's half-angle
        slope = math.tan(math.radians(max_incidence_deg))
        margin = (slope * (radius + 0.5) / scale).astype(np.float32)
    else:
        margin = np.full(len(ids), threshold, dtype=np.float32)
    keep = np.empty(len(ids), dtype=bool)
    numba_kernels.zbuffer_keep(depth, camera.width, pix, rng, radius, relative, margin, keep)
    mask = np.zeros(len(proj.valid), dtype=bool)
    mask[ids] = keep
    return mask


__all__ = ["derived_window_radius", "zbuffer_mask"]
