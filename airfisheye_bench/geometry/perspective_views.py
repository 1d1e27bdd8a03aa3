"""Perspective views of a fisheye camera: how a model that only knows perspective images sees a fisheye image
(docs/evaluation.md, "Perspective models on fisheye"; docs/design.md, "Perspective views").

A view is the model's own perspective camera (an ideal ``pinhole``, or any calibrated one) turned by ``R_fish_view``
(3x3: maps the view's directions into the fisheye camera frame, as a cube face's ``R_cam_face``), all sharing the
fisheye's centre. The views are

- ``cube`` (default): the cube's faces the fisheye sees, ``front``, ``left``, ``right``, ``up``, ``down``
  (:func:`~airfisheye_bench.geometry.cubemap.face_rotation`; a face that no valid fisheye pixel falls in is left
  out), each through the model's camera: at 90 deg exactly the cube, wider ones overlap;
- a list of ``[yaw, pitch]`` or ``[yaw, pitch, roll]`` in degrees (the gimbal's convention,
  :func:`~airfisheye_bench.geometry.transforms.gimbal_rotation`: positive yaw looks left, positive pitch down): a
  tiling, with overlap where the model's field of view is wider than the steps.

Images travel between the fisheye and the views through the project's weighted-gather tables
(:class:`~airfisheye_bench.geometry.remap_table.RemapTable`, applied by ``apply_table``, cached in its LRU):

- **to the views** (:meth:`PerspectiveViews.to_views`): every view pixel's ray, turned into the fisheye frame and
  projected by the fisheye: its four bilinear taps (images) or the nearest pixel (labels), taps outside the fisheye's
  valid region dropped and the rest renormalised; a view pixel that sees none of the fisheye gets ``fill``.
- **back to the fisheye** (:meth:`PerspectiveViews.from_views`): every valid fisheye pixel's ray seen by each view
  whose frame it falls in: ``bilinear`` blends the views' bilinear taps, each view weighted by a feather that falls
  linearly to 0 at its border (its distance to the frame's edge in pixels, over half the frame's shorter side), so
  overlapping views fade into each other and an exact cube's seams are shared equally; ``nearest`` takes the
  nearest texel of the one view whose feather is largest (labels). Taps on view pixels that saw nothing of the fisheye
  are dropped unless nothing else is left.

**Depth.** The benchmark's depth is range along the ray (docs/design.md, "Frames and units"); a perspective model
trained by this project predicts range too (its views were served from the same cube faces, which store range), an
outside model usually z along its view's axis. ``depth="z"`` converts: a fisheye ray ``d`` is ``d_v = R^T d`` in a
view, of unit length, so ``range = z / d_v.z``, applied per tap (the views' axes differ where they are blended)
after the interpolation of ``z``, which is affine across a plane where range is not. ``to_views`` of sparse depth
(:meth:`PerspectiveViews.splat_to_views`) moves each LiDAR pixel to the nearest view pixel of every view that sees
it, never interpolated (``range * d_v.z`` for ``z``; the nearest return where two land on one view pixel).

Example:
    >>> from airfisheye_bench.geometry.cameras import ideal_camera
    >>> views = PerspectiveViews(ideal_camera(64, 64, 190.0), ideal_camera(32, 32, 90.0, "pinhole"))
    >>> views.names, round(views.coverage_fraction, 3)
    (('front', 'left', 'right', 'up', 'down'), 1.0)
    >>> tiles = views.to_views(torch.rand(2, 3, 64, 64))
    >>> tiles.shape, views.from_views(tiles).shape
    (torch.Size([2, 5, 3, 32, 32]), torch.Size([2, 3, 64, 64]))
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import torch

from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.cubemap import FACE_NAMES, face_rotation
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
from airfisheye_bench.geometry.transforms import gimbal_rotation

__all__ = [
    "DEPTH_CONVENTIONS",
    "VIEW_SETS",
    "PerspectiveView",
    "PerspectiveViews",
    "cube_views",
    "parse_views",
    "views_problem",
]

#: The named view sets (``views=``); a list of ``[yaw, pitch(, roll)]`` is the other form.
VIEW_SETS = ("cube",)
#: What a view's depth output measures: ``range`` along the ray (this project's models) or ``z`` along its axis.
DEPTH_CONVENTIONS = ("range", "z")
#: The feather's floor inside a view's frame: a sample on an exact cube's seam still has a weight.
_MIN_FEATHER = 1e-4
#: Pixels beyond a view's frame that still count as on its edge (float64 rounding of a ray on a seam).
_EDGE_TOL = 1e-6
_FORMS = "cube, or a list of views [yaw, pitch] or [yaw, pitch, roll] in degrees"


@dataclass(frozen=True)
class PerspectiveView:
    """One view: a name and ``R_fish_view`` (float64 3x3, view directions -> fisheye camera frame)."""

    name: str
    rotation: np.ndarray

    def describe(self) -> dict[str, Any]:
        """Plain data for a record: the name and the rotation's rows."""
        return {"name": self.name, "R_fish_view": np.round(self.rotation, 12).tolist()}


