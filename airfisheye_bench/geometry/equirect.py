"""Equirectangular (ERP) panoramas: their axis convention and their remap to any camera (docs/design.md,
"Equirectangular panoramas"). The one place for ERP geometry.

Convention
----------
A panorama of ``H`` rows and ``W`` columns (usually ``W = 2 H``) covers the whole sphere around its centre. Its
frame has OpenCV camera axes (x right, y down, z forward), like every camera frame of the project:

- **longitude** ``lon`` in ``[-pi, pi)``: the azimuth about the panorama's down axis (``-y``), 0 straight ahead
  (``+z``), increasing to the right (``+x`` at ``pi/2``); ``-pi`` (= ``+pi``) is straight behind (``-z``);
- **latitude** ``lat`` in ``[-pi/2, pi/2]``: the elevation above the ``x-z`` plane, ``+pi/2`` straight up (``-y``);
- direction ``d = (cos(lat) sin(lon), -sin(lat), cos(lat) cos(lon))``.

Pixels follow the project's convention (the centre of pixel (row i, col j) is at ``(u, v) = (j, i)``; the image
spans ``[-0.5, W - 0.5] x [-0.5, H - 0.5]``), and the image is seen from inside the sphere, as a photograph:

- ``lon = 2 pi (u + 0.5) / W - pi``: the left edge ``u = -0.5`` is straight behind, columns increase to the right
  (the left quarter looks back-left, ``u = W/4 - 0.5`` looks left, the middle ``u = W/2 - 0.5`` ahead (azimuth 0
  is the edge between columns ``W/2 - 1`` and ``W/2``), ``u = 3W/4 - 0.5`` right), and the right edge wraps back
  onto the left one;
- ``lat = pi/2 - pi (v + 0.5) / H``: the top edge ``v = -0.5`` is the up pole, the bottom edge the down pole; no
  pixel centre lies on a pole.

A panorama whose middle column looks along the body's forward axis and whose top is the body's up has
``R_pano_body = CAM_FROM_FLU`` (``geometry/transforms.py``).

Remap
-----
:class:`EquirectToFisheye` maps a panorama to any camera of ``CAMERA_MODELS`` (fisheye, pinhole, ...), at any
orientation of that camera in the panorama's frame (``rotation = R_pano_cam``;
:func:`~airfisheye_bench.geometry.transforms.gimbal_rotation` builds one from gimbal angles), with the lookup-table
mechanism of the cube remap (:mod:`~airfisheye_bench.geometry.remap_table`: the same :class:`RemapTable`, the same
process LRU and on-disk cache, keyed by the panorama's size, the camera's ``key()``, the rotation, the mode and the
supersampling):

- ``bilinear`` (images): four taps around the ray's continuous pixel; columns wrap across the +-180 deg seam, and a
  tap above the first row (below the last) is the texel across the pole: the same row, half a turn away
  (``col + W // 2``; exact for an even ``W``);
- ``nearest`` (labels, depth): the texel containing the ray, values copied exactly; depth is never interpolated
  across an edge, as on the cube path.

Depth is the project's depth, *range* along the ray from the panorama's centre (ERP datasets store range): the remap
serves it unchanged, as the cube path serves its faces' range. :func:`range_to_z_depth` and
:func:`z_depth_to_range` convert a map to planar depth along a camera's optical axis and back.

Public API (stable): :func:`lonlat_to_direction`, :func:`direction_to_lonlat`, :func:`direction_to_erp`,
:func:`erp_rays`, :class:`EquirectToFisheye` (``table``, ``valid_mask``, ``remap`` / ``__call__``),
:func:`range_to_z_depth`, :func:`z_depth_to_range`; tables are forgotten with
:func:`~airfisheye_bench.geometry.remap_table.clear_table_cache`.

Example:
    >>> from airfisheye_bench.geometry import ideal_camera
    >>> from airfisheye_bench.geometry.transforms import gimbal_rotation
    >>> erp = torch.rand(3, 64, 128)  # [C, H, W], channels first as the cube faces
    >>> remap = EquirectToFisheye(ideal_camera(48, 48), 64, rotation=gimbal_rotation(pitch_deg=30.0))
    >>> remap(erp).shape, remap(erp, mode="nearest", fill=255).shape
    (torch.Size([3, 48, 48]), torch.Size([3, 48, 48]))
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.geometry import portable
from airfisheye_bench.geometry._arrays import ArrayLike, as_tensor, back, check_last_dim
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.remap_table import (
    MODES,
    RemapTable,
    apply_table,
    check_rotation,
    filled_mask,
    interleaved_view,
    load_or_build,
    pack_table,
    rotation_key,
)

#: Interpolation modes, as the cube remap's.
ERP_MODES = MODES


def lonlat_to_direction(lon: ArrayLike, lat: ArrayLike) -> ArrayLike:
    """Unit directions ``[..., 3]`` (panorama frame) of longitudes and latitudes in radians.

    Example:
        >>> lonlat_to_direction(np.array([0.0, np.pi / 2]), np.array([0.0, 0.0])).round(6) + 0.0  # ahead, right
        array([[0., 0., 1.],
               [1., 0., 0.]])
    """
    lo, was_numpy = as_tensor(lon, "lon")
    la, _ = as_tensor(lat, "lat", dtype=lo.dtype)
    lo, la = torch.broadcast_tensors(lo, la)
    d = torch.stack([la.cos() * lo.sin(), -la.sin(), la.cos() * lo.cos()], -1)
    return back(d, was_numpy)


def direction_to_lonlat(directions: ArrayLike) -> tuple[ArrayLike, ArrayLike]:
    """``(lon [...], lat [...])`` in radians of directions ``[..., 3]`` (any non-zero length) in the panorama frame.

    ``lon`` is in ``[-pi, pi]`` (``atan2``: straight behind may come out as either end), ``lat`` in
    ``[-pi/2, pi/2]``; both computed with ``atan2``, well conditioned at the poles.

    Example:
        >>> lon, lat = direction_to_lonlat(np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0]]))  # up, left
        >>> (np.degrees(lat).round(6) + 0.0).tolist(), (np.degrees(lon).round(6) + 0.0).tolist()
        ([90.0, 0.0], [0.0, -90.0])
    """
    d, was_numpy = as_tensor(directions, "directions")
    check_last_dim(d, 3, "directions")
    x, y, z = d.unbind(-1)
    lon = torch.atan2(x, z)
    lat = torch.atan2(-y, torch.hypot(x, z))
    return back(lon, was_numpy), back(lat, was_numpy)


def direction_to_erp(directions: torch.Tensor, height: int, width: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Continuous pixel coordinates ``(u [N], v [N])`` of panorama-frame directions ``[N, 3]`` on an
    ``height x width`` panorama: ``u`` in ``[-0.5, W - 0.5]`` (both ends straight behind), ``v`` in
    ``[-0.5, H - 0.5]``.

    Example:
        >>> u, v = direction_to_erp(torch.tensor([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]), 4, 8)
        >>> u.tolist(), v.tolist()  # ahead: between columns 3 and 4; right: column 5.5; both on the equator
        ([3.5, 5.5], [1.5, 1.5])
    """
    h, w = _check_erp_size((height, width))
    d = directions if directions.dtype in (torch.float32, torch.float64) else directions.to(torch.float64)
    lon, lat = direction_to_lonlat(d)
    u = (lon + math.pi) * (w / (2.0 * math.pi)) - 0.5
    v = (math.pi / 2.0 - lat) * (h / math.pi) - 0.5
    return u, v


