"""Cubemap-to-fisheye remapping with cached lookup tables (paper, section III-B).

Five 90-degree pinhole faces share the camera origin (the back face is omitted). Each face is an OpenCV camera with
focal ``S/2`` and principal point ``((S-1)/2, (S-1)/2)``, oriented by ``R_cam_face`` (columns = the face's x, y, z
axes in the fisheye camera frame; docs/design.md):

=====  ===========  ======  ======
face   looks along  face x  face y
=====  ===========  ======  ======
front  +z           +x      +y
left   -x           +z      +y
right  +x           -z      +y
up     -y           +x      +z
down   +y           +x      -z
=====  ===========  ======  ======

Faces are stacked in the order :data:`FACE_NAMES` everywhere (``[5, C, S, S]``).

The lookup table is a *weighted gather*: for every output pixel inside the image circle, ``T`` flat indices into
the stacked faces ``[5 * S * S]`` and ``T`` weights (``T = 1`` for nearest, ``4`` for bilinear, ``4 k^2`` with
``k x k`` supersampling). Bilinear taps that fall off a face's edge are re-projected onto the neighbouring face,
which is what padding each face with its neighbours' edge texels does, so there are no seams at face borders.
On CPU a fused numba kernel applies the table in one pass; on other devices ``index_select`` does.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.geometry._arrays import ArrayLike
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.remap_table import (
    MODES,
    RemapTable,
    apply_table,
    check_rotation,
    clear_table_cache,
    filled_mask,
    interleaved_view,
    load_or_build,
    pack_table,
    rotation_key,
)

FACE_NAMES: tuple[str, ...] = ("front", "left", "right", "up", "down")

# Columns are the face's x, y, z axes expressed in the fisheye camera frame.
_FACE_AXES = {
    "front": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "left": ((0, 0, 1), (0, 1, 0), (-1, 0, 0)),
    "right": ((0, 0, -1), (0, 1, 0), (1, 0, 0)),
    "up": ((1, 0, 0), (0, 0, 1), (0, -1, 0)),
    "down": ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
}
_R_CAM_FACE = np.stack([np.array(_FACE_AXES[name], dtype=np.float64).T for name in FACE_NAMES])


def face_rotation(name: str) -> np.ndarray:
    """``R_cam_face`` (3x3) of the face called ``name``: maps face-frame directions to the camera frame.

    Example:
        >>> face_rotation("right") @ np.array([0.0, 0.0, 1.0])  # the right face looks along camera +x
        array([1., 0., 0.])
    """
    if name not in FACE_NAMES:
        raise ValueError(f"name must be one of {FACE_NAMES}, got {name!r}")
    return _R_CAM_FACE[FACE_NAMES.index(name)].copy()


def face_rays(
    face_size: int, dtype: torch.dtype = torch.float32, device: torch.device | str | None = None
) -> torch.Tensor:
    """Unit rays through the pixel centres of all five faces, in the camera frame: ``[5, S, S, 3]``.

    Example:
        >>> rays = face_rays(4)
        >>> rays.shape, bool(torch.allclose(rays.norm(dim=-1), torch.ones(5, 4, 4)))
        (torch.Size([5, 4, 4, 3]), True)
    """
    _check_face_size(face_size)
    s = int(face_size)
    coords = (torch.arange(s, dtype=torch.float64) - (s - 1) / 2.0) / (s / 2.0)
    y, x = torch.meshgrid(coords, coords, indexing="ij")
    d_face = torch.stack([x, y, torch.ones_like(x)], -1)
    d_face = d_face / d_face.norm(dim=-1, keepdim=True)
    rays = torch.einsum("kij,hwj->khwi", torch.from_numpy(_R_CAM_FACE), d_face)
    return rays.to(dtype=dtype, device=device)


def direction_to_face(
    directions: torch.Tensor, face_size: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Locate camera-frame directions ``[N, 3]`` on the cubemap.

    Returns:
        ``(face [N] int64, u [N], v [N])``: the face index in :data:`FACE_NAMES` order (``-1`` where the direction
        belongs to the omitted back face or is not a finite non-zero vector) and continuous pixel coordinates on
        that face (in the input's floating dtype).
    """
    d = directions if directions.dtype in (torch.float32, torch.float64) else directions.to(torch.float64)
    x, y, z = d.unbind(-1)
    ax, ay, az = x.abs(), y.abs(), z.abs()
    z_major = (az >= ax) & (az >= ay)
    x_major = ~z_major & (ax >= ay)
    face = torch.where(z_major, 0, torch.where(x_major, torch.where(x < 0, 1, 2), torch.where(y < 0, 3, 4)))
    # Face-frame coordinates R_cam_face^T d, written out per face (see the table in the module docstring).
    xf = torch.where(z_major, x, torch.where(x_major, torch.where(x < 0, z, -z), x))
    yf = torch.where(z_major | x_major, y, torch.where(y < 0, z, -z))
    zf = torch.where(z_major, z, torch.where(x_major, ax, ay))
    bad = (z_major & (z <= 0)) | ~torch.isfinite(d).all(-1) | (zf <= 0)
    half, centre = face_size / 2.0, (face_size - 1) / 2.0
    zf = torch.where(bad, 1.0, zf)
    return torch.where(bad, -1, face), xf / zf * half + centre, yf / zf * half + centre