def cube_views() -> tuple[PerspectiveView, ...]:
    """The five cube faces as views, in :data:`~airfisheye_bench.geometry.cubemap.FACE_NAMES` order."""
    return tuple(PerspectiveView(name, face_rotation(name)) for name in FACE_NAMES)


def parse_views(value: Any) -> tuple[PerspectiveView, ...]:
    """``views=`` as given: ``cube`` or a list of ``[yaw, pitch]`` / ``[yaw, pitch, roll]`` (degrees).

    Raises:
        ValueError: one line naming the entry and the forms (:func:`views_problem`).

    Example:
        >>> [v.name for v in parse_views([[0, 0], [60, 0, 5]])]
        ['yaw0_pitch0', 'yaw60_pitch0_roll5']
        >>> parse_views("tiles")
        Traceback (most recent call last):
        ...
        ValueError: views='tiles': expected cube, or a list of views [yaw, pitch] or [yaw, pitch, roll] in degrees
    """
    problem = views_problem(value)
    if problem is not None:
        raise ValueError(f"views={value!r}: {problem}")
    if value == "cube":
        return cube_views()
    views = []
    for entry in value:
        angles = [float(a) for a in entry] + [0.0] * (3 - len(entry))
        name = f"yaw{angles[0]:g}_pitch{angles[1]:g}" + (f"_roll{angles[2]:g}" if angles[2] else "")
        views.append(PerspectiveView(name, gimbal_rotation(*angles)))
    return tuple(views)


def views_problem(value: Any) -> str | None:
    """Why ``views=`` refuses ``value`` (``None``: it is a view set), without the key: the config check's rule.

    Example:
        >>> views_problem("cube") is None, views_problem([[0, 0], [90, 0]]) is None
        (True, True)
        >>> views_problem([[0, 0], [90]])
        'view [90]: expected cube, or a list of views [yaw, pitch] or [yaw, pitch, roll] in degrees'
    """
    if value == "cube":
        return None
    if isinstance(value, str) or not isinstance(value, Sequence) or not value:
        return f"expected {_FORMS}"
    for entry in value:
        if (
            isinstance(entry, str)
            or not isinstance(entry, Sequence)
            or len(entry) not in (2, 3)
            or not all(
                isinstance(a, int | float) and not isinstance(a, bool) and np.isfinite(a) for a in entry
            )
        ):
            shown = list(entry) if isinstance(entry, Sequence) and not isinstance(entry, str) else entry
            return f"view {shown!r}: expected {_FORMS}"
    return None


