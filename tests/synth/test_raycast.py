"""Ray-primitive intersections against analytic answers, and the grid tracer against brute force."""

from __future__ import annotations

import math

import pytest
import torch

from airfisheye_bench.synth import raycast
from airfisheye_bench.synth.primitives import (
    box_hit_distance,
    box_surface,
    cylinder_hit_distance,
    cylinder_surface,
    ellipsoid_hit_distance,
    ellipsoid_surface,
)
from airfisheye_bench.synth.raycast import GROUND, MISS, PrimitiveSet, RayTracer


def rays_of(origins, dirs) -> torch.Tensor:
    o = torch.as_tensor(origins, dtype=torch.float32).reshape(-1, 3)
    d = torch.as_tensor(dirs, dtype=torch.float32).reshape(-1, 3)
    d = d / d.norm(dim=1, keepdim=True)
    return torch.cat([o.T, d.T]).contiguous()


def col(*values) -> torch.Tensor:
    return torch.tensor(values, dtype=torch.float32).reshape(-1, 1)


def box(cx, cy, cz, hx, hy, hz, yaw=0.0) -> torch.Tensor:
    return col(cx, cy, cz, hx, hy, hz, math.cos(yaw), math.sin(yaw), 0.0, 0.0)


# ---------------------------------------------------------------------------------------------- primitives
def test_axis_aligned_box_from_all_six_sides():
    p = box(0, 0, 0, 1, 2, 3).expand(10, 6)
    origins = [[-10, 0, 0], [10, 0, 0], [0, -10, 0], [0, 10, 0], [0, 0, -10], [0, 0, 10]]
    dirs = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    t = box_hit_distance(rays_of(origins, dirs), p)
    assert t.tolist() == [9.0, 9.0, 8.0, 8.0, 7.0, 7.0]
    normal, _, face = box_surface(rays_of(origins, dirs), p)
    expected = -torch.tensor(dirs, dtype=torch.float32)  # each face's normal points back at the ray
    assert torch.allclose(normal, expected, atol=1e-6)
    assert face.tolist() == [0, 0, 0, 0, 2, 1]


def test_box_misses_and_inside_origin():
    p = box(0, 0, 0, 1, 1, 1).expand(10, 3)
    r = rays_of([[-10, 5, 0], [0, 0, 0], [5, 0, 0]], [[1, 0, 0], [1, 0, 0], [1, 0, 0]])
    t = box_hit_distance(r, p)
    assert math.isinf(t[0]) and t[1] == 1.0 and math.isinf(t[2])  # miss, exit from inside, box behind


def test_rotated_box_hits_its_corner():
    # A unit-half-size square turned by 45 degrees presents a corner at distance sqrt(2) from its centre.
    p = box(10, 0, 0, 1, 1, 1, yaw=math.pi / 4)
    t = box_hit_distance(rays_of([0, 0, 0], [1, 0, 0]), p)
    assert t.item() == pytest.approx(10 - math.sqrt(2), abs=1e-5)


@pytest.mark.parametrize("shape", ["gable", "pyramid", "hip"])
def test_roofs_follow_their_slopes(shape):
    hx, hy, hz = 4.0, 2.0, 1.0  # roof from z = 0 (eaves) to 2 (ridge), centred at z = 1
    slopes = {
        "gable": (0.0, 2 * hz / hy, 0.0),
        "pyramid": (2 * hz / hx, 2 * hz / hy, 0.0),
        "hip": (2 * hz / hy, 2 * hz / hy, hx - hy),
    }
    sx, sy, kx = slopes[shape]
    p = col(0, 0, hz, hx, hy, hz, 1, 0, sx, sy, kx).expand(11, 4)
    xs, ys = [0.0, 0.0, 3.0, 3.0], [0.0, 1.0, 0.0, 1.5]
    r = rays_of([[x, y, 10] for x, y in zip(xs, ys, strict=True)], [[0, 0, -1]] * 4)
    t = box_hit_distance(r, p, sloped=True)
    for k, (x, y) in enumerate(zip(xs, ys, strict=True)):
        top = min(2 * hz - sy * abs(y), 2 * hz - sx * (abs(x) - kx), 2 * hz)  # the analytic roof surface
        assert t[k].item() == pytest.approx(10 - top, abs=1e-5), (shape, x, y)
    normal, _, face = box_surface(r, p, sloped=True)
    assert (face == 1).all()
    if shape == "gable":  # the slope at y = 1 faces +y and up: normal ~ (0, sy, 1) normalised
        n = torch.tensor([0.0, sy, 1.0]) / math.hypot(sy, 1.0)
        assert torch.allclose(normal[1], n, atol=1e-5)