class CubemapToFisheye:
    """Remap stacked cube faces to a fisheye image with lookup tables built once and cached.

    Args:
        camera: The output fisheye camera (lens model, FOV and resolution).
        face_size: Side ``S`` of the square cube faces, in pixels.
        supersample: ``k`` for ``k x k`` bilinear samples per output pixel in ``bilinear`` mode, averaged
            (antialiasing when the faces are much finer than the output). ``nearest`` always takes the texel
            nearest to the pixel centre's ray.
        cache_dir: Optional directory for an on-disk cache of the tables, keyed by all parameters.
        rotation: Optional orientation of the output camera relative to the cube, ``R_cube_cam`` (3x3: maps the
            output camera's directions into the cube's camera frame; ``geometry.transforms.gimbal_rotation`` builds
            one from gimbal angles). ``None`` is the identity: the output looks along the front face.

    Example:
        >>> from airfisheye_bench.geometry import ideal_camera
        >>> remap = CubemapToFisheye(ideal_camera(64, 64), face_size=32)
        >>> faces = torch.rand(5, 3, 32, 32)
        >>> remap(faces).shape, remap(faces, mode="nearest").shape
        (torch.Size([3, 64, 64]), torch.Size([3, 64, 64]))
        >>> int(remap.valid_mask.sum()) < 64 * 64  # the corners lie outside the image circle
        True
    """

    def __init__(
        self,
        camera: CameraModel,
        face_size: int,
        supersample: int = 1,
        cache_dir: str | os.PathLike | None = None,
        rotation: ArrayLike | None = None,
    ) -> None:
        if not isinstance(camera, CameraModel):
            raise ValueError(
                f"camera must be a CameraModel (ideal_camera(...), camera_from_dict(...)), got {type(camera).__name__}"
            )
        _check_face_size(face_size)
        if int(supersample) != supersample or supersample < 1:
            raise ValueError(f"supersample must be a positive integer, got {supersample}")
        self.camera = camera
        self.face_size = int(face_size)
        self.supersample = int(supersample)
        self.cache_dir = Path(cache_dir) if cache_dir is not None else None
        self.rotation = check_rotation(rotation)

    def table(self, mode: str) -> RemapTable:
        """The (cached) lookup table for ``mode``."""
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        key = (self.camera.key(), self.face_size, mode, self.supersample if mode == "bilinear" else 1)
        rot = rotation_key(self.rotation)
        if rot is not None:  # an unrotated table keeps the key (and disk name) it always had
            key = (*key, rot)
        return load_or_build(key, "cubemap-lut", self.cache_dir, lambda: self._build(mode))

    @property
    def valid_mask(self) -> torch.Tensor:
        """``[H, W]`` bool: inside the FOV and landing on one of the five faces."""
        return filled_mask(self.table("nearest"), self.camera.height, self.camera.width)

    def remap(self, faces: ArrayLike, mode: str = "bilinear", fill: float = 0) -> ArrayLike:
        """Map stacked faces ``[5, C, S, S]`` or ``[B, 5, C, S, S]`` to ``[C, H, W]`` or ``[B, C, H, W]``.

        Args:
            faces: Faces in :data:`FACE_NAMES` order; numpy or torch, any real dtype. ``nearest`` copies values
                (use it for labels and depth); ``bilinear`` interpolates in float32 and rounds back for integer dtypes.
            mode: ``bilinear`` (images) or ``nearest`` (labels, depth).
            fill: Value for pixels outside the FOV or on the missing back face (255 for labels, 0 for depth).
        """
        x, was_numpy = _as_faces(faces, self.face_size)
        lut = self.table(mode)
        batch_shape, channels = x.shape[:-4], x.shape[-3]
        faces5 = x.reshape(-1, 5, channels, self.face_size, self.face_size)
        size = (faces5.shape[0], channels, self.camera.height * self.camera.width)
        out = torch.full(size, fill, dtype=x.dtype, device=x.device)
        # Three-channel faces stored channels-last (torch.from_numpy(hwc).permute(0, 3, 1, 2), no copy) are blended
        # in place by the interleaved kernel.
        apply_table(lambda: _planar(faces5), interleaved_view(faces5.transpose(1, 2)), lut, out)
        out = out.view(*batch_shape, channels, self.camera.height, self.camera.width)
        return out.numpy() if was_numpy else out

    __call__ = remap

    # ------------------------------------------------------------------ table construction
    def _build(self, mode: str) -> RemapTable:
        cam, s = self.camera, self.face_size
        inside = cam.valid_mask().reshape(-1)
        # float32 locates a texel to ~1e-4 px even on 2048^2 faces; the camera model itself ran in float64.
        rays = cam.ray_grid(torch.float32).reshape(-1, 3)[inside]
        if self.rotation is not None:
            rays = rays @ torch.from_numpy(self.rotation).to(rays.dtype).T
        face, u, v = direction_to_face(rays, s)
        on_face = face >= 0
        pixels = inside.nonzero().squeeze(1)[on_face]
        if mode == "nearest":
            index = _flat_index(
                face[on_face], v[on_face].round().clamp(0, s - 1), u[on_face].round().clamp(0, s - 1), s
            )
            return pack_table(pixels, index[None], torch.ones(1, len(pixels)))
        k = self.supersample
        if k == 1:
            index, weight = _bilinear_taps(face[on_face], u[on_face], v[on_face], s)
            return pack_table(pixels, index, weight)
        offsets = (torch.arange(k, dtype=torch.float64) + 0.5) / k - 0.5
        uv = cam.pixel_grid().reshape(-1, 2)[pixels]
        indices, weights = [], []
        for dy in offsets.tolist():
            for dx in offsets.tolist():
                sub_rays = cam.unproject(uv + torch.tensor([dx, dy], dtype=torch.float64))
                # Sub-samples outside the valid region get no weight (the pixel is only partly inside).
                sub_inside = cam.project(sub_rays)[1] & torch.isfinite(sub_rays).all(-1)
                sub_rays = sub_rays.nan_to_num(0.0, 0.0, 0.0)
                if self.rotation is not None:
                    sub_rays = sub_rays @ torch.from_numpy(self.rotation).T
                idx, w = _bilinear_taps(*direction_to_face(sub_rays, s), s)
                indices.append(idx)
                weights.append(w * sub_inside)
        weight = torch.cat(weights)
        weight = weight / weight.sum(0, keepdim=True).clamp_min(1e-12)
        return pack_table(pixels, torch.cat(indices), weight)


