"""Scene generation, rendering, ground-truth visibility, flight-planning queries and the class tables."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from airfisheye_bench.synth import raycast
from airfisheye_bench.synth.builder import SceneBuilder
from airfisheye_bench.synth.classes import (
    IGNORE_ID,
    RAW_CLASSES,
    RAW_ID,
    RAW_TO_TRAIN,
    SKY_ID,
    TRAIN_CLASSES,
    raw_to_train_lut,
)
from airfisheye_bench.synth.raycast import GROUND
from airfisheye_bench.synth.scene import ENVIRONMENTS, Lighting, Scene


# --------------------------------------------------------------------------------------------------- classes
def test_class_tables_are_consistent():
    assert [c.id for c in RAW_CLASSES] == list(range(len(RAW_CLASSES)))
    assert [c.id for c in TRAIN_CLASSES] == list(range(len(TRAIN_CLASSES)))
    assert len(RAW_CLASSES) == 23 and len(TRAIN_CLASSES) == 13  # the paper's counts
    assert len({c.name for c in RAW_CLASSES}) == len(RAW_CLASSES)
    assert set(RAW_TO_TRAIN) == {c.id for c in RAW_CLASSES}
    assert set(RAW_TO_TRAIN.values()) == {c.id for c in TRAIN_CLASSES}  # every training class is used
    assert RAW_CLASSES[SKY_ID].name == "sky" and TRAIN_CLASSES[RAW_TO_TRAIN[SKY_ID]].name == "sky"
    assert all(len(c.color) == 3 and all(0 <= v <= 255 for v in c.color) for c in RAW_CLASSES + TRAIN_CLASSES)
    assert max(RAW_TO_TRAIN) < IGNORE_ID
    lut = raw_to_train_lut()
    assert lut.dtype == np.uint8 and lut.shape == (256,) and lut[IGNORE_ID] == IGNORE_ID
    assert all(lut[r] == t for r, t in RAW_TO_TRAIN.items()) and (lut[len(RAW_CLASSES) :] == IGNORE_ID).all()


# ---------------------------------------------------------------------------------------- a constructed scene
def one_box_scene(device="cpu") -> Scene:
    """A 4 x 4 x 6 m house centred at (10, 0) on grass, with a road strip along y = -20."""
    b = SceneBuilder(60.0, np.random.default_rng(0))
    b.paint_rect(-30, -22, 30, -18, "road", (0.3, 0.3, 0.3))
    b.add_box(10, 0, 0, 4, 4, 6, 0.0, "house", (0.8, 0.8, 0.8))
    return Scene(b.finish(), device=device)


def test_raycast_classes_distances_and_normals():
    s = one_box_scene()
    o = torch.tensor([[0.0, 0.0, 3.0], [0.0, 0.0, 3.0], [0.0, -20.0, 10.0], [0.0, 0.0, 3.0]])
    d = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [-0.6, 0.0, -0.8]])
    hits = s.raycast(o, d, max_dist=500.0)
    assert hits.dist[0].item() == pytest.approx(8.0) and hits.raw_id[0].item() == RAW_ID["house"]
    assert torch.allclose(hits.normal[0], torch.tensor([-1.0, 0.0, 0.0]))
    assert math.isinf(hits.dist[1]) and hits.raw_id[1].item() == SKY_ID and hits.prim[1].item() == -2
    assert hits.dist[2].item() == pytest.approx(10.0) and hits.raw_id[2].item() == RAW_ID["road"]
    assert hits.raw_id[3].item() == RAW_ID["grass"] and hits.prim[3].item() == GROUND
    assert hits.dist[3].item() == pytest.approx(3.75)
    assert bool((hits.albedo[[0, 2, 3]] > 0).all()) and bool((hits.albedo[1] == 0).all())


def test_segment_visible_in_front_of_and_behind_a_box():
    s = one_box_scene()
    cam = torch.tensor([0.0, 0.0, 3.0])
    points = torch.tensor(
        [
            [7.0, 0.0, 3.0],  # in front of the box
            [8.0, 0.0, 3.0],  # on its front face (a LiDAR return): visible within tolerance
            [12.0, 0.0, 3.0],  # on its back face
            [20.0, 0.0, 0.0],  # on the ground behind it
            [20.0, 0.0, 14.0],  # in the air, seen over the box (z = 7.4 m at its front face)
            [0.0, 15.0, 0.0],  # ground to the side
        ]
    )
    vis = s.segment_visible(cam.expand_as(points), points)
    assert vis.tolist() == [True, True, False, False, True, True]
    # The same segments reversed (from the points to the camera) agree for the free-space points.
    back = s.segment_visible(points[[0, 4]], cam.expand(2, 3))
    assert back.tolist() == [True, True]


def test_render_shadow_is_darker_and_colours_are_valid():
    s = one_box_scene()
    light = Lighting(sun_elevation_deg=45.0, sun_azimuth_deg=0.0)  # sun in the +x direction
    # Ground points just west (-x, in the box's shadow) and far from the box, seen from straight above.
    xy = torch.tensor([[6.5, 0.0], [-15.0, 10.0]])
    o = torch.cat([xy, torch.full((2, 1), 50.0)], 1)
    d = torch.tensor([[0.0, 0.0, -1.0]]).expand(2, 3)
    rgb, raw, dist = s.render(o, d, light)
    assert raw.tolist() == [RAW_ID["grass"]] * 2 and torch.allclose(dist, torch.full((2,), 50.0))
    assert rgb[0].sum() < 0.8 * rgb[1].sum()
    sky_rgb, sky_raw, sky_dist = s.render(o, -d, light)
    assert sky_raw.tolist() == [SKY_ID] * 2 and bool(torch.isinf(sky_dist).all())
    assert bool(((sky_rgb >= 0) & (sky_rgb <= 1)).all())


def test_flight_planning_queries():
    s = one_box_scene()
    assert s.bounds == (-30.0, -30.0, 30.0, 30.0)
    xy = torch.tensor([[10.0, 0.0], [10.0, 5.0], [-20.0, 20.0], [500.0, 0.0]])
    assert s.ground_height(xy).tolist() == [0.0] * 4
    h0 = s.obstacle_height(xy, 0.0)
    h4 = s.obstacle_height(xy, 4.0)
    assert h0[0].item() == pytest.approx(6.0, abs=0.01) and h0[1].item() == 0.0
    assert h4[1].item() == pytest.approx(6.0, abs=0.01)  # the box is 3 m away
    assert h4[2].item() == 0.0 and h4[3].item() == 0.0
    with pytest.raises(ValueError, match="radius"):
        s.obstacle_height(xy, -1.0)


def test_input_validation():
    s = one_box_scene()
    with pytest.raises(ValueError, match="origins"):
        s.raycast(torch.zeros(4, 2), torch.zeros(4, 2))
    with pytest.raises(ValueError, match="dirs"):
        s.raycast(torch.zeros(4, 3), torch.zeros(3, 3))
    with pytest.raises(ValueError, match="unit"):
        s.raycast(torch.zeros(1, 3), torch.tensor([[0.0, 0.0, 2.0]]))
    with pytest.raises(ValueError, match="max_dist"):
        s.raycast(torch.zeros(1, 3), torch.tensor([[0.0, 0.0, 1.0]]), max_dist=-1.0)
    with pytest.raises(ValueError, match="points"):
        s.segment_visible(torch.zeros(2, 3), torch.zeros(2, 2))
    with pytest.raises(ValueError, match="env"):
        Scene.generate("moon", 0)
    with pytest.raises(ValueError, match="lighting"):
        s.render(torch.zeros(1, 3), torch.tensor([[0.0, 0.0, 1.0]]), lighting=None)


# ------------------------------------------------------------------------------------------- environments
def fisheye_like_rays(n_az: int = 48, n_el: int = 24) -> torch.Tensor:
    az = torch.linspace(0, 2 * math.pi, n_az + 1)[:-1]
    el = torch.linspace(-1.4, 0.6, n_el)
    a, e = torch.meshgrid(az, el, indexing="ij")
    return torch.stack([e.cos() * a.cos(), e.cos() * a.sin(), e.sin()], -1).reshape(-1, 3)


@pytest.mark.parametrize("env", ENVIRONMENTS)
def test_every_environment_generates_and_renders(env):
    scene = Scene.generate(env, seed=3, size_m=160.0)
    again = Scene.generate(env, seed=3, size_m=160.0)
    other = Scene.generate(env, seed=4, size_m=160.0)
    assert scene.num_primitives > 40
    assert torch.equal(scene.tracer.prims.boxes, again.tracer.prims.boxes)
    assert torch.equal(scene.ground_raw, again.ground_raw)
    assert not torch.equal(scene.ground_raw, other.ground_raw)
    d = fisheye_like_rays()
    xy = torch.tensor([[5.0, -3.0]])
    z = scene.obstacle_height(xy, 3.0) + 25.0  # fly clear of the roofs
    o = torch.cat([xy, z[:, None]], 1).expand_as(d)
    rgb, raw, dist = scene.render(o, d, Lighting.random(torch.Generator().manual_seed(1)))
    assert rgb.dtype == torch.float32 and bool(((rgb >= 0) & (rgb <= 1)).all())
    assert raw.dtype == torch.uint8 and int(raw.max()) < len(RAW_CLASSES)
    assert bool((raw == SKY_ID).any()) and bool((raw != SKY_ID).any())
    assert torch.equal(torch.isinf(dist), raw == SKY_ID)
    assert len(set(raw.tolist())) >= 4  # a varied view: sky, ground classes, objects


def test_environments_differ_in_character():
    tall = {}
    for env in ENVIRONMENTS:
        s = Scene.generate(env, seed=0, size_m=200.0)
        tall[env] = float(s.tracer.prim_aabb[5].max())
    assert tall["downtown"] > 2 * tall["suburban"]


def test_render_is_bit_identical_across_chunks_threads_and_batches(monkeypatch):
    scene = Scene.generate("town", seed=0, size_m=120.0)
    d = fisheye_like_rays(40, 20)
    o = torch.tensor([[3.0, 2.0, 30.0]]).expand_as(d).contiguous()
    light = Lighting.random(torch.Generator().manual_seed(7))
    ref = scene.render(o, d, light)
    monkeypatch.setattr(raycast, "CHUNK_SIZE", 97)
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(2 if threads == 1 else 1)
        small = scene.render(o, d, light)
    finally:
        torch.set_num_threads(threads)
    part = scene.render(o[100:300], d[100:300], light)
    for a, b, c in zip(ref, small, part, strict=True):
        assert torch.equal(a, b) and torch.equal(a[100:300], c)


def test_lighting_random_is_deterministic_and_varies():
    a = Lighting.random(torch.Generator().manual_seed(0))
    b = Lighting.random(torch.Generator().manual_seed(0))
    c = Lighting.random(torch.Generator().manual_seed(1))
    assert a == b and a != c
    assert math.isclose(sum(v * v for v in a.sun_direction()), 1.0, rel_tol=1e-9)
    assert a.sun_direction()[2] > 0 and isinstance(a.to_dict()["sky_zenith"], list)
