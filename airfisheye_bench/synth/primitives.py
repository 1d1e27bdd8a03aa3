"""Analytic ray-primitive intersections, vectorised over (ray, primitive) pairs.

Three convex primitive kinds cover every object of the synthetic scenes:

* **box** — a box rotated about the vertical axis (yaw), optionally cut by sloped half-spaces
  ``z + sx |x| <= hz`` and ``z + sy |y| <= hz`` in its own frame. ``sx = sy = 0`` is a plain box (walls,
  vehicles, fences, flat roofs); ``sx = 0, sy = 2 hz / hy`` a gable roof with its ridge along the local x axis;
  both non-zero a hip / pyramid roof. Parameters (rows of a ``[10, P]`` table):
  ``cx, cy, cz, hx, hy, hz, cos(yaw), sin(yaw), sx, sy`` (centre and half extents in metres). Sloped boxes
  (roofs) have an 11th row ``kx``, the half-length of the ridge along x: the x half-spaces are
  ``z + sx (|x| - kx) <= hz`` (``kx = 0`` gives a pyramid, ``kx = hx - hy`` a hip roof).
* **cylinder** — vertical, capped: ``cx, cy, r, z0, z1`` (poles, tree trunks).
* **ellipsoid** — axis-aligned: ``cx, cy, cz, rx, ry, rz`` (tree crowns, bushes).

Every function takes the ray components as a ``[6, K]`` tensor (``ox, oy, oz, dx, dy, dz``) and the
primitive parameters as ``[n_params, K]`` (one column per pair), and returns per-pair results. Only IEEE-exact
operations (+, -, *, /, sqrt, min, max, comparisons) are used on ray data, and no reductions across pairs,
so a ray's result never depends on how the rays were batched (vectorised and scalar tails round alike).

Example:
    >>> import torch
    >>> rays = torch.tensor([[0.0], [0.0], [1.0], [1.0], [0.0], [0.0]])      # from (0, 0, 1) along +x
    >>> box = torch.tensor([[5.0], [0.0], [1.0], [1.0], [1.0], [1.0], [1.0], [0.0], [0.0], [0.0]])
    >>> box_hit_distance(rays, box).tolist()                                  # box spans x in [4, 6]
    [4.0]
"""

from __future__ import annotations

import torch

from airfisheye_bench.geometry import portable
from airfisheye_bench.synth._ops import select as _select

__all__ = [
    "BOX_PARAMS",
    "CYLINDER_PARAMS",
    "ELLIPSOID_PARAMS",
    "ROOF_PARAMS",
    "box_hit_distance",
    "box_surface",
    "cylinder_hit_distance",
    "cylinder_surface",
    "ellipsoid_hit_distance",
    "ellipsoid_surface",
]

BOX_PARAMS = ("cx", "cy", "cz", "hx", "hy", "hz", "cos", "sin", "sx", "sy")
ROOF_PARAMS = (*BOX_PARAMS, "kx")
CYLINDER_PARAMS = ("cx", "cy", "r", "z0", "z1")
ELLIPSOID_PARAMS = ("cx", "cy", "cz", "rx", "ry", "rz")

_TINY = 1e-30
_BIG = 3.0e38


def _safe(den: torch.Tensor) -> torch.Tensor:
    """Nudge exact zeros (a ray parallel to a slab) to +-1e-30, so the slab spans +-huge but finite distances.

    Normal values are unchanged (1e-30 is far below their last bit).
    """
    return den + torch.copysign(torch.full_like(den, _TINY), den)


def _choose(t_near: torch.Tensor, t_far: torch.Tensor, hit: torch.Tensor, t_min: float) -> torch.Tensor:
    """First crossing beyond ``t_min``: the entry, or the exit when the ray starts inside; ``inf`` otherwise.

    ``t_near`` and ``t_far`` are finite (the kernels keep them within +-_BIG).
    """
    t = _select(t_near > t_min, t_near, t_far)
    valid = hit & (t_far > t_min)
    # Dividing a positive distance by 1 (valid) or 0 (invalid) gives it back or +inf, without a branchy where.
    return t.clamp(min=_TINY) / valid.to(t.dtype)