def test_cylinder_side_cap_and_miss():
    p = col(5, 0, 0.5, 0, 4).expand(5, 3)
    r = rays_of([[0, 0, 2], [5, 0, 10], [0, 0, 6]], [[1, 0, 0], [0, 0, -1], [1, 0, 0]])
    t = cylinder_hit_distance(r, p)
    assert t[0].item() == pytest.approx(4.5) and t[1].item() == pytest.approx(6.0) and math.isinf(t[2])
    normal, _, face = cylinder_surface(r[:, :2], p[:, :2])
    assert torch.allclose(normal, torch.tensor([[-1.0, 0, 0], [0, 0, 1.0]]), atol=1e-6)
    assert face.tolist() == [0, 1]


def test_ellipsoid_along_axes_and_oblique():
    p = col(0, 0, 5, 2, 3, 1).expand(6, 3)
    r = rays_of([[-10, 0, 5], [0, 0, 20], [-10, -10, 5]], [[1, 0, 0], [0, 0, -1], [1, 1, 0]])
    t = ellipsoid_hit_distance(r, p)
    # Oblique ray along x = y: enters where x^2 / 4 + x^2 / 9 = 1.
    x = math.sqrt(1 / (1 / 4 + 1 / 9))
    assert t[0].item() == pytest.approx(8.0) and t[1].item() == pytest.approx(14.0)
    assert t[2].item() == pytest.approx(math.sqrt(2) * (10 - x), abs=1e-4)
    normal, _, _ = ellipsoid_surface(r[:, :1], p[:, :1])
    assert torch.allclose(normal, torch.tensor([[-1.0, 0, 0]]), atol=1e-6)


# ------------------------------------------------------------------------------------------------- tracer
def random_prims(n: int, seed: int = 1) -> PrimitiveSet:
    g = torch.Generator().manual_seed(seed)

    def u(a, b):
        return a + (b - a) * torch.rand(n, generator=g)

    yaw = u(0, 6.28)
    hz = u(0.5, 8)
    boxes = torch.stack(
        [u(-40, 40), u(-40, 40), hz, u(0.2, 6), u(0.2, 6), hz, yaw.cos(), yaw.sin(), 0 * hz, 0 * hz]
    )
    rz, ry, rx = u(0.5, 3), u(1, 5), u(1, 6)
    roofs = torch.stack(
        [
            u(-40, 40),
            u(-40, 40),
            8 + rz,
            rx,
            ry,
            rz,
            yaw.cos(),
            yaw.sin(),
            u(0, 1) * 2 * rz / rx,
            2 * rz / ry,
            u(0, 1),
        ]
    )
    cyl = torch.stack([u(-40, 40), u(-40, 40), u(0.1, 1), 0 * hz, u(1, 10)])
    ell = torch.stack([u(-40, 40), u(-40, 40), u(2, 10), u(0.5, 4), u(0.5, 4), u(0.5, 3)])
    return PrimitiveSet(boxes, roofs, cyl, ell)


def brute_force(prims: PrimitiveSet, o: torch.Tensor, d: torch.Tensor, t_max: float):
    """Every ray against every primitive (the kernels broadcast over a [rays, primitives] grid)."""
    rays = torch.cat([o.T, d.T]).unsqueeze(2)  # [6, N, 1]
    t_all = torch.cat(
        [
            box_hit_distance(rays, prims.boxes.unsqueeze(1)),
            box_hit_distance(rays, prims.roofs.unsqueeze(1), sloped=True),
            cylinder_hit_distance(rays, prims.cylinders.unsqueeze(1)),
            ellipsoid_hit_distance(rays, prims.ellipsoids.unsqueeze(1)),
        ],
        dim=1,
    )  # [N, P] in global-id order
    t_obj, p_obj = t_all.min(1)
    t_g = torch.where(d[:, 2] < 0, -o[:, 2] / d[:, 2], torch.tensor(float("inf")))
    ground = t_g < t_obj
    t = torch.where(ground, t_g, t_obj)
    prim = torch.where(ground, GROUND, p_obj)
    miss = t > t_max
    return torch.where(miss, float("inf"), t), torch.where(miss, MISS, prim)


@pytest.fixture(scope="module")
def scene_rays():
    prims = random_prims(120)
    g = torch.Generator().manual_seed(2)
    n = 4000
    o = torch.rand(n, 3, generator=g) * torch.tensor([120.0, 120.0, 30.0]) - torch.tensor([60.0, 60.0, 0.0])
    d = torch.randn(n, 3, generator=g)
    d = d / d.norm(dim=1, keepdim=True)
    return prims, o, d


