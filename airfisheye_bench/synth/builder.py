"""Incremental construction of a synthetic scene: primitives with their attributes, and the painted ground.

:class:`SceneBuilder` is what the environment generators (:mod:`~airfisheye_bench.synth.environments`) talk
to: they add boxes, roofs, cylinders and ellipsoids with a raw class, a colour and a texture, and paint 2-D
class regions (road, sidewalk, grass, water, ...) on a ground raster. :meth:`SceneBuilder.finish` turns it all
into tensors (:class:`SceneData`).

Colours are given as sRGB-like triples in [0, 1]; they are stored as linear albedo (squared).

Example:
    >>> import numpy as np
    >>> b = SceneBuilder(size_m=40.0, rng=np.random.default_rng(0))
    >>> b.paint_rect(-20, -3, 20, 3, "road", (0.3, 0.3, 0.3))
    >>> b.add_box(5, 5, 0, 8, 6, 3, 0.0, "house", (0.9, 0.9, 0.8), texture="facade", params=(3.0, 2.5))
    >>> b.add_roof(5, 5, 3, 8.8, 6.8, 2.0, 0.0, "gable", "roof", (0.6, 0.25, 0.2))
    >>> data = b.finish()
    >>> len(data.prims), tuple(data.ground_raw.shape)
    (2, (160, 160))
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from airfisheye_bench.synth.classes import RAW_ID
from airfisheye_bench.synth.raycast import PrimitiveSet
from airfisheye_bench.synth.shading import TEXTURES

__all__ = ["SceneBuilder", "SceneData"]

Color = tuple[float, float, float]
_KINDS = ("boxes", "roofs", "cylinders", "ellipsoids")


@dataclass
class SceneData:
    """Everything a :class:`~airfisheye_bench.synth.scene.Scene` is made of (CPU tensors).

    Attributes:
        prims: the primitives (global ids: boxes, roofs, cylinders, ellipsoids).
        raw: ``[P]`` uint8 raw class per primitive.
        albedo: ``[P, 3]`` linear base albedo per primitive.
        texture: ``[P]`` int64 texture kind.
        params: ``[P, 2]`` texture parameters.
        seed: ``[P]`` int64 per-primitive texture seed.
        ground_raw: ``[H, W]`` uint8 raw class of the ground; row ``i`` / column ``j`` covers
            ``y = ymin + (i + 0.5) * res``, ``x = xmin + (j + 0.5) * res``.
        ground_albedo: ``[H, W, 3]`` linear albedo of the ground.
        ground_res: metres per ground texel.
        bounds: ``(xmin, ymin, xmax, ymax)``.
    """

    prims: PrimitiveSet
    raw: torch.Tensor
    albedo: torch.Tensor
    texture: torch.Tensor
    params: torch.Tensor
    seed: torch.Tensor
    ground_raw: torch.Tensor
    ground_albedo: torch.Tensor
    ground_res: float
    bounds: tuple[float, float, float, float]


class SceneBuilder:
    """Collects primitives and paints the ground of a square scene centred on the origin.

    Args:
        size_m: edge length of the square scene.
        rng: the random generator shared with the environment generator (colour jitter, texture seeds).
        ground_res: metres per ground texel.
        ground: raw class and colour the ground starts with.
    """

    def __init__(
        self,
        size_m: float,
        rng: np.random.Generator,
        ground_res: float = 0.25,
        ground: tuple[str, Color] = ("grass", (0.36, 0.5, 0.22)),
    ) -> None:
        if size_m <= 0:
            raise ValueError(f"size_m must be positive, got {size_m}")
        self.size = float(size_m)
        self.half = self.size / 2.0
        self.rng = rng
        self.res = float(ground_res)
        n = math.ceil(self.size / self.res)
        self.ground_raw = np.full((n, n), RAW_ID[ground[0]], dtype=np.uint8)
        self.ground_rgb = np.empty((n, n, 3), dtype=np.float32)
        self.ground_rgb[:] = np.asarray(ground[1], dtype=np.float32)
        self._params: dict[str, list[list[float]]] = {k: [] for k in _KINDS}
        self._attrs: dict[str, list[tuple]] = {k: [] for k in _KINDS}

    # ---------------------------------------------------------------------------------------- helpers
    def jitter(self, color: Color, amount: float = 0.06, brightness: float = 0.1) -> Color:
        """A per-object variation of ``color``: independent channel noise plus a common brightness change."""
        c = np.asarray(color, dtype=np.float64)
        c = c * (1.0 + brightness * (2.0 * self.rng.random() - 1.0)) + amount * (
            2.0 * self.rng.random(3) - 1.0
        )
        return tuple(float(v) for v in np.clip(c, 0.02, 0.98))

    def inside(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Whether ``(x, y)`` lies inside the scene, at least ``margin`` from its border."""
        return abs(x) <= self.half - margin and abs(y) <= self.half - margin

    def _attr(self, kind: str, raw: str, color: Color, texture: str, params: tuple[float, float]) -> None:
        if raw not in RAW_ID:
            raise ValueError(f"unknown raw class {raw!r}")
        if texture not in TEXTURES:
            raise ValueError(f"unknown texture {texture!r}")
        seed = int(self.rng.integers(0, 1 << 20))
        self._attrs[kind].append((RAW_ID[raw], color, TEXTURES[texture], params, seed))

    # ------------------------------------------------------------------------------------- primitives
    def add_box(
        self,
        cx: float,
        cy: float,
        z0: float,
        lx: float,
        ly: float,
        height: float,
        yaw: float,
        raw: str,
        color: Color,
        texture: str = "plain",
        params: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """A box of footprint ``lx x ly`` (local x, y; rotated by ``yaw`` radians) from ``z0`` to ``z0 + height``."""
        self._params["boxes"].append(
            [cx, cy, z0 + height / 2, lx / 2, ly / 2, height / 2, math.cos(yaw), math.sin(yaw), 0.0, 0.0]
        )
        self._attr("boxes", raw, color, texture, params)

    def add_roof(
        self,
        cx: float,
        cy: float,
        z0: float,
        lx: float,
        ly: float,
        height: float,
        yaw: float,
        shape: str,
        raw: str,
        color: Color,
        texture: str = "roof",
        params: tuple[float, float] = (0.35, 0.0),
    ) -> None:
        """A roof over the footprint ``lx x ly``, from its eaves at ``z0`` up to ``z0 + height``.

        ``shape``: ``gable`` (ridge along local x), ``hip`` (ridge along x, sloped ends), ``pyramid`` or ``flat``.
        """
        hx, hy, hz = lx / 2, ly / 2, height / 2
        slopes = {  # (sx, sy, kx): see airfisheye_bench.synth.primitives
            "gable": (0.0, 2 * hz / hy, 0.0),
            "hip": (2 * hz / hy, 2 * hz / hy, max(hx - hy, 0.0)),
            "pyramid": (2 * hz / hx, 2 * hz / hy, 0.0),
            "flat": (0.0, 0.0, 0.0),
        }
        if shape not in slopes:
            raise ValueError(f"shape must be one of {sorted(slopes)}, got {shape!r}")
        sx, sy, kx = slopes[shape]
        self._params["roofs"].append([cx, cy, z0 + hz, hx, hy, hz, math.cos(yaw), math.sin(yaw), sx, sy, kx])
        self._attr("roofs", raw, color, texture, params)

    def add_cylinder(
        self,
        cx: float,
        cy: float,
        radius: float,
        z0: float,
        z1: float,
        raw: str,
        color: Color,
        texture: str = "plain",
        params: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """A vertical cylinder from ``z0`` to ``z1``."""
        self._params["cylinders"].append([cx, cy, radius, z0, z1])
        self._attr("cylinders", raw, color, texture, params)

    def add_ellipsoid(
        self,
        cx: float,
        cy: float,
        cz: float,
        rx: float,
        ry: float,
        rz: float,
        raw: str,
        color: Color,
        texture: str = "foliage",
        params: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """An axis-aligned ellipsoid with centre ``(cx, cy, cz)`` and semi-axes ``rx, ry, rz``."""
        self._params["ellipsoids"].append([cx, cy, cz, rx, ry, rz])
        self._attr("ellipsoids", raw, color, texture, params)

    # ------------------------------------------------------------------------------------------ ground
    def _pix(self, x: float) -> int:
        return int(np.clip(round((x + self.half) / self.res), 0, self.ground_raw.shape[0]))

    def paint_rect(
        self, x0: float, y0: float, x1: float, y1: float, raw: str, color: Color, noise: float = 0.0
    ) -> None:
        """Paint the axis-aligned rectangle ``[x0, x1] x [y0, y1]`` of the ground with a class and colour.

        ``noise`` adds per-texel colour noise (e.g. for bare soil).
        """
        c0, c1 = self._pix(min(x0, x1)), self._pix(max(x0, x1))
        r0, r1 = self._pix(min(y0, y1)), self._pix(max(y0, y1))
        if c1 <= c0 or r1 <= r0:
            return
        self.ground_raw[r0:r1, c0:c1] = RAW_ID[raw]
        if noise > 0:
            jit = 1.0 + noise * (2.0 * self.rng.random((r1 - r0, c1 - c0, 1), dtype=np.float32) - 1.0)
            self.ground_rgb[r0:r1, c0:c1] = np.asarray(color, dtype=np.float32) * jit
        else:
            self.ground_rgb[r0:r1, c0:c1] = np.asarray(color, dtype=np.float32)

    def paint_ellipse(self, cx: float, cy: float, rx: float, ry: float, raw: str, color: Color) -> None:
        """Paint the axis-aligned ellipse with centre ``(cx, cy)`` and semi-axes ``rx, ry``."""
        c0, c1 = self._pix(cx - rx), self._pix(cx + rx)
        r0, r1 = self._pix(cy - ry), self._pix(cy + ry)
        if c1 <= c0 or r1 <= r0:
            return
        xs = -self.half + (np.arange(c0, c1) + 0.5) * self.res
        ys = -self.half + (np.arange(r0, r1) + 0.5) * self.res
        m = ((xs[None, :] - cx) / rx) ** 2 + ((ys[:, None] - cy) / ry) ** 2 <= 1.0
        self.ground_raw[r0:r1, c0:c1][m] = RAW_ID[raw]
        self.ground_rgb[r0:r1, c0:c1][m] = np.asarray(color, dtype=np.float32)

    # ------------------------------------------------------------------------------------------ finish
    def finish(self) -> SceneData:
        """Freeze the scene into tensors."""
        tables = {}
        for kind, rows in (("boxes", 10), ("roofs", 11), ("cylinders", 5), ("ellipsoids", 6)):
            p = self._params[kind]
            tables[kind] = torch.tensor(p, dtype=torch.float32).reshape(-1, rows).T.contiguous()
        prims = PrimitiveSet(**tables)
        attrs = [a for kind in _KINDS for a in self._attrs[kind]]
        raw = torch.tensor([a[0] for a in attrs], dtype=torch.uint8)
        albedo = torch.tensor([a[1] for a in attrs], dtype=torch.float32).reshape(-1, 3) ** 2
        texture = torch.tensor([a[2] for a in attrs], dtype=torch.int64)
        params = torch.tensor([a[3] for a in attrs], dtype=torch.float32).reshape(-1, 2)
        seed = torch.tensor([a[4] for a in attrs], dtype=torch.int64)
        ground_albedo = torch.from_numpy(np.clip(self.ground_rgb, 0.0, 1.0) ** 2)
        return SceneData(
            prims=prims,
            raw=raw,
            albedo=albedo,
            texture=texture,
            params=params,
            seed=seed,
            ground_raw=torch.from_numpy(self.ground_raw.copy()),
            ground_albedo=ground_albedo.contiguous(),
            ground_res=self.res,
            bounds=(-self.half, -self.half, self.half, self.half),
        )