def erp_rays(
    height: int, width: int, dtype: torch.dtype = torch.float32, device: torch.device | str | None = None
) -> torch.Tensor:
    """Unit rays through every pixel centre of an ``height x width`` panorama, ``[H, W, 3]`` (panorama frame).

    The same bits on every CPU (the sines and cosines of :mod:`~airfisheye_bench.geometry.portable`), so a generator
    may write what it casts along them.

    Example:
        >>> rays = erp_rays(2, 4)
        >>> rays.shape, bool(torch.allclose(rays.norm(dim=-1), torch.ones(2, 4)))
        (torch.Size([2, 4, 3]), True)
    """
    h, w = _check_erp_size((height, width))
    lon = (np.arange(w, dtype=np.float64) + 0.5) * (2.0 * math.pi / w) - math.pi
    lat = math.pi / 2.0 - (np.arange(h, dtype=np.float64) + 0.5) * (math.pi / h)
    sin_lon, cos_lon = portable.sin(lon)[None, :], portable.cos(lon)[None, :]
    sin_lat, cos_lat = portable.sin(lat)[:, None], portable.cos(lat)[:, None]
    rays = np.stack(np.broadcast_arrays(cos_lat * sin_lon, -sin_lat, cos_lat * cos_lon), -1)
    return torch.from_numpy(rays).to(dtype=dtype, device=device)


