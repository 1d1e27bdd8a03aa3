"""Vectorised ray casting against a set of primitives over a flat ground, accelerated by a 2-D uniform grid.

The scenes are 2.5-D (objects stand on the ground), so the acceleration structure is a uniform grid over the
ground plane (8 m cells by default): each cell lists, per primitive kind, the primitives whose padded
footprint overlaps it, and stores their lowest bottom and highest top. A ray, clipped to the grid's box
(including its height range), is walked column by column along its dominant horizontal axis; inside a column
it crosses one or two cells of the other axis, which gives a closed-form enumeration of the (ray, cell) pairs
without a per-step DDA. The pairs live in dense ``[columns, rays]`` tables (broadcasting, no gathers), and
pairs whose height interval misses the cell's ``[z_min, z_max]`` are culled — the main saving for aerial views,
where most rays pass high above the objects until they dive into a street. The surviving pairs are expanded to
(ray, primitive) pairs, culled by the primitive's bounding box against the ray segment's box, and tested
exactly (:mod:`~airfisheye_bench.synth.primitives`). Columns are processed in rounds of growing width (4, 8,
16, 16, ...) and rays whose nearest hit lies before the end of the columns already visited leave the active
set (front-to-back early termination; an any-hit query stops at the first hit).

The nearest hit of each ray is found with a ``scatter_reduce(amin)`` over 64-bit keys
``(float bits of t) << 32 | primitive id``: ties go to the lowest id, and the result is independent of the
order of the pairs, of threading and of batching. Rays are processed in chunks of a fixed size; every
per-ray computation is elementwise with IEEE-exact operations, so a ray's result is bit-identical whatever
chunk or batch it arrives in.

The ground is the plane ``z = ground_z``; ids returned for it and for misses are :data:`GROUND` and
:data:`MISS`.

Example:
    >>> import torch
    >>> prims = PrimitiveSet(boxes=torch.tensor([[5.0, 0, 1, 1, 1, 1, 1, 0, 0, 0]]).T)
    >>> tracer = RayTracer(prims, bounds=(-10.0, -10.0, 10.0, 10.0), cell_size=2.0)
    >>> o = torch.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    >>> d = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.6, -0.8]])
    >>> t, prim = tracer.trace(o, d, torch.full((2,), 100.0))
    >>> t.tolist(), prim.tolist()     # the box at x = 4, then the ground at distance 1 / 0.8
    ([4.0, 1.25], [0, -1])
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import torch

from airfisheye_bench.synth._ops import expand as _expand
from airfisheye_bench.synth._ops import nonzero as _nonzero
from airfisheye_bench.synth._ops import rows as _rows
from airfisheye_bench.synth._ops import take as _take
from airfisheye_bench.synth.primitives import (
    box_hit_distance,
    box_surface,
    cylinder_hit_distance,
    cylinder_surface,
    ellipsoid_hit_distance,
    ellipsoid_surface,
)

__all__ = ["CHUNK_SIZE", "GROUND", "MISS", "PrimitiveSet", "RayTracer"]

GROUND = -1
MISS = -2
CHUNK_SIZE = 1 << 16
"""Rays per internal chunk (fixed, so memory stays bounded; results do not depend on it)."""

# Every primitive's bounding box is padded by _PAD metres before it is registered in the grid cells. The
# traversal computes cell indices from float32 positions whose error (~1e-5 m in a 1 km scene) is far below
# _PAD, so a cell missed by rounding at a cell border is harmless: any primitive the ray could hit within
# that sliver lies within _PAD of the border and is therefore also listed in the neighbouring cell visited.
_PAD = 1e-3


def _empty(rows: int, device: torch.device | str = "cpu") -> torch.Tensor:
    return torch.zeros(rows, 0, dtype=torch.float32, device=device)


@dataclass
class PrimitiveSet:
    """All primitives of a scene, one parameter table per kind (columns are primitives).

    Global primitive ids run over boxes, then roofs (sloped boxes), cylinders and ellipsoids.

    Attributes:
        boxes: ``[10, Nb]`` plain boxes (see :data:`~airfisheye_bench.synth.primitives.BOX_PARAMS`).
        roofs: ``[11, Nr]`` boxes with sloped half-spaces (see :data:`~airfisheye_bench.synth.primitives.ROOF_PARAMS`).
        cylinders: ``[5, Nc]`` vertical cylinders.
        ellipsoids: ``[6, Ne]`` axis-aligned ellipsoids.

    Example:
        >>> prims = PrimitiveSet(cylinders=torch.tensor([[0.0, 0.0, 0.5, 0.0, 4.0]]).T)
        >>> len(prims), prims.offsets, prims.aabb()[:, 0].tolist()
        (1, (0, 0, 0, 1, 1), [-0.5, -0.5, 0.0, 0.5, 0.5, 4.0])
    """

    boxes: torch.Tensor = field(default_factory=lambda: _empty(10))
    roofs: torch.Tensor = field(default_factory=lambda: _empty(11))
    cylinders: torch.Tensor = field(default_factory=lambda: _empty(5))
    ellipsoids: torch.Tensor = field(default_factory=lambda: _empty(6))

    def __post_init__(self) -> None:
        for name, rows in (("boxes", 10), ("roofs", 11), ("cylinders", 5), ("ellipsoids", 6)):
            value = getattr(self, name)
            if value.ndim != 2 or value.shape[0] != rows:
                raise ValueError(f"{name} must have shape [{rows}, n], got {tuple(value.shape)}")
            setattr(self, name, value.to(torch.float32).contiguous())
        device = self.boxes.device
        for name in ("roofs", "cylinders", "ellipsoids"):
            setattr(self, name, getattr(self, name).to(device))

    @property
    def offsets(self) -> tuple[int, int, int, int, int]:
        """First global id of each kind, and the total count."""
        nb, nr, nc, ne = (t.shape[1] for t in (self.boxes, self.roofs, self.cylinders, self.ellipsoids))
        return 0, nb, nb + nr, nb + nr + nc, nb + nr + nc + ne

    def __len__(self) -> int:
        return self.offsets[-1]

    def to(self, device: torch.device | str) -> PrimitiveSet:
        return PrimitiveSet(
            *(t.to(device) for t in (self.boxes, self.roofs, self.cylinders, self.ellipsoids))
        )

    def aabb(self) -> torch.Tensor:
        """``[6, P]`` bounding boxes ``xmin, ymin, zmin, xmax, ymax, zmax`` in global-id order."""
        parts = []
        for b in (self.boxes, self.roofs):
            ex = b[6].abs() * b[3] + b[7].abs() * b[4]
            ey = b[7].abs() * b[3] + b[6].abs() * b[4]
            parts.append(torch.stack([b[0] - ex, b[1] - ey, b[2] - b[5], b[0] + ex, b[1] + ey, b[2] + b[5]]))
        c = self.cylinders
        parts.append(torch.stack([c[0] - c[2], c[1] - c[2], c[3], c[0] + c[2], c[1] + c[2], c[4]]))
        e = self.ellipsoids
        parts.append(
            torch.stack([e[0] - e[3], e[1] - e[4], e[2] - e[5], e[0] + e[3], e[1] + e[4], e[2] + e[5]])
        )
        return torch.cat(parts, dim=1)

    def kind_table(self, kind: int) -> torch.Tensor:
        """Parameter table of kind ``kind`` (0 boxes, 1 roofs, 2 cylinders, 3 ellipsoids)."""
        return (self.boxes, self.roofs, self.cylinders, self.ellipsoids)[kind]

    def kind_hit_distance(self, kind: int, rays: torch.Tensor, params: torch.Tensor) -> torch.Tensor:
        """Hit distances of rays ``[6, K]`` against primitives of one kind given by their parameters."""
        return self._kinds()[kind][3](rays, params)

    def _kinds(self):
        o = self.offsets
        return (
            (o[0], o[1], self.boxes, lambda r, p: box_hit_distance(r, p), lambda r, p: box_surface(r, p)),
            (
                o[1],
                o[2],
                self.roofs,
                lambda r, p: box_hit_distance(r, p, sloped=True),
                lambda r, p: box_surface(r, p, sloped=True),
            ),
            (o[2], o[3], self.cylinders, cylinder_hit_distance, cylinder_surface),
            (o[3], o[4], self.ellipsoids, ellipsoid_hit_distance, ellipsoid_surface),
        )

    def hit_distance(self, rays: torch.Tensor, prim: torch.Tensor) -> torch.Tensor:
        """Distance along each ray ``rays[:, k]`` (``[6, K]``) to primitive ``prim[k]`` (``inf`` = miss)."""
        t = torch.full(prim.shape, float("inf"), dtype=torch.float32, device=rays.device)
        for lo, hi, table, fn, _ in self._kinds():
            if hi == lo:
                continue
            sel = _nonzero((prim >= lo) & (prim < hi))
            if sel.numel():
                t[sel] = fn(_rows(rays, sel), _rows(table, _take(prim, sel) - lo))
        return t

    def surface(
        self, rays: torch.Tensor, prim: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Normal ``[K, 3]``, face coordinates ``uv [K, 2]`` and face kind ``[K]`` where each ray hits ``prim``."""
        k = prim.shape[0]
        normal = torch.zeros(k, 3, dtype=torch.float32, device=rays.device)
        uv = torch.zeros(k, 2, dtype=torch.float32, device=rays.device)
        face = torch.zeros(k, dtype=torch.uint8, device=rays.device)
        for lo, hi, table, _, fn in self._kinds():
            if hi == lo:
                continue
            sel = _nonzero((prim >= lo) & (prim < hi))
            if sel.numel():
                normal[sel], uv[sel], face[sel] = fn(_rows(rays, sel), _rows(table, _take(prim, sel) - lo))
        return normal, uv, face