class PerspectiveViews:
    """A fisheye camera seen through perspective views (the module docstring says how).

    Args:
        fisheye: The fisheye camera (the data's).
        camera: The views' camera (the perspective model's own, at the size it takes).
        views: The views (default: :func:`cube_views`); views that no valid fisheye pixel falls in are left out.
    """

    def __init__(
        self, fisheye: CameraModel, camera: CameraModel, views: Sequence[PerspectiveView] | None = None
    ) -> None:
        for name, cam in (("fisheye", fisheye), ("camera", camera)):
            if not isinstance(cam, CameraModel):
                raise ValueError(f"{name} must be a CameraModel, got {type(cam).__name__}")
        self.fisheye = fisheye
        self.camera = camera
        candidates = tuple(views) if views is not None else cube_views()
        if not candidates:
            raise ValueError("views: give at least one view")
        for view in candidates:
            check_rotation(view.rotation, f"view {view.name!r}")
        self._candidates = candidates
        seen = [bool(self._frame_samples(view)[0].any()) for view in candidates]
        #: The views kept: those some valid fisheye pixel falls in.
        self.views: tuple[PerspectiveView, ...] = tuple(v for v, s in zip(candidates, seen, strict=True) if s)
        if not self.views:
            raise ValueError("no view sees any valid pixel of the fisheye camera")

    # ------------------------------------------------------------------ what the views cover
    @property
    def names(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.views)

    @property
    def coverage(self) -> torch.Tensor:
        """``[H, W]`` bool: the valid fisheye pixels some view sees (the others get ``fill`` from :meth:`from_views`)."""
        return filled_mask(self.table("from", "bilinear"), self.fisheye.height, self.fisheye.width)

    @property
    def coverage_fraction(self) -> float:
        """The share of the fisheye's valid pixels that some view sees."""
        valid = self.fisheye.valid_mask()
        return float((self.coverage & valid).sum()) / max(1, int(valid.sum()))

    @property
    def view_valid(self) -> torch.Tensor:
        """``[K, h, w]`` bool: the view pixels that see the fisheye's valid region."""
        n, h, w = len(self.views), self.camera.height, self.camera.width
        return filled_mask(self.table("to", "bilinear"), n * h, w).view(n, h, w)

    def describe(self) -> dict[str, Any]:
        """What was used, for a record: the views, their camera, the coverage of the fisheye."""
        return {
            "views": [v.describe() for v in self.views],
            "view_camera": self.camera.to_dict(),
            "fisheye_camera": self.fisheye.to_dict(),
            "coverage": round(self.coverage_fraction, 6),
        }

    # ------------------------------------------------------------------ remaps
    def to_views(self, image: torch.Tensor, mode: str = "bilinear", fill: float = 0) -> torch.Tensor:
        """Fisheye images ``[B, C, H, W]`` (or ``[C, H, W]``) -> views ``[B, K, C, h, w]`` (or ``[K, C, h, w]``).

        ``bilinear`` for images (integer ones rounded back), ``nearest`` for labels (values copied); view pixels that
        see no valid fisheye pixel get ``fill``.
        """
        x, squeeze = self._batched(image, self.fisheye, "image")
        b, c = x.shape[:2]
        n, h, w = len(self.views), self.camera.height, self.camera.width
        out = torch.full((b, c, n * h * w), fill, dtype=x.dtype, device=x.device)
        apply_table(lambda: x.reshape(b, c, -1), interleaved_view(x), self.table("to", mode), out)
        out = out.view(b, c, n, h, w).transpose(1, 2)
        return out[0] if squeeze else out

    def from_views(
        self, views: torch.Tensor, mode: str = "bilinear", fill: float = 0, depth: str | None = None
    ) -> torch.Tensor:
        """View outputs ``[B, K, C, h, w]`` (or ``[K, C, h, w]``) -> the fisheye ``[B, C, H, W]`` (or ``[C, H, W]``).

        Args:
            views: One output per view, in :attr:`views` order.
            mode: ``bilinear``: the views blended with feathered weights (depth, probabilities, logits, images);
                ``nearest``: the nearest texel of the most central view (labels, copied exactly).
            fill: Pixels outside the fisheye's valid region, or that no view sees.
            depth: ``None`` (not depth), ``range`` (the views' depth is range: as it is) or ``z`` (along each view's
                axis: made range, ``z / d_v.z``, tap by tap).
        """
        if depth is not None and depth not in DEPTH_CONVENTIONS:
            raise ValueError(f"depth must be None or one of {DEPTH_CONVENTIONS}, got {depth!r}")
        x, squeeze = self._batched_views(views)
        b, c = x.shape[0], x.shape[2]
        planar = x.transpose(1, 2).reshape(b, c, -1)
        if depth == "z" and not planar.is_floating_point():
            planar = planar.float()
        out = torch.full(
            (b, c, self.fisheye.height * self.fisheye.width), fill, dtype=planar.dtype, device=x.device
        )
        # A nearest table is a copy (its weights unread): the chosen view's factor is applied after it.
        kind = "from-z" if depth == "z" and mode == "bilinear" else "from"
        lut = self.table(kind, mode)
        apply_table(lambda: planar, None, lut, out)
        if depth == "z" and mode == "nearest":
            pixels = lut.pixels.to(out.device)
            out[..., pixels] *= self._z_factor(lut).to(device=out.device, dtype=out.dtype)
        out = out.view(b, c, self.fisheye.height, self.fisheye.width)
        return out[0] if squeeze else out

    def splat_to_views(self, sparse: torch.Tensor, depth: str = "range") -> torch.Tensor:
        """Sparse depth maps ``[B, 1, H, W]`` (range, 0 = none) -> ``[B, K, 1, h, w]`` in the views: each point at the
        nearest pixel of every view whose frame it falls in, its value never interpolated (``depth="z"``: made z
        along the view's axis); where several land on one view pixel, the nearest return is kept."""
        if depth not in DEPTH_CONVENTIONS:
            raise ValueError(f"depth must be one of {DEPTH_CONVENTIONS}, got {depth!r}")
        x, squeeze = self._batched(sparse, self.fisheye, "sparse")
        b, c = x.shape[:2]
        n, h, w = len(self.views), self.camera.height, self.camera.width
        src, dst, dz = (t.to(x.device) for t in self._splat)
        values = x.reshape(b, c, -1)[..., src].float()
        if depth == "z":
            values = values * dz.to(values.dtype)
        hit = values > 0
        big = torch.finfo(values.dtype).max
        out = torch.full((b, c, n * h * w), big, dtype=values.dtype, device=x.device)
        out.scatter_reduce_(2, dst.expand(b, c, -1), torch.where(hit, values, big), "amin")
        out = torch.where(out == big, 0.0, out).view(b, c, n, h, w).transpose(1, 2)
        return out[0] if squeeze else out

    # ------------------------------------------------------------------ tables
    def table(self, direction: str, mode: str) -> RemapTable:
        """The (cached) table ``to`` the views, ``from`` them, or ``from-z`` (z made range), for ``mode``."""
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        key = (
            "views",
            direction,
            mode,
            self.fisheye.key(),
            self.camera.key(),
            tuple(rotation_key(v.rotation) for v in self.views),
        )
        if direction == "to":
            build = lambda: self._build_to(mode)  # noqa: E731
        elif direction in ("from", "from-z"):
            build = lambda: self._build_from(mode, direction == "from-z")  # noqa: E731
        else:
            raise ValueError(f"direction must be to, from or from-z, got {direction!r}")
        return load_or_build(key, "views-lut", None, build)

    def _build_to(self, mode: str) -> RemapTable:
        """View pixels (flat over ``[K, h, w]``) <- fisheye pixels ``[H * W]``."""
        fish = self.fisheye
        valid = fish.valid_mask().reshape(-1)
        rays = self.camera.ray_grid(torch.float64).reshape(-1, 3)
        has_ray = torch.isfinite(rays).all(-1) & self.camera.valid_mask().reshape(-1)
        rays = rays.nan_to_num(0.0, 0.0, 0.0)
        pixels, indices, weights = [], [], []
        for k, view in enumerate(self.views):
            uv, ok = fish.project(rays @ torch.from_numpy(view.rotation).T)
            ok &= has_ray & fish.in_image(uv)
            index, weight = _taps(uv, fish.width, fish.height, mode)
            weight = torch.where(valid[index] & ok, weight, 0.0)  # taps outside the fisheye's valid region
            keep = weight.sum(0) > 0
            pixels.append(keep.nonzero().squeeze(1) + k * len(rays))
            indices.append(index[:, keep])
            weights.append(weight[:, keep] / weight[:, keep].sum(0, keepdim=True))
        return pack_table(torch.cat(pixels), torch.cat(indices, 1), torch.cat(weights, 1))

    def _build_from(self, mode: str, z_to_range: bool) -> RemapTable:
        """Fisheye pixels ``[H * W]`` <- view pixels (flat over ``[K, h, w]``)."""
        seen = self.view_valid.reshape(-1)
        indices, weights, factors = [], [], []
        for k, view in enumerate(self.views):
            inside, uv, dz = self._frame_samples(view)
            index, weight, ratio = self._view_taps(k, uv, inside, mode)
            indices.append(index)
            weights.append(weight * torch.where(inside, _feather(uv, self.camera), 0.0))
            factors.append(ratio / dz)
        index, weight, factor = torch.cat(indices), torch.cat(weights), torch.cat(factors)
        on_seen = torch.where(seen[index], weight, 0.0)
        # Taps on view pixels that saw nothing of the fisheye are dropped, unless nothing else is left (its rim).
        weight = torch.where(on_seen.sum(0, keepdim=True) > 0, on_seen, weight)
        valid = self.fisheye.valid_mask().reshape(-1)
        keep = valid & (weight.sum(0) > 0)
        index, weight, factor = index[:, keep], weight[:, keep], factor[:, keep]
        if mode == "nearest":  # the most central view's texel alone
            best = weight.argmax(0, keepdim=True)
            index, factor = index.gather(0, best), factor.gather(0, best)
            weight = torch.ones_like(index, dtype=torch.float64)
        else:
            weight = weight / weight.sum(0, keepdim=True)
        if z_to_range:
            weight = weight * factor
        return pack_table(keep.nonzero().squeeze(1), index, weight)

    def _view_taps(
        self, k: int, uv: torch.Tensor, inside: torch.Tensor, mode: str
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``([T, N] indices into the stacked views, [T, N] weights, [T, N] z ratios)`` of positions ``uv`` in view
        ``k``: its nearest texel, or its four bilinear taps. A tap off the frame (a sample in its outer half pixel) is
        the texel centre on the view's extended image plane; its direction is looked up in the view it falls
        deepest in, whose nearest texel is used (an exact cube's seams blend across the faces, as the cube-map
        remap's), with ``t_k.z / t_j.z`` (the texel ray's z in view ``k`` over its own) turning that view's z into
        view ``k``'s; one that no view's frame holds repeats the edge."""
        w, h = self.camera.width, self.camera.height
        size = w * h
        if mode == "nearest":
            col, row = uv[:, 0].round().clamp(0, w - 1).long(), uv[:, 1].round().clamp(0, h - 1).long()
            ones = torch.ones(1, len(uv), dtype=torch.float64)
            return (k * size + row * w + col)[None], ones, ones
        x0, y0 = uv[:, 0].floor(), uv[:, 1].floor()
        fx, fy = uv[:, 0] - x0, uv[:, 1] - y0
        xs = torch.stack([x0, x0 + 1, x0, x0 + 1]).long()
        ys = torch.stack([y0, y0, y0 + 1, y0 + 1]).long()
        weight = torch.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
        index = k * size + ys.clamp(0, h - 1) * w + xs.clamp(0, w - 1)
        ratio = torch.ones_like(weight)
        off = ((xs < 0) | (xs > w - 1) | (ys < 0) | (ys > h - 1)) & inside
        if off.any():
            index[off], ratio[off] = self._off_frame_texels(k, xs[off], ys[off])
        return index, weight, ratio

    def _off_frame_texels(
        self, k: int, xs: torch.Tensor, ys: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Texel positions just off view ``k``'s frame -> ``(index into the stacked views, t_k.z / t_j.z)`` of the
        nearest texel of the view ``j`` whose frame holds their direction deepest (``k`` itself, clamped, if
        none)."""
        w, h = self.camera.width, self.camera.height
        size = w * h
        rot_k = torch.from_numpy(self.views[k].rotation)
        ray = self.camera.unproject(torch.stack([xs, ys], -1).to(torch.float64)) @ rot_k.T  # fisheye frame
        best = torch.full((len(xs),), -math.inf, dtype=torch.float64)
        index = k * size + ys.clamp(0, h - 1) * w + xs.clamp(0, w - 1)
        for j, view in enumerate(self.views):
            if j == k:
                continue
            uv, ok = self.camera.project(ray @ torch.from_numpy(view.rotation))
            depth = _edge_distance(uv, self.camera)
            better = ok & (depth >= -_EDGE_TOL) & (depth > best)
            col = uv[:, 0].round().clamp(0, w - 1).long()
            row = uv[:, 1].round().clamp(0, h - 1).long()
            index = torch.where(better, j * size + row * w + col, index)
            best = torch.where(better, depth, best)
        view, texel = index // size, index % size
        rays = self.camera.ray_grid(torch.float64).reshape(-1, 3)[texel]  # in its own view's frame
        rotations = torch.from_numpy(np.stack([v.rotation for v in self.views]))
        in_k = torch.einsum("nij,nj->ni", rot_k.T[None] @ rotations[view], rays)
        return index, in_k[:, 2] / rays[:, 2]

    def _z_factor(self, lut: RemapTable) -> torch.Tensor:
        """``[P]`` float32: ``1 / d_v.z`` at each pixel of a nearest ``from`` table, in the view it copies from."""
        size = self.camera.height * self.camera.width
        view = lut.index[:, 0].long() // size
        dz = torch.stack([self._frame_samples(v)[2] for v in self.views])  # [K, H*W]
        return (1.0 / dz[view, lut.pixels]).to(torch.float32)

    @cached_property
    def _fisheye_rays(self) -> tuple[torch.Tensor, torch.Tensor]:
        """``(valid [H*W], rays [H*W, 3])`` of the fisheye, float64, rays zero where there is none."""
        rays = self.fisheye.ray_grid(torch.float64).reshape(-1, 3)
        valid = self.fisheye.valid_mask().reshape(-1) & torch.isfinite(rays).all(-1)
        return valid, rays.nan_to_num(0.0, 0.0, 0.0)

    def _frame_samples(self, view: PerspectiveView) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(inside [H*W], uv [H*W, 2], d_v.z [H*W])``: each valid fisheye pixel's ray in ``view``, whether it falls
        in the view's frame (projecting validly), where, and its unit direction's z there."""
        valid, rays = self._fisheye_rays
        local = rays @ torch.from_numpy(view.rotation)  # R^T d, row by row
        uv, ok = self.camera.project(local)
        # The frame's edge with a margin of rounding: a ray on an exact cube's seam falls on both faces' edges.
        inside = valid & ok & (_edge_distance(uv, self.camera) >= -_EDGE_TOL)
        dz = torch.where(inside, local[:, 2], 1.0)
        return inside, torch.where(inside[:, None], uv, 0.0), dz

    @cached_property
    def _splat(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(fisheye pixel [N], view pixel [N] flat over [K, h, w], d_v.z [N])`` of every valid fisheye pixel in
        every view whose frame it falls in (the nearest view pixel)."""
        h, w = self.camera.height, self.camera.width
        src, dst, dz = [], [], []
        for k, view in enumerate(self.views):
            inside, uv, z = self._frame_samples(view)
            col = uv[:, 0].round().clamp(0, w - 1).long()
            row = uv[:, 1].round().clamp(0, h - 1).long()
            pixel = inside.nonzero().squeeze(1)
            src.append(pixel)
            dst.append((k * h + row[pixel]) * w + col[pixel])
            dz.append(z[pixel])
        return torch.cat(src), torch.cat(dst), torch.cat(dz).float()

    # ------------------------------------------------------------------ shapes
    @staticmethod
    def _batched(x: torch.Tensor, camera: CameraModel, what: str) -> tuple[torch.Tensor, bool]:
        if not isinstance(x, torch.Tensor) or x.ndim not in (3, 4):
            raise ValueError(f"{what} must be a tensor [C, H, W] or [B, C, H, W]")
        if tuple(x.shape[-2:]) != (camera.height, camera.width):
            raise ValueError(
                f"{what} is {tuple(x.shape[-2:])}, the camera {camera.height}x{camera.width} (height x width)"
            )
        squeeze = x.ndim == 3
        x = x[None] if squeeze else x
        return (x.to(torch.uint8) if x.dtype == torch.bool else x), squeeze

    def _batched_views(self, x: torch.Tensor) -> tuple[torch.Tensor, bool]:
        shape = (len(self.views), self.camera.height, self.camera.width)
        if not isinstance(x, torch.Tensor) or x.ndim not in (4, 5) or (x.shape[-4], *x.shape[-2:]) != shape:
            got = tuple(x.shape) if isinstance(x, torch.Tensor) else type(x).__name__
            raise ValueError(
                f"views must be [K, C, h, w] or [B, K, C, h, w] with K, h, w = {shape} ({', '.join(self.names)}), "
                f"got {got}"
            )
        squeeze = x.ndim == 4
        x = x[None] if squeeze else x
        return (x.to(torch.uint8) if x.dtype == torch.bool else x), squeeze


def _taps(uv: torch.Tensor, width: int, height: int, mode: str) -> tuple[torch.Tensor, torch.Tensor]:
    """``([T, N] flat pixel indices, [T, N] float64 weights)`` of image positions ``uv [N, 2]``: the nearest pixel
    (``T = 1``), or the four bilinear taps, clamped to the image (its outer half pixel repeats the edge)."""
    u, v = uv[:, 0].clamp(0, width - 1), uv[:, 1].clamp(0, height - 1)
    if mode == "nearest":
        return (v.round().long() * width + u.round().long())[None], torch.ones(1, len(u), dtype=torch.float64)
    x0, y0 = u.floor().clamp(max=width - 2).clamp_min(0), v.floor().clamp(max=height - 2).clamp_min(0)
    fx, fy = u - x0, v - y0
    x0, y0 = x0.long(), y0.long()
    x1, y1 = (x0 + 1).clamp(max=width - 1), (y0 + 1).clamp(max=height - 1)
    index = torch.stack([y0 * width + x0, y0 * width + x1, y1 * width + x0, y1 * width + x1])
    weight = torch.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy]).to(torch.float64)
    return index, weight


def _edge_distance(uv: torch.Tensor, camera: CameraModel) -> torch.Tensor:
    """``[N]``: how far (pixels) positions lie inside the frame ``[-0.5, w - 0.5] x [-0.5, h - 0.5]`` (negative:
    outside)."""
    w, h = camera.width, camera.height
    u, v = uv[:, 0].to(torch.float64), uv[:, 1].to(torch.float64)
    return torch.minimum(torch.minimum(u + 0.5, w - 0.5 - u), torch.minimum(v + 0.5, h - 0.5 - v))


def _feather(uv: torch.Tensor, camera: CameraModel) -> torch.Tensor:
    """``[N]``: a weight falling linearly to 0 at the frame's edge: the distance to it in pixels over half the
    shorter side, at least :data:`_MIN_FEATHER`."""
    return (_edge_distance(uv, camera) / (0.5 * min(camera.width, camera.height))).clamp_min(_MIN_FEATHER)