class EquirectToFisheye:
    """Remap an equirectangular panorama to a camera image with lookup tables built once and cached.

    Args:
        camera: The output camera (any :class:`~airfisheye_bench.geometry.cameras.CameraModel`: lens model, FOV and
            resolution).
        erp_size: The panorama's size: ``(height, width)``, or one ``height`` for ``width = 2 * height``.
        rotation: Optional orientation of the output camera in the panorama's frame, ``R_pano_cam`` (3x3: maps the
            camera's directions into the panorama's frame). ``None`` is the identity: the optical axis looks at
            longitude 0 on the equator, the image's up towards the up pole.
        supersample: ``k`` for ``k x k`` bilinear samples per output pixel in ``bilinear`` mode, averaged
            (antialiasing when the panorama is much finer than the output). ``nearest`` always takes the texel
            containing the pixel centre's ray.
        cache_dir: Optional directory for an on-disk cache of the tables (``erp-lut-<hash>.npz``), keyed by all
            parameters.

    Attributes:
        camera, erp_height, erp_width, rotation (``None`` or float64 3x3), supersample, cache_dir.

    Example:
        >>> from airfisheye_bench.geometry import ideal_camera
        >>> remap = EquirectToFisheye(ideal_camera(64, 64), (32, 64))
        >>> remap(np.zeros((1, 32, 64), np.float32), mode="nearest").shape  # numpy in, numpy out
        (1, 64, 64)
        >>> int(remap.valid_mask.sum()) == int(remap.camera.valid_mask().sum())  # the sphere has no gap
        True
    """

    def __init__(
        self,
        camera: CameraModel,
        erp_size: int | tuple[int, int],
        rotation: ArrayLike | None = None,
        supersample: int = 1,
        cache_dir: str | os.PathLike | None = None,
    ) -> None:
        if not isinstance(camera, CameraModel):
            raise ValueError(
                f"camera must be a CameraModel (ideal_camera(...), camera_from_dict(...)), got {type(camera).__name__}"
            )
        if isinstance(erp_size, (int, np.integer)) and not isinstance(erp_size, bool):
            erp_size = (int(erp_size), 2 * int(erp_size))
        self.erp_height, self.erp_width = _check_erp_size(erp_size)
        if isinstance(supersample, bool) or int(supersample) != supersample or supersample < 1:
            raise ValueError(f"supersample must be a positive integer, got {supersample}")
        self.camera = camera
        self.rotation = check_rotation(rotation)
        self.supersample = int(supersample)
        self.cache_dir = Path(cache_dir) if cache_dir is not None else None

    def table(self, mode: str) -> RemapTable:
        """The (cached) lookup table for ``mode``: indices into the flattened panorama ``[H * W]``."""
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        key = (
            "erp",
            self.erp_height,
            self.erp_width,
            self.camera.key(),
            rotation_key(self.rotation),
            mode,
            self.supersample if mode == "bilinear" else 1,
        )
        return load_or_build(key, "erp-lut", self.cache_dir, lambda: self._build(mode))

    @property
    def valid_mask(self) -> torch.Tensor:
        """``[H, W]`` bool: the pixels the remap fills (the camera's valid region: every ray meets the sphere)."""
        return filled_mask(self.table("nearest"), self.camera.height, self.camera.width)

    def remap(self, erp: ArrayLike, mode: str = "bilinear", fill: float = 0) -> ArrayLike:
        """Map a panorama ``[C, H, W]`` or ``[B, C, H, W]`` to the camera image ``[C, h, w]`` or ``[B, C, h, w]``.

        Args:
            erp: The panorama, numpy or torch, any real dtype. ``nearest`` copies values (labels, range depth);
                ``bilinear`` interpolates in float32 and rounds back for integer dtypes. Three channels stored
                channels-last (``torch.from_numpy(hwc).permute(2, 0, 1)``, no copy) are blended in place.
            mode: ``bilinear`` (images) or ``nearest`` (labels, depth).
            fill: Value for pixels outside the camera's valid region (255 for labels, 0 for depth).
        """
        x, was_numpy = _as_erp(erp, self.erp_height, self.erp_width)
        lut = self.table(mode)
        batch_shape, channels = x.shape[:-3], x.shape[-3]
        x4 = x.reshape(-1, channels, self.erp_height, self.erp_width)
        out = torch.full(
            (x4.shape[0], channels, self.camera.height * self.camera.width),
            fill,
            dtype=x.dtype,
            device=x.device,
        )
        apply_table(lambda: x4.reshape(x4.shape[0], channels, -1), interleaved_view(x4), lut, out)
        out = out.view(*batch_shape, channels, self.camera.height, self.camera.width)
        return out.numpy() if was_numpy else out

    __call__ = remap

    # ------------------------------------------------------------------ table construction
    def _directions(self, rays: torch.Tensor) -> torch.Tensor:
        """Camera-frame rays -> panorama-frame directions."""
        if self.rotation is None:
            return rays
        return rays @ torch.from_numpy(self.rotation).to(rays.dtype).T

    def _build(self, mode: str) -> RemapTable:
        cam, h, w = self.camera, self.erp_height, self.erp_width
        inside = cam.valid_mask().reshape(-1)
        pixels = inside.nonzero().squeeze(1)
        # float64: a 8192-column panorama's texel is 7.7e-4 rad, and the ray grid is float64 already.
        rays = cam.ray_grid(torch.float64).reshape(-1, 3)[inside]
        u, v = direction_to_erp(self._directions(rays), h, w)
        if mode == "nearest":
            col = torch.remainder((u + 0.5).floor().to(torch.int64), w)
            row = (v + 0.5).floor().clamp(0, h - 1).to(torch.int64)
            return pack_table(pixels, (row * w + col)[None], torch.ones(1, len(pixels)))
        k = self.supersample
        if k == 1:
            index, weight = _bilinear_taps(u, v, h, w)
            return pack_table(pixels, index, weight)
        offsets = (torch.arange(k, dtype=torch.float64) + 0.5) / k - 0.5
        uv = cam.pixel_grid().reshape(-1, 2)[pixels]
        indices, weights = [], []
        for dy in offsets.tolist():
            for dx in offsets.tolist():
                sub_rays = cam.unproject(uv + torch.tensor([dx, dy], dtype=torch.float64))
                # Sub-samples outside the valid region get no weight (the pixel is only partly inside).
                sub_inside = cam.project(sub_rays)[1] & torch.isfinite(sub_rays).all(-1)
                sub_rays = torch.where(sub_inside[:, None], sub_rays, rays)
                idx, wt = _bilinear_taps(*direction_to_erp(self._directions(sub_rays), h, w), h, w)
                indices.append(idx)
                weights.append(wt * sub_inside)
        weight = torch.cat(weights)
        weight = weight / weight.sum(0, keepdim=True).clamp_min(1e-12)
        return pack_table(pixels, torch.cat(indices), weight)


