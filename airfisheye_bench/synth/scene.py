"""A procedural 3-D scene that can be ray cast, rendered and queried for visibility.

:class:`Scene` is the generator's world: primitives (boxes, roofs, cylinders, ellipsoids) standing on a flat
ground (``z = 0``) painted with class regions, all in the world frame (x east, y north, z up, metres).
``Scene.generate(env, seed)`` builds one of the :data:`ENVIRONMENTS` deterministically.

Queries (all vectorised over rays; rays are processed in fixed-size chunks and every per-ray computation is
elementwise, so results are bit-identical for any batching, thread count or chunk size):

* :meth:`Scene.raycast` — nearest hit: distance, raw class, normal, textured albedo (and, beyond the contract,
  the primitive id: :data:`~airfisheye_bench.synth.raycast.GROUND` = -1, :data:`~airfisheye_bench.synth.raycast.MISS` = -2).
* :meth:`Scene.render` — shaded RGB (sun with shadow rays, sky light, haze), raw class, range.
* :meth:`Scene.segment_visible` — exact ground-truth visibility of points from viewpoints.
* :meth:`Scene.ground_height`, :meth:`Scene.obstacle_height`, :attr:`Scene.bounds` — for flight planning.

Beyond the contract: :attr:`RayHits.prim`, :attr:`Scene.num_primitives`, :attr:`Scene.device`, a per-ray
``max_dist`` tensor in :meth:`Scene.raycast`, and the constructor ``Scene(SceneData)`` for hand-built scenes
(:class:`~airfisheye_bench.synth.builder.SceneBuilder`). ``device="cuda"`` keeps every tensor and the ray
casting on the GPU. On CPU, prefer one torch thread per worker process (``torch.set_num_threads(1)``) and
several workers: the kernels are many short elementwise passes, which intra-op threads barely speed up.

Example:
    >>> import torch
    >>> scene = Scene.generate("suburban", seed=0, size_m=120.0)
    >>> o = torch.tensor([[0.0, 0.0, 40.0]]).expand(3, 3)
    >>> d = torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.6, 0.8], [0.6, 0.0, -0.8]])
    >>> hits = scene.raycast(o, d, max_dist=500.0)
    >>> hits.dist.shape, hits.raw_id.dtype, bool(torch.isinf(hits.dist[1]))   # ray 1 looks up: sky
    (torch.Size([3]), torch.uint8, True)
    >>> rgb, raw, dist = scene.render(o, d, Lighting())
    >>> bool(((rgb >= 0) & (rgb <= 1)).all())
    True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from airfisheye_bench.geometry import portable
from airfisheye_bench.synth._ops import nonzero, take
from airfisheye_bench.synth.builder import SceneData
from airfisheye_bench.synth.classes import RAW_ID, SKY_ID
from airfisheye_bench.synth.environments import ENVIRONMENTS, build_environment
from airfisheye_bench.synth.raycast import GROUND, RayTracer
from airfisheye_bench.synth.shading import Lighting, ground_albedo, shade, sky_color, surface_albedo

__all__ = ["ENVIRONMENTS", "Lighting", "RayHits", "Scene"]

_HEIGHT_RES = 1.0  # metres per texel of the obstacle-height raster


@dataclass
class RayHits:
    """Nearest hit per ray (world frame).

    Attributes:
        dist: ``[N]`` float32 range to the hit, ``inf`` where the ray escapes (sky).
        raw_id: ``[N]`` uint8 raw class (:data:`~airfisheye_bench.synth.classes.SKY_ID` on a miss).
        normal: ``[N, 3]`` unit surface normal facing the ray (zeros on a miss).
        albedo: ``[N, 3]`` textured linear albedo (zeros on a miss).
        prim: ``[N]`` int64 primitive id (-1 ground, -2 miss).
    """

    dist: torch.Tensor
    raw_id: torch.Tensor
    normal: torch.Tensor
    albedo: torch.Tensor
    prim: torch.Tensor


def _check_rays(origins: torch.Tensor, dirs: torch.Tensor, name: str = "dirs", unit: bool = True) -> None:
    if not isinstance(origins, torch.Tensor) or origins.ndim != 2 or origins.shape[1] != 3:
        raise ValueError(
            f"origins must be a tensor of shape [N, 3], got {getattr(origins, 'shape', type(origins))}"
        )
    if not isinstance(dirs, torch.Tensor) or dirs.shape != origins.shape:
        raise ValueError(
            f"{name} must be a tensor of shape {tuple(origins.shape)} like origins, "
            f"got {getattr(dirs, 'shape', type(dirs))}"
        )
    if not (bool(torch.isfinite(origins).all()) and bool(torch.isfinite(dirs).all())):
        raise ValueError(f"origins and {name} must be finite")
    if unit and dirs.numel():
        sq = (dirs * dirs).sum(-1)
        if bool(((sq - 1.0).abs() > 2e-3).any()):
            raise ValueError(f"{name} must be unit vectors (got squared norms up to {float(sq.max()):.4g})")


class Scene:
    """A procedural scene; build it with :meth:`generate` (or from a :class:`SceneData`).

    Args:
        data: primitives, attributes and ground raster.
        env: environment name (metadata).
        seed: generation seed (metadata).
        device: where the tensors live and the rays are cast.
        cell_size: acceleration-grid cell edge in metres.

    Example:
        >>> import numpy as np
        >>> from airfisheye_bench.synth.builder import SceneBuilder
        >>> b = SceneBuilder(40.0, np.random.default_rng(0))
        >>> b.add_box(10, 0, 0, 4, 4, 6, 0.0, "house", (0.8, 0.8, 0.8))
        >>> scene = Scene(b.finish())
        >>> cam = torch.tensor([[0.0, 0.0, 3.0]]).expand(2, 3)
        >>> scene.segment_visible(cam, torch.tensor([[7.0, 0.0, 3.0], [15.0, 0.0, 3.0]])).tolist()
        [True, False]
    """

    def __init__(
        self,
        data: SceneData,
        env: str = "custom",
        seed: int = 0,
        device: torch.device | str = "cpu",
        cell_size: float = 8.0,
    ) -> None:
        self.env = env
        self.seed = int(seed)
        self.device = torch.device(device)
        dev = self.device
        self._bounds = tuple(float(b) for b in data.bounds)
        self.tracer = RayTracer(data.prims.to(dev), self._bounds, cell_size=cell_size)
        self.prim_raw = data.raw.to(dev)
        self.prim_albedo = data.albedo.to(dev)
        self.prim_texture = data.texture.to(dev)
        self.prim_params = data.params.to(dev)
        self.prim_seed = data.seed.to(dev)
        self.ground_raw = data.ground_raw.to(dev)
        self.ground_albedo_map = data.ground_albedo.to(dev)
        self.ground_res = float(data.ground_res)
        self._height_map = self._rasterise_heights()
        self._pooled: dict[int, torch.Tensor] = {}

    @classmethod
    def generate(
        cls, env: str, seed: int, size_m: float = 400.0, device: torch.device | str = "cpu"
    ) -> Scene:
        """Build environment ``env`` (one of :data:`ENVIRONMENTS`) of ``size_m x size_m`` metres.

        Deterministic for ``(env, seed, size_m)`` on any machine (NumPy's PCG64 drives the layout).

        Example:
            >>> a = Scene.generate("downtown", seed=2, size_m=100.0)
            >>> b = Scene.generate("downtown", seed=2, size_m=100.0)
            >>> torch.equal(a.tracer.prims.boxes, b.tracer.prims.boxes), a.bounds
            (True, (-50.0, -50.0, 50.0, 50.0))
        """
        if env not in ENVIRONMENTS:
            raise ValueError(f"env must be one of {ENVIRONMENTS}, got {env!r}")
        if not size_m > 0:
            raise ValueError(f"size_m must be positive, got {size_m}")
        return cls(build_environment(env, int(seed), float(size_m)), env=env, seed=int(seed), device=device)

    # ---------------------------------------------------------------------------------------- properties
    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the area with objects (the ground plane extends beyond)."""
        return self._bounds

    @property
    def num_primitives(self) -> int:
        return len(self.tracer.prims)

    def __repr__(self) -> str:
        return f"Scene(env={self.env!r}, seed={self.seed}, bounds={self.bounds}, primitives={self.num_primitives})"

    # ------------------------------------------------------------------------------------------- queries
    def raycast(
        self, origins: torch.Tensor, dirs: torch.Tensor, max_dist: float | torch.Tensor = 1000.0
    ) -> RayHits:
        """Nearest hit of each ray ``origins[i] + t * dirs[i]``, ``0 < t <= max_dist``.

        Args:
            origins: ``[N, 3]`` world-frame origins.
            dirs: ``[N, 3]`` unit directions.
            max_dist: scalar or ``[N]`` largest range; farther hits count as misses.
        """
        _check_rays(origins, dirs)
        o = origins.to(self.device, torch.float32)
        d = dirs.to(self.device, torch.float32)
        t_max = torch.as_tensor(max_dist, dtype=torch.float32, device=self.device)
        if t_max.numel() not in (1, o.shape[0]) or bool((t_max <= 0).any()) or bool(torch.isnan(t_max).any()):
            raise ValueError(f"max_dist must be a positive scalar or one value per ray, got {max_dist!r}")
        t, prim = self.tracer.trace(o, d, t_max.reshape(-1).expand(o.shape[0]).contiguous())
        return self._hits(o, d, t, prim)

    def _hits(self, o: torch.Tensor, d: torch.Tensor, t: torch.Tensor, prim: torch.Tensor) -> RayHits:
        n = o.shape[0]
        dev = self.device
        raw = torch.full((n,), SKY_ID, dtype=torch.uint8, device=dev)
        normal = torch.zeros(n, 3, dtype=torch.float32, device=dev)
        albedo = torch.zeros(n, 3, dtype=torch.float32, device=dev)
        # Ground.
        g = nonzero(prim == GROUND)
        if g.numel():
            point = take(o, g) + take(t, g).unsqueeze(1) * take(d, g)
            graw, galb = self._ground_lookup(point[:, :2])
            raw.index_copy_(0, g, graw)
            normal.index_copy_(0, g, torch.tensor([[0.0, 0.0, 1.0]], device=dev).expand(g.numel(), 3))
            albedo.index_copy_(0, g, ground_albedo(graw, galb, point, RAW_ID))
        # Objects.
        k = nonzero(prim >= 0)
        if k.numel():
            pk = take(prim, k)
            ok, dk = take(o, k), take(d, k)
            point = ok + take(t, k).unsqueeze(1) * dk
            rays = torch.cat([ok.T, dk.T]).contiguous()
            nrm, uv, face = self.tracer.prims.surface(rays, pk)
            normal.index_copy_(0, k, nrm)
            raw.index_copy_(0, k, take(self.prim_raw, pk))
            alb = surface_albedo(
                take(self.prim_texture, pk),
                take(self.prim_albedo, pk),
                take(self.prim_params, pk),
                take(self.prim_seed, pk),
                point,
                uv,
                face,
            )
            albedo.index_copy_(0, k, alb)
        return RayHits(dist=t, raw_id=raw, normal=normal, albedo=albedo, prim=prim)

    def _ground_lookup(self, xy: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Raw class and base albedo of the ground texel under each point (nearest; clamped at the border)."""
        h, w = self.ground_raw.shape
        x0, y0 = self._bounds[0], self._bounds[1]
        j = torch.floor((xy[:, 0] - x0) / self.ground_res).long().clamp(0, w - 1)
        i = torch.floor((xy[:, 1] - y0) / self.ground_res).long().clamp(0, h - 1)
        flat = i * w + j
        return self.ground_raw.reshape(-1)[flat], self.ground_albedo_map.reshape(-1, 3)[flat]

    def render(
        self,
        origins: torch.Tensor,
        dirs: torch.Tensor,
        lighting: Lighting,
        max_dist: float = 1000.0,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Shaded colour, raw class and range of each ray.

        Returns:
            ``rgb [N, 3]`` float32 display values in [0, 1], ``raw_id [N]`` uint8 (sky on misses) and
            ``dist [N]`` float32 (``inf`` for sky).
        """
        if not isinstance(lighting, Lighting):
            raise ValueError(f"lighting must be a Lighting, got {type(lighting).__name__}")
        hits = self.raycast(origins, dirs, max_dist)
        d = dirs.to(self.device, torch.float32)
        o = origins.to(self.device, torch.float32)
        rgb = sky_color(d, lighting)
        surf = nonzero(torch.isfinite(hits.dist))
        if surf.numel():
            nrm, dist, ds = take(hits.normal, surf), take(hits.dist, surf), take(d, surf)
            lx, ly, lz = lighting.sun_direction()
            ndl = nrm[:, 0] * lx + nrm[:, 1] * ly + nrm[:, 2] * lz
            sunlit = torch.zeros(surf.numel(), dtype=torch.bool, device=self.device)
            facing = nonzero(ndl > 0)
            if facing.numel():
                df = take(dist, facing)
                # Start the shadow ray just off the surface (offset grows with range: float32 error).
                off = (0.01 + 2e-5 * df).unsqueeze(1)
                start = (
                    take(o, take(surf, facing)) + df.unsqueeze(1) * take(ds, facing) + off * take(nrm, facing)
                )
                sun = torch.tensor([[lx, ly, lz]], dtype=torch.float32, device=self.device)
                t_sh, _ = self.tracer.trace(
                    start, sun.expand_as(start).contiguous(), torch.full_like(df, 1.0e4), any_hit=True
                )
                sunlit.index_copy_(0, facing, torch.isinf(t_sh))
            water = take(hits.raw_id, surf) == RAW_ID["water"]
            shaded = shade(take(hits.albedo, surf), nrm, ds, dist, sunlit, water, lighting)
            rgb.index_copy_(0, surf, shaded)
        return rgb, hits.raw_id, hits.dist

    def segment_visible(
        self, origins: torch.Tensor, points: torch.Tensor, rel_eps: float = 1e-3, abs_eps: float = 0.02
    ) -> torch.Tensor:
        """Whether the segment from each origin to its point is unobstructed (exact ray cast).

        A point counts as visible when nothing is hit before ``|p - o| - max(abs_eps, rel_eps * |p - o|)``:
        the tolerance absorbs the point's own surface (a LiDAR return lies on it).

        Args:
            origins: ``[N, 3]`` viewpoints (e.g. the camera centre, repeated).
            points: ``[N, 3]`` target points.
            rel_eps: tolerance relative to the segment length.
            abs_eps: minimum tolerance in metres.

        Returns:
            ``[N]`` bool.
        """
        _check_rays(origins, points, name="points", unit=False)
        o = origins.to(self.device, torch.float32)
        p = points.to(self.device, torch.float32)
        v = p - o
        length = portable.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])
        safe = torch.where(length > 0, length, torch.ones_like(length))
        d = v / safe.unsqueeze(1)
        reach = length - torch.maximum(torch.full_like(length, abs_eps), rel_eps * length)
        visible = reach <= 0  # the point is (within tolerance) at the origin
        cast = (~visible).nonzero().squeeze(1)
        if cast.numel():
            t, _ = self.tracer.trace(o[cast], d[cast], reach[cast], any_hit=True)
            visible[cast] = torch.isinf(t)
        return visible

    # ------------------------------------------------------------------------------------ flight planning
    def ground_height(self, xy: torch.Tensor) -> torch.Tensor:
        """Height of the ground under each ``xy [N, 2]`` (the ground is flat: zeros)."""
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"xy must have shape [N, 2], got {tuple(xy.shape)}")
        return torch.full((xy.shape[0],), self.tracer.ground_z, dtype=torch.float32, device=xy.device)

    def _rasterise_heights(self) -> torch.Tensor:
        """Max top height of any object over each 1 m texel (objects' bounding boxes; ground = 0)."""
        x0, y0, x1, y1 = self._bounds
        w = math.ceil((x1 - x0) / _HEIGHT_RES)
        h = math.ceil((y1 - y0) / _HEIGHT_RES)
        hmap = torch.full((h * w,), self.tracer.ground_z, dtype=torch.float32)
        box = self.tracer.prim_aabb.cpu()
        if box.shape[1]:
            j0 = torch.floor((box[0] - x0) / _HEIGHT_RES).long().clamp(0, w - 1)
            j1 = torch.floor((box[3] - x0) / _HEIGHT_RES).long().clamp(0, w - 1)
            i0 = torch.floor((box[1] - y0) / _HEIGHT_RES).long().clamp(0, h - 1)
            i1 = torch.floor((box[4] - y0) / _HEIGHT_RES).long().clamp(0, h - 1)
            wx = j1 - j0 + 1
            counts = wx * (i1 - i0 + 1)
            prim = torch.repeat_interleave(torch.arange(box.shape[1]), counts)
            local = torch.arange(prim.numel()) - torch.repeat_interleave(
                torch.cumsum(counts, 0) - counts, counts
            )
            texel = (i0[prim] + local // wx[prim]) * w + j0[prim] + local % wx[prim]
            hmap = hmap.scatter_reduce(0, texel, box[5][prim], "amax")
        return hmap.reshape(h, w)

    def obstacle_height(self, xy: torch.Tensor, radius: float) -> torch.Tensor:
        """Highest top of anything within ``radius`` metres (a square neighbourhood, conservative) of each ``xy``.

        Uses the objects' bounding boxes on a 1 m raster; outside the bounds only the ground remains (0).

        Args:
            xy: ``[N, 2]`` positions.
            radius: search radius in metres (>= 0).
        """
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"xy must have shape [N, 2], got {tuple(xy.shape)}")
        if radius < 0:
            raise ValueError(f"radius must be >= 0, got {radius}")
        k = math.ceil(radius / _HEIGHT_RES)
        if k not in self._pooled:
            hm = self._height_map.unsqueeze(0).unsqueeze(0)
            self._pooled[k] = F.max_pool2d(hm, 2 * k + 1, stride=1, padding=k)[0, 0] if k else hm[0, 0]
        pooled = self._pooled[k]
        h, w = pooled.shape
        x0, y0 = self._bounds[:2]
        xyc = xy.detach().to("cpu", torch.float32)
        j = torch.floor((xyc[:, 0] - x0) / _HEIGHT_RES).long()
        i = torch.floor((xyc[:, 1] - y0) / _HEIGHT_RES).long()
        # Outside the raster, clamp to the nearest texel within reach, else the ground.
        jc, ic = j.clamp(0, w - 1), i.clamp(0, h - 1)
        near = ((j - jc).abs() <= k) & ((i - ic).abs() <= k)
        out = torch.where(near, pooled[ic, jc], torch.full_like(xyc[:, 0], self.tracer.ground_z))
        return out.to(xy.device)