def _bilinear_taps(
    face: torch.Tensor, u: torch.Tensor, v: torch.Tensor, s: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """Four bilinear taps ``([4, N] flat indices into the stacked faces, [4, N] float64 weights)`` per sample.

    A tap off the face's edge is the texel centre on the face's extended image plane; its direction falls on a
    neighbouring face, whose nearest texel is used. A tap that would land on the missing back face (or a sample on
    no face) gets no weight; the remaining weights are renormalised.
    """
    x0, y0 = u.floor(), v.floor()
    fx, fy = u - x0, v - y0
    half, centre = s / 2.0, (s - 1) / 2.0
    on_face = face >= 0
    base = face.clamp_min(0) * (s * s)
    corners = (
        (x0, y0, (1 - fx) * (1 - fy)),
        (x0 + 1, y0, fx * (1 - fy)),
        (x0, y0 + 1, (1 - fx) * fy),
        (x0 + 1, y0 + 1, fx * fy),
    )
    indices, weights = [], []
    for cx, cy, w in corners:
        index = base + cy.clamp(0, s - 1).to(torch.int64) * s + cx.clamp(0, s - 1).to(torch.int64)
        w = torch.where(on_face, w, 0.0)
        # Only taps in the one-texel border band leave their face: re-project just those.
        off = ((cx < 0) | (cx > s - 1) | (cy < 0) | (cy > s - 1)) & on_face
        if off.any():
            sel = off.nonzero().squeeze(1)
            d_face = torch.stack(
                [(cx[sel] - centre) / half, (cy[sel] - centre) / half, torch.ones(len(sel), dtype=cx.dtype)],
                -1,
            )
            rot = torch.from_numpy(_R_CAM_FACE).to(d_face.dtype)
            d_cam = torch.einsum("nij,nj->ni", rot[face[sel]], d_face)
            nf, nu, nv = direction_to_face(d_cam, s)
            index[sel] = _flat_index(
                nf.clamp_min(0), nv.round().clamp(0, s - 1), nu.round().clamp(0, s - 1), s
            )
            w[sel] = torch.where(nf < 0, 0.0, w[sel])
        indices.append(index)
        weights.append(w)
    weight = torch.stack(weights)
    return torch.stack(indices), weight / weight.sum(0, keepdim=True).clamp_min(1e-12)


def _planar(faces: torch.Tensor) -> torch.Tensor:
    """``[B, 5, C, S, S]`` -> ``[B, C, 5 * S * S]`` (a copy of contiguous blocks, no element shuffling)."""
    b, _, c, s, _ = faces.shape
    return faces.transpose(1, 2).reshape(b, c, 5 * s * s)


def _flat_index(face: torch.Tensor, row: torch.Tensor, col: torch.Tensor, s: int) -> torch.Tensor:
    return face * (s * s) + row.to(torch.int64) * s + col.to(torch.int64)


def _as_faces(faces: ArrayLike, face_size: int) -> tuple[torch.Tensor, bool]:
    was_numpy = not isinstance(faces, torch.Tensor)
    x = torch.from_numpy(np.ascontiguousarray(faces)) if was_numpy else faces
    if x.ndim not in (4, 5) or x.shape[-4] != 5 or x.shape[-2:] != (face_size, face_size):
        raise ValueError(
            f"faces must have shape [5, C, {face_size}, {face_size}] or [B, 5, C, {face_size}, {face_size}] "
            f"(faces ordered {FACE_NAMES}), got {tuple(x.shape)}"
        )
    if x.dtype == torch.bool:
        x = x.to(torch.uint8)
    return x, was_numpy


def _check_face_size(face_size: int) -> None:
    if int(face_size) != face_size or face_size < 2:
        raise ValueError(f"face_size must be an integer >= 2, got {face_size}")


__all__ = [
    "FACE_NAMES",
    "MODES",
    "CubemapToFisheye",
    "RemapTable",
    "clear_table_cache",
    "direction_to_face",
    "face_rays",
    "face_rotation",
]