def _facing_normal(nx: torch.Tensor, ny: torch.Tensor, nz: torch.Tensor, rays: torch.Tensor) -> torch.Tensor:
    """Stack a normal ``[K, 3]`` and flip it to face the incoming ray (explicit sums: batch-independent)."""
    flip = (nx * rays[3] + ny * rays[4] + nz * rays[5]) > 0
    sign = 1.0 - 2.0 * flip.to(nx.dtype)
    return torch.stack([nx * sign, ny * sign, nz * sign], dim=-1)


def _box_local(rays: torch.Tensor, p: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Ray origin and direction in the box frame (yaw removed, origin at the box centre)."""
    ox, oy, oz, dx, dy, dz = rays
    c, s = p[6], p[7]
    rx, ry = ox - p[0], oy - p[1]
    lx = c * rx + s * ry
    ly = c * ry - s * rx
    lz = oz - p[2]
    ex = c * dx + s * dy
    ey = c * dy - s * dx
    return lx, ly, lz, ex, ey, dz


def _box_interval(
    rays: torch.Tensor, p: torch.Tensor, sloped: bool, track: bool = False
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor | None, torch.Tensor | None]:
    """Entry/exit distances, a hit flag and (with ``track``) the index of the entering and exiting plane.

    Planes 0-5 are -x, +x, -y, +y, -z, +z; 6-9 are the sloped planes with normals (+-sx, 0, 1), (0, +-sy, 1)
    (only with ``sloped``, which needs the 11-row roof table). Without ``track`` only min / max and exact
    blends are used (fast); with it the plane ids are followed too (the winner pass, one pair per ray).
    """
    lx, ly, lz, ex, ey, ez = _box_local(rays, p)
    t_near = torch.full_like(lx, -_BIG)
    t_far = torch.full_like(lx, _BIG)
    near_id = far_id = None
    if track:
        near_id = torch.zeros(lx.shape, dtype=torch.uint8, device=lx.device)
        far_id = torch.zeros_like(near_id)
    for axis, (pos, e, h) in enumerate(((lx, ex, p[3]), (ly, ey, p[4]), (lz, ez, p[5]))):
        e = _safe(e)
        t_lo = (-h - pos) / e  # crossing of the negative face
        t_hi = (h - pos) / e
        tn, tf = torch.minimum(t_lo, t_hi), torch.maximum(t_lo, t_hi)
        if track:
            neg_first = (t_lo < t_hi).to(torch.uint8)
            near_id = torch.where(tn > t_near, 2 * axis + 1 - neg_first, near_id)
            far_id = torch.where(tf < t_far, 2 * axis + neg_first, far_id)
        t_near = torch.maximum(t_near, tn)
        t_far = torch.minimum(t_far, tf)
    if sloped:
        hz = p[5]
        hz_x = hz + p[8] * p[10]  # the x planes are shifted out by the ridge half-length
        for k, (a, b) in enumerate(((p[8], None), (-p[8], None), (None, p[9]), (None, -p[9]))):
            # Half-space a*x + b*y + z <= hz in the box frame: entered where the ray goes against its normal.
            if a is not None:
                den = _safe(a * ex + ez)
                num = hz_x - (a * lx + lz)
            else:
                den = _safe(b * ey + ez)
                num = hz - (b * ly + lz)
            t = num / den
            entering = den < 0
            tn = _select(entering, t, torch.full_like(t, -_BIG))
            tf = _select(entering, torch.full_like(t, _BIG), t)
            if track:
                near_id = torch.where(tn > t_near, 6 + k, near_id)
                far_id = torch.where(tf < t_far, 6 + k, far_id)
            t_near = torch.maximum(t_near, tn)
            t_far = torch.minimum(t_far, tf)
    return t_near, t_far, t_near <= t_far, near_id, far_id


def box_hit_distance(
    rays: torch.Tensor, params: torch.Tensor, t_min: float = 0.0, sloped: bool = False
) -> torch.Tensor:
    """Distance to the first surface crossing beyond ``t_min`` (``inf`` when the ray misses).

    Args:
        rays: ``[6, K]`` ray origins and unit directions.
        params: ``[10, K]`` box parameters (see :data:`BOX_PARAMS`), ``[11, K]`` with ``sloped``.
        t_min: crossings at or before this distance are ignored.
        sloped: also apply the sloped roof half-spaces (``sx``, ``sy``); plain boxes skip them for speed.

    Returns:
        ``[K]`` float distances.
    """
    t_near, t_far, hit, _, _ = _box_interval(rays, params, sloped)
    return _choose(t_near, t_far, hit, t_min)


def box_surface(
    rays: torch.Tensor, params: torch.Tensor, t_min: float = 0.0, sloped: bool = False
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Surface data at the hit of each (ray, box) pair (the pair must hit).

    Returns:
        ``normal [K, 3]`` (world frame, facing the ray), ``uv [K, 2]`` face coordinates in metres
        (side faces: horizontal position along the face from its left end, and height above the box bottom;
        top and sloped faces: local x, y) and ``face [K]`` (``uint8``: 0 side, 1 top/sloped, 2 bottom).
    """
    t_near, t_far, _, near_id, far_id = _box_interval(rays, params, sloped, track=True)
    inside = ~(t_near > t_min)
    plane = torch.where(inside, far_id, near_id).long()
    t = torch.where(inside, t_far, t_near)
    lx, ly, lz, ex, ey, ez = _box_local(rays, params)
    hx, hy, hz, c, s = params[3], params[4], params[5], params[6], params[7]
    px, py, pz = lx + t * ex, ly + t * ey, lz + t * ez
    zero, one = torch.zeros_like(px), torch.ones_like(px)
    # Local normals of the 10 planes, selected per pair.
    sx, sy = params[8], params[9]
    nx_tab = torch.stack([-one, one, zero, zero, zero, zero, sx, -sx, zero, zero])
    ny_tab = torch.stack([zero, zero, -one, one, zero, zero, zero, zero, sy, -sy])
    nz_tab = torch.stack([zero, zero, zero, zero, -one, one, one, one, one, one])
    sel = plane.unsqueeze(0)
    nlx = nx_tab.gather(0, sel)[0]
    nly = ny_tab.gather(0, sel)[0]
    nlz = nz_tab.gather(0, sel)[0]
    norm = portable.sqrt(nlx * nlx + nly * nly + nlz * nlz)
    nlx, nly, nlz = nlx / norm, nly / norm, nlz / norm
    nwx = c * nlx - s * nly
    nwy = s * nlx + c * nly
    normal = _facing_normal(nwx, nwy, nlz, rays)
    # Face coordinates: along-face position (counter-clockwise seen from above) and height above the bottom.
    u_side = torch.where(
        plane == 0, hy - py, torch.where(plane == 1, py + hy, torch.where(plane == 2, px + hx, hx - px))
    )
    is_side = plane < 4
    u = torch.where(is_side, u_side, px)
    v = torch.where(is_side, pz + hz, py)
    face = torch.where(is_side, 0, torch.where(plane == 4, 2, 1)).to(torch.uint8)
    return normal, torch.stack([u, v], dim=-1), face


def _cylinder_interval(rays: torch.Tensor, p: torch.Tensor) -> tuple[torch.Tensor, ...]:
    ox, oy, oz, dx, dy, dz = rays
    px, py = ox - p[0], oy - p[1]
    a = dx * dx + dy * dy + _TINY  # > 0; a vertical ray gets a huge but finite radial interval
    # Shift to the point of closest approach first: avoids cancellation for far-away cylinders.
    t_c = -(px * dx + py * dy) / a
    qx, qy = px + t_c * dx, py + t_c * dy
    c = qx * qx + qy * qy - p[2] * p[2]
    half = portable.sqrt(torch.clamp(-c / a, min=0.0))
    ts0, ts1 = t_c - half, t_c + half
    ez = _safe(dz)
    tz0 = (p[3] - oz) / ez
    tz1 = (p[4] - oz) / ez
    tzn, tzf = torch.minimum(tz0, tz1), torch.maximum(tz0, tz1)
    cap_near = tzn > ts0
    cap_far = tzf < ts1
    t_near = torch.maximum(tzn, ts0)
    t_far = torch.minimum(ts1, tzf)
    hit = (c <= 0) & (t_near <= t_far)
    return t_near, t_far, hit, cap_near, cap_far


def cylinder_hit_distance(rays: torch.Tensor, params: torch.Tensor, t_min: float = 0.0) -> torch.Tensor:
    """Distance to the first crossing of a vertical capped cylinder (``params [5, K]``) beyond ``t_min``."""
    t_near, t_far, hit, _, _ = _cylinder_interval(rays, params)
    return _choose(t_near, t_far, hit, t_min)


def cylinder_surface(
    rays: torch.Tensor, params: torch.Tensor, t_min: float = 0.0
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Normal ``[K, 3]`` (facing the ray), ``uv [K, 2]`` (world x + y, height above the base) and face
    (0 side, 1 cap) at the hit of each (ray, cylinder) pair."""
    t_near, t_far, _, cap_near, cap_far = _cylinder_interval(rays, params)
    inside = ~(t_near > t_min)
    t = torch.where(inside, t_far, t_near)
    cap = torch.where(inside, cap_far, cap_near)
    ox, oy, oz, dx, dy, dz = rays
    hx, hy, hz = ox + t * dx, oy + t * dy, oz + t * dz
    rx, ry = hx - params[0], hy - params[1]
    rn = portable.sqrt(rx * rx + ry * ry)
    rn = torch.where(rn > 0, rn, torch.ones_like(rn))
    zero = torch.zeros_like(rx)
    nx = torch.where(cap, zero, rx / rn)
    ny = torch.where(cap, zero, ry / rn)
    nz = torch.where(cap, torch.ones_like(rx), zero)
    normal = _facing_normal(nx, ny, nz, rays)
    uv = torch.stack([hx + hy, hz - params[3]], dim=-1)
    return normal, uv, cap.to(torch.uint8)


def _ellipsoid_interval(rays: torch.Tensor, p: torch.Tensor) -> tuple[torch.Tensor, ...]:
    ox, oy, oz, dx, dy, dz = rays
    px, py, pz = (ox - p[0]) / p[3], (oy - p[1]) / p[4], (oz - p[2]) / p[5]
    qx, qy, qz = dx / p[3], dy / p[4], dz / p[5]
    a = qx * qx + qy * qy + qz * qz
    t_c = -(px * qx + py * qy + pz * qz) / a
    mx, my, mz = px + t_c * qx, py + t_c * qy, pz + t_c * qz
    c = mx * mx + my * my + mz * mz - 1.0
    half = portable.sqrt(torch.clamp(-c / a, min=0.0))
    return t_c - half, t_c + half, c <= 0


def ellipsoid_hit_distance(rays: torch.Tensor, params: torch.Tensor, t_min: float = 0.0) -> torch.Tensor:
    """Distance to the first crossing of an axis-aligned ellipsoid (``params [6, K]``) beyond ``t_min``."""
    t_near, t_far, hit = _ellipsoid_interval(rays, params)
    return _choose(t_near, t_far, hit, t_min)


def ellipsoid_surface(
    rays: torch.Tensor, params: torch.Tensor, t_min: float = 0.0
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Normal ``[K, 3]`` (facing the ray), ``uv [K, 2]`` (world x + 0.5 z, y - 0.5 z) and face (all 0)."""
    t_near, t_far, _ = _ellipsoid_interval(rays, params)
    t = torch.where(t_near > t_min, t_near, t_far)
    ox, oy, oz, dx, dy, dz = rays
    hx, hy, hz = ox + t * dx, oy + t * dy, oz + t * dz
    gx = (hx - params[0]) / (params[3] * params[3])
    gy = (hy - params[1]) / (params[4] * params[4])
    gz = (hz - params[2]) / (params[5] * params[5])
    gn = portable.sqrt(gx * gx + gy * gy + gz * gz)
    normal = _facing_normal(gx / gn, gy / gn, gz / gn, rays)
    uv = torch.stack([hx + 0.5 * hz, hy - 0.5 * hz], dim=-1)
    return normal, uv, torch.zeros_like(hx, dtype=torch.uint8)