def _pack(t: torch.Tensor, prim: torch.Tensor | int) -> torch.Tensor:
    """Order-preserving 64-bit key for non-negative float32 distances, ties broken by primitive id."""
    return (t.contiguous().view(torch.int32).to(torch.int64) << 32) | prim


def _unpack(key: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    t = (key >> 32).to(torch.int32).view(torch.float32)
    return t, key & 0xFFFFFFFF


def _safe(den: torch.Tensor) -> torch.Tensor:
    return torch.where(den.abs() < 1e-12, torch.full_like(den, 1e-12), den)


class RayTracer:
    """Nearest-hit and any-hit queries against a :class:`PrimitiveSet` standing on a flat ground.

    Args:
        prims: the primitives.
        bounds: ``(xmin, ymin, xmax, ymax)`` of the grid; every primitive must lie inside.
        cell_size: grid cell edge in metres (a few metres: the size of a small object).
        ground_z: height of the ground plane.
        first_round: columns per ray in the first traversal round (doubled every round up to ``max_round``).
        max_round: upper bound on the columns per round.
    """

    def __init__(
        self,
        prims: PrimitiveSet,
        bounds: tuple[float, float, float, float],
        cell_size: float = 8.0,
        ground_z: float = 0.0,
        first_round: int = 4,
        max_round: int = 16,
    ) -> None:
        x0, y0, x1, y1 = (float(b) for b in bounds)
        if not (x1 > x0 and y1 > y0):
            raise ValueError(f"bounds must be (xmin, ymin, xmax, ymax) with max > min, got {bounds}")
        if cell_size <= 0:
            raise ValueError(f"cell_size must be positive, got {cell_size}")
        self.prims = prims
        self.bounds = (x0, y0, x1, y1)
        self.cell_size = float(cell_size)
        self.ground_z = float(ground_z)
        self.first_round = int(first_round)
        self.max_round = int(max_round)
        self.nx = max(1, math.ceil((x1 - x0) / cell_size))
        self.ny = max(1, math.ceil((y1 - y0) / cell_size))
        self._build()

    @property
    def device(self) -> torch.device:
        return self.prims.boxes.device

    def _build(self) -> None:
        dev = self.device
        box = self.prims.aabb()
        box[:3] -= _PAD
        box[3:] += _PAD
        self.prim_aabb = box.contiguous()
        n_cells = self.nx * self.ny
        p = box.shape[1]
        if p:
            self.z_lo = float(box[2].min())
            self.z_hi = float(box[5].max())
        else:
            self.z_lo = self.z_hi = self.ground_z
        cs, x0, y0 = self.cell_size, self.bounds[0], self.bounds[1]
        ix0 = torch.floor((box[0] - x0) / cs).long().clamp(0, self.nx - 1)
        ix1 = torch.floor((box[3] - x0) / cs).long().clamp(0, self.nx - 1)
        iy0 = torch.floor((box[1] - y0) / cs).long().clamp(0, self.ny - 1)
        iy1 = torch.floor((box[4] - y0) / cs).long().clamp(0, self.ny - 1)
        wx = ix1 - ix0 + 1
        counts = wx * (iy1 - iy0 + 1)
        prim = torch.repeat_interleave(torch.arange(p, device=dev), counts)
        local = torch.arange(prim.numel(), device=dev) - torch.repeat_interleave(
            torch.cumsum(counts, 0) - counts, counts
        )
        cell = (iy0[prim] + local // wx[prim]) * self.nx + ix0[prim] + local % wx[prim]
        order = torch.sort(cell, stable=True).indices  # stable: ids stay ascending within a cell
        prim, cell = prim[order], cell[order]
        count = torch.bincount(cell, minlength=n_cells)
        self.cell_count = count
        inf = torch.full((n_cells,), float("inf"), device=dev)
        self.cell_zmin = inf.scatter_reduce(0, cell, box[2][prim], "amin")
        self.cell_zmax = (-inf).scatter_reduce(0, cell, box[5][prim], "amax")
        # One cell list per primitive kind, so a kind's pairs are expanded without masking the others.
        self.kind_lists = []
        offsets = self.prims.offsets
        for k in range(4):
            sel = (prim >= offsets[k]) & (prim < offsets[k + 1])
            items = (prim[sel] - offsets[k]).to(torch.int32).contiguous()
            kcount = torch.bincount(cell[sel], minlength=n_cells).to(torch.int32)
            start = torch.cumsum(kcount, 0, dtype=torch.int32) - kcount
            aabb = box[:, offsets[k] : offsets[k + 1]].contiguous()
            self.kind_lists.append((items, start, kcount, offsets[k], aabb))

    # ------------------------------------------------------------------------------------------------ queries
    def trace(
        self, origins: torch.Tensor, dirs: torch.Tensor, t_max: torch.Tensor, any_hit: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Nearest (or, with ``any_hit``, some) hit of each ray within ``t_max``.

        Args:
            origins: ``[N, 3]`` ray origins.
            dirs: ``[N, 3]`` unit directions.
            t_max: ``[N]`` largest distance of interest per ray.
            any_hit: stop each ray at the first hit found (a shadow / visibility query); the returned
                distance is then that of *a* hit before ``t_max``, not necessarily the nearest.

        Returns:
            ``t [N]`` float32 distances (``inf`` = no hit within ``t_max``) and ``prim [N]`` int64 ids
            (:data:`GROUND`, :data:`MISS` or a global primitive id).
        """
        n = origins.shape[0]
        t_out = torch.empty(n, dtype=torch.float32, device=origins.device)
        p_out = torch.empty(n, dtype=torch.int64, device=origins.device)
        for s in range(0, n, CHUNK_SIZE):
            e = min(n, s + CHUNK_SIZE)
            t_out[s:e], p_out[s:e] = self._trace_chunk(origins[s:e], dirs[s:e], t_max[s:e], any_hit)
        return t_out, p_out

    def _trace_chunk(
        self, origins: torch.Tensor, dirs: torch.Tensor, t_max: torch.Tensor, any_hit: bool
    ) -> tuple[torch.Tensor, torch.Tensor]:
        rays = torch.cat([origins.T, dirs.T]).to(torch.float32).contiguous()  # [6, N]
        ox, _, oz, _, _, dz = rays
        t_max = t_max.to(torch.float32)
        n_prims = len(self.prims)
        inf = torch.full_like(ox, float("inf"))
        t_ground = torch.where(dz < 0, (self.ground_z - oz) / _safe(dz), inf)
        t_ground = torch.where(t_ground >= 0, t_ground, inf)
        t_lim = torch.minimum(t_ground, t_max)
        init_key = _pack(t_lim, n_prims)
        best = init_key.clone()
        if n_prims:
            self._walk(rays, t_lim, best, init_key, any_hit)
        t, prim = _unpack(best)
        sentinel = prim == n_prims
        ground = sentinel & (t_ground <= t_max)
        prim = torch.where(sentinel, torch.where(ground, GROUND, MISS), prim)
        t = torch.where(sentinel & ~ground, inf, t)
        return t, prim

    def _walk(
        self,
        rays: torch.Tensor,
        t_lim: torch.Tensor,
        best: torch.Tensor,
        init_key: torch.Tensor,
        any_hit: bool,
    ) -> None:
        """Update ``best`` (packed keys, in place) with the primitive hits of every ray up to ``t_lim``."""
        dev = rays.device
        ox, oy, oz, dx, dy, dz = rays
        x0, y0, x1, y1 = self.bounds
        cs = self.cell_size
        # Clip each ray to the grid's box [x0, x1] x [y0, y1] x [z_lo, z_hi].
        t_in = torch.zeros_like(ox)
        t_out = t_lim.clone()
        for o, d, lo, hi in ((ox, dx, x0, x1), (oy, dy, y0, y1), (oz, dz, self.z_lo, self.z_hi)):
            ds = _safe(d)
            ta, tb = (lo - o) / ds, (hi - o) / ds
            t_in = torch.maximum(t_in, torch.minimum(ta, tb))
            t_out = torch.minimum(t_out, torch.maximum(ta, tb))
        ray = _nonzero(t_in <= t_out)
        if ray.numel() == 0:
            return
        t_in, t_out = _take(t_in, ray), _take(t_out, ray)
        sub = _rows(rays, ray)  # the rays that enter the grid's box
        rx, ry, rz, rdx, rdy, rdz = sub
        # Per-ray walk set-up along the dominant horizontal axis ("a"); "b" is the other one.
        major_x = rdx.abs() >= rdy.abs()
        oa, da = torch.where(major_x, rx, ry), torch.where(major_x, rdx, rdy)
        ob, db = torch.where(major_x, ry, rx), torch.where(major_x, rdy, rdx)
        a0 = torch.where(major_x, x0, y0)
        b0 = torch.where(major_x, y0, x0)
        i32 = torch.int32  # cell arithmetic in int32: half the memory traffic of int64
        na = torch.where(major_x, self.nx, self.ny).to(i32)
        nb = torch.where(major_x, self.ny, self.nx).to(i32)
        # Cell id = iy * nx + ix = ia * stride_a + ib * stride_b.
        stride_a = torch.where(major_x, 1, self.nx).to(i32)
        stride_b = torch.where(major_x, self.nx, 1).to(i32)
        step = torch.where(da < 0, -1, 1).to(i32)
        zero = torch.zeros_like(na)
        col_first = torch.floor((oa + t_in * da - a0) / cs).to(i32).clamp(zero, na - 1)
        col_last = torch.floor((oa + t_out * da - a0) / cs).to(i32).clamp(zero, na - 1)
        n_col = ((col_last - col_first) * step + 1).clamp(min=1)
        da_safe = _safe(da)
        flat_a = da.abs() < 1e-12
        per_ray = torch.stack([oa, da_safe, ob, db, rz, rdz, a0, b0, t_in, t_out, rx, rdx, ry, rdy])
        per_ray_i = torch.stack([col_first, step, nb - 1, stride_a, stride_b, n_col])

        k0, width = 0, self.first_round
        act = torch.arange(ray.numel(), device=dev)
        while act.numel():
            # Dense [W, A] tables over the W columns of this round and the A active rays (broadcast, no
            # gathers; the long axis innermost so that the elementwise kernels vectorise).
            oa_, da_, ob_, db_, oz_, dz_, a0_, b0_, tin_, tout_, ox_, dx_, oy_, dy_ = _rows(per_ray, act)
            first_, step_, nbm_, sa_, sb_, ncol_ = _rows(per_ray_i, act)
            n_act = act.numel()
            j = torch.arange(k0, k0 + width, device=dev, dtype=i32).unsqueeze(1)
            col = first_ + step_ * j
            # Column's distance interval along the ray.
            a_lo = a0_ + col * cs
            ta, tb = (a_lo - oa_) / da_, (a_lo + cs - oa_) / da_
            tc0 = torch.maximum(torch.minimum(ta, tb), tin_)
            tc1 = torch.minimum(torch.maximum(ta, tb), tout_)
            # Cells of the other axis crossed inside the column: one, or two (|db| <= |da|).
            bs, be = ob_ + tc0 * db_, ob_ + tc1 * db_
            zero = torch.zeros_like(nbm_)
            ib_lo = torch.floor((torch.minimum(bs, be) - b0_) / cs).to(i32).clamp(zero, nbm_)
            ib_hi = torch.floor((torch.maximum(bs, be) - b0_) / cs).to(i32).clamp(zero, nbm_)
            zs, ze = oz_ + tc0 * dz_, oz_ + tc1 * dz_
            z_lo, z_hi = torch.minimum(zs, ze), torch.maximum(zs, ze)
            live = (j < ncol_) & (tc0 <= tc1)
            base = col * sa_ + ib_lo * sb_
            cells, oks = [], []
            for k in range(2):  # [2, W, A] as two slabs
                ok = live & (ib_lo < ib_hi) if k else live
                cell = ((base + sb_) if k else base) * ok  # 0 where not ok (torch.where is slow on CPU)
                cell = cell.reshape(-1)
                # Empty cells have z range [inf, -inf], so this also drops them.
                ok = ok.reshape(-1) & (z_lo.reshape(-1) <= _take(self.cell_zmax, cell))
                ok &= z_hi.reshape(-1) >= _take(self.cell_zmin, cell)
                cells.append(cell)
                oks.append(ok)
            sel = _nonzero(torch.cat(oks))
            if sel.numel():
                slots = width * n_act
                c = sel % slots  # flat (column, ray) slot
                r = c % n_act  # row in the active set
                t0, t1 = _take(tc0.reshape(-1), c), _take(tc1.reshape(-1), c)
                ox_, dx_, oy_, dy_ = _rows(torch.stack([ox_, dx_, oy_, dy_]), r)
                xs, xe = ox_ + t0 * dx_, ox_ + t1 * dx_
                ys, ye = oy_ + t0 * dy_, oy_ + t1 * dy_
                seg = (
                    torch.minimum(xs, xe),
                    torch.minimum(ys, ye),
                    _take(z_lo.reshape(-1), c),
                    torch.maximum(xs, xe),
                    torch.maximum(ys, ye),
                    _take(z_hi.reshape(-1), c),
                )
                self._test_cells(sub, best, ray, _take(act, r), _take(torch.cat(cells), sel), seg)
            # Which rays are finished: all columns visited, or a hit before the end of the visited ones.
            j_last = torch.clamp(ncol_, max=k0 + width) - 1
            col = first_ + step_ * j_last
            a_end = a0_ + (col + (step_ > 0).to(i32)) * cs
            t_end = torch.minimum((a_end - oa_) / da_, tout_)
            t_end = torch.where(_take(flat_a, act), tout_, t_end)
            b_act = _take(best, _take(ray, act))
            best_t, _ = _unpack(b_act)
            done = (j_last >= ncol_ - 1) | (best_t <= t_end)
            if any_hit:
                done |= b_act < _take(init_key, _take(ray, act))
            act = _take(act, _nonzero(~done))
            k0 += width
            width = min(2 * width, self.max_round)

    def _test_cells(
        self,
        sub: torch.Tensor,
        best: torch.Tensor,
        ray: torch.Tensor,
        r: torch.Tensor,
        cell: torch.Tensor,
        seg: tuple[torch.Tensor, ...],
    ) -> None:
        """Intersect ray ``sub[:, r[i]]`` with every primitive listed in ``cell[i]``.

        ``seg`` (six ``[K]`` tensors) is the bounding box of the ray's segment inside the cell's column: primitives whose
        box misses it are culled before the exact test. ``ray`` maps rows of ``sub`` to rows of ``best``.
        """
        for kind, (items, start, count, offset, aabb) in enumerate(self.kind_lists):
            if items.numel() == 0:
                continue
            counts = _take(count, cell)
            pair, total = _expand(counts)
            if total == 0:
                continue
            # Position of each item in the kind's cell lists: the cell's start plus the rank within the cell.
            excl = torch.cumsum(counts, 0, dtype=torch.int32) - counts
            pos = _take(_take(start, cell) - excl, pair) + torch.arange(
                total, dtype=torch.int32, device=sub.device
            )
            local = _take(items, pos)
            bb = _rows(aabb, local)
            sg = [_take(v, pair) for v in seg]
            keep = (
                (sg[0] <= bb[3])
                & (sg[3] >= bb[0])
                & (sg[1] <= bb[4])
                & (sg[4] >= bb[1])
                & (sg[2] <= bb[5])
                & (sg[5] >= bb[2])
            )
            idx = _nonzero(keep)
            if idx.numel() == 0:
                continue
            rr = _take(_take(r, pair), idx)
            local = _take(local, idx)
            t = self.prims.kind_hit_distance(kind, _rows(sub, rr), _rows(self.prims.kind_table(kind), local))
            hit = _nonzero(t < float("inf"))
            if hit.numel():
                key = _pack(_take(t, hit), _take(local, hit).long() + offset)
                best.scatter_reduce_(0, _take(ray, _take(rr, hit)), key, "amin")