def _bilinear_taps(u: torch.Tensor, v: torch.Tensor, h: int, w: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Four bilinear taps ``([4, N] flat indices into [H * W], [4, N] float64 weights)`` per sample.

    Columns wrap (the +-180 deg seam); a row above the first or below the last is read across the pole: the
    mirrored row, half a turn away.
    """
    v = v.clamp(-0.5, h - 0.5)
    x0, y0 = u.floor(), v.floor()
    fx, fy = u - x0, v - y0
    x0, y0 = x0.to(torch.int64), y0.to(torch.int64)
    indices, weights = [], []
    for dx, dy, wt in (
        (0, 0, (1 - fx) * (1 - fy)),
        (1, 0, fx * (1 - fy)),
        (0, 1, (1 - fx) * fy),
        (1, 1, fx * fy),
    ):
        col, row = x0 + dx, y0 + dy
        above, below = row < 0, row > h - 1
        across = above | below
        row = torch.where(above, -1 - row, torch.where(below, 2 * h - 1 - row, row))
        col = torch.remainder(torch.where(across, col + w // 2, col), w)
        indices.append(row * w + col)
        weights.append(wt)
    return torch.stack(indices), torch.stack(weights)


def range_to_z_depth(depth: ArrayLike, rays: ArrayLike) -> ArrayLike:
    """Range maps ``[..., H, W]`` -> planar depth along the optical axis: ``range * ray_z`` for the unit rays
    ``[H, W, 3]`` of the camera (``camera.ray_grid()``); 0 where the range is 0, the ray is NaN, or it looks
    sideways or backwards (``ray_z <= 0``: no planar depth, e.g. beyond 90 deg in a fisheye).

    Example:
        >>> rays = torch.tensor([[[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [1.0, 0.0, 0.0]]])
        >>> range_to_z_depth(torch.tensor([[2.0, 5.0, 3.0]]), rays)
        tensor([[2., 4., 0.]])
    """
    d, was_numpy = as_tensor(depth, "depth")
    z = _ray_z(rays, d)
    return back(torch.where((z > 0) & (d > 0), d * z, 0.0).to(d.dtype), was_numpy)


def z_depth_to_range(depth: ArrayLike, rays: ArrayLike) -> ArrayLike:
    """Planar depth maps ``[..., H, W]`` -> range along the unit rays ``[H, W, 3]``: ``depth / ray_z``; 0 where the
    depth is 0 or the ray has no planar depth (``ray_z <= 0`` or NaN).

    Example:
        >>> rays = torch.tensor([[[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]]])
        >>> z_depth_to_range(torch.tensor([[2.0, 4.0]]), rays)
        tensor([[2., 5.]])
    """
    d, was_numpy = as_tensor(depth, "depth")
    z = _ray_z(rays, d)
    ok = (z > 0) & (d > 0)
    return back(torch.where(ok, d / torch.where(ok, z, 1.0), 0.0).to(d.dtype), was_numpy)


def _ray_z(rays: ArrayLike, depth: torch.Tensor) -> torch.Tensor:
    r, _ = as_tensor(rays, "rays", dtype=torch.float64)
    check_last_dim(r, 3, "rays")
    if depth.shape[-2:] != r.shape[:-1] or r.ndim != 3:
        raise ValueError(
            f"rays must be [H, W, 3] matching depth [..., H, W], got {tuple(r.shape)} and {tuple(depth.shape)}"
        )
    return r[..., 2].nan_to_num(0.0).to(device=depth.device, dtype=torch.float64)


def _as_erp(erp: ArrayLike, height: int, width: int) -> tuple[torch.Tensor, bool]:
    was_numpy = not isinstance(erp, torch.Tensor)
    x = torch.from_numpy(np.asarray(erp)) if was_numpy else erp
    if x.ndim not in (3, 4) or x.shape[-2:] != (height, width):
        raise ValueError(
            f"erp must have shape [C, {height}, {width}] or [B, C, {height}, {width}] (channels first), "
            f"got {tuple(x.shape)}"
        )
    if x.dtype == torch.bool:
        x = x.to(torch.uint8)
    return x, was_numpy


def _check_erp_size(size: object) -> tuple[int, int]:
    try:
        h, w = (int(s) for s in size)  # type: ignore[union-attr]
        ok = all(int(s) == s and not isinstance(s, bool) for s in size) and h >= 2 and w >= 2  # type: ignore[union-attr]
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"erp_size must be a height or (height, width), integers >= 2, got {size!r}")
    return h, w


__all__ = [
    "ERP_MODES",
    "EquirectToFisheye",
    "direction_to_erp",
    "direction_to_lonlat",
    "erp_rays",
    "lonlat_to_direction",
    "range_to_z_depth",
    "z_depth_to_range",
]