@pytest.fixture(scope="module")
def reference(scene_rays):
    return brute_force(*scene_rays, t_max=300.0)


@pytest.mark.parametrize("cell_size", [2.0, 8.0, 50.0])
def test_grid_tracer_matches_brute_force(scene_rays, reference, cell_size):
    prims, o, d = scene_rays
    tracer = RayTracer(prims, (-50, -50, 50, 50), cell_size=cell_size)
    t, prim = tracer.trace(o, d, torch.full((o.shape[0],), 300.0))
    t_ref, p_ref = reference
    assert torch.equal(torch.isinf(t), torch.isinf(t_ref))
    assert torch.equal(t[torch.isfinite(t)], t_ref[torch.isfinite(t_ref)])  # same kernels: bit-identical
    # Ids agree except where an object's face lies exactly on the ground at the hit (a tie).
    differ = prim != p_ref
    assert bool(((p_ref[differ] == GROUND) & (prim[differ] >= 0)).all())


def test_any_hit_reports_occlusion_exactly(scene_rays):
    prims, o, d = scene_rays
    tracer = RayTracer(prims, (-50, -50, 50, 50), cell_size=6.0)
    t_near, _ = tracer.trace(o, d, torch.full((o.shape[0],), 40.0))
    t_any, _ = tracer.trace(o, d, torch.full((o.shape[0],), 40.0), any_hit=True)
    assert torch.equal(torch.isinf(t_any), torch.isinf(t_near))
    hit = torch.isfinite(t_any)
    assert bool((t_any[hit] >= t_near[hit]).all() and (t_any[hit] <= 40.0).all())


def test_nearest_hit_ordering_and_ties():
    # Three boxes on the +x axis, listed far to near: the nearest wins whatever its id.
    prims = PrimitiveSet(
        boxes=torch.cat([box(30, 0, 2, 1, 1, 2), box(20, 0, 2, 1, 1, 2), box(10, 0, 2, 1, 1, 2)], 1)
    )
    tracer = RayTracer(prims, (-40, -40, 40, 40), cell_size=4.0)
    o = torch.tensor([[0.0, 0.0, 1.0], [40.0, 0.0, 1.0]])
    d = torch.tensor([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    t, prim = tracer.trace(o, d, torch.full((2,), 100.0))
    assert t.tolist() == [9.0, 9.0] and prim.tolist() == [2, 0]
    # Two identical boxes: the lower id wins the tie.
    prims = PrimitiveSet(boxes=torch.cat([box(10, 0, 2, 1, 1, 2), box(10, 0, 2, 1, 1, 2)], 1))
    t, prim = RayTracer(prims, (-40, -40, 40, 40)).trace(o[:1], d[:1], torch.full((1,), 100.0))
    assert prim.tolist() == [0]


def test_ground_sky_and_max_distance():
    tracer = RayTracer(PrimitiveSet(), (-10, -10, 10, 10))
    o = torch.tensor([[0.0, 0.0, 10.0]] * 3)
    d = torch.tensor([[0.0, 0.6, -0.8], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    t, prim = tracer.trace(o, d, torch.tensor([100.0, 100.0, 5.0]))
    assert t[0].item() == pytest.approx(12.5) and prim.tolist() == [GROUND, MISS, MISS]
    assert math.isinf(t[1]) and math.isinf(t[2])  # the ground lies beyond max_dist for ray 2


def test_results_do_not_depend_on_chunking_or_order(scene_rays, monkeypatch):
    prims, o, d = scene_rays
    tracer = RayTracer(prims, (-50, -50, 50, 50), cell_size=8.0)
    t_max = torch.full((o.shape[0],), 300.0)
    t_ref, p_ref = tracer.trace(o, d, t_max)
    monkeypatch.setattr(raycast, "CHUNK_SIZE", 777)
    t, prim = tracer.trace(o, d, t_max)
    assert torch.equal(t, t_ref) and torch.equal(prim, p_ref)
    perm = torch.randperm(o.shape[0], generator=torch.Generator().manual_seed(0))
    t, prim = tracer.trace(o[perm], d[perm], t_max)
    assert torch.equal(t, t_ref[perm]) and torch.equal(prim, p_ref[perm])
    for i in (0, 17, 123):  # one ray at a time
        t1, p1 = tracer.trace(o[i : i + 1], d[i : i + 1], t_max[:1])
        assert torch.equal(t1, t_ref[i : i + 1]) and torch.equal(p1, p_ref[i : i + 1])


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="boxes"):
        PrimitiveSet(boxes=torch.zeros(9, 2))
    with pytest.raises(ValueError, match="bounds"):
        RayTracer(PrimitiveSet(), (0, 0, -1, 1))
