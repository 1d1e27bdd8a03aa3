"""Occlusion methods on scans whose beams do not sit where ``LidarSpec`` puts them, as a real sensor's.

A spinning LiDAR fires at an arbitrary azimuth phase every frame (and per ring), with some jitter, dropped
returns and its own point order. The scans here are built by casting such beams at an analytic scene (boxes in
front of a wall, on the ground), and every point's visibility from the camera is exact (a ray-box test).
"""

from __future__ import annotations

import numpy as np
import pytest

from airfisheye_bench.geometry import ideal_camera
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_layout import organize_scan
from airfisheye_bench.geometry.occlusion import occlusion_mask, ordering_mask, ordering_reference
from airfisheye_bench.studies import lidar_scene
from tests.helpers.occlusion_scenes import rig, seen_from

PAPER = LidarSpec()  # 64 x 2048, 270 deg
CAMERA = ideal_camera(512, 512, fov_deg=190.0)
CAMERA_OFFSET = (0.0, 0.6, 0.4)  # 0.6 m beside (left) and 0.4 m above the LiDAR, looking along its x axis
BENCH = lidar_scene  # one definition of the scene and scan variants, shared with the benchmark
# LiDAR frame (x forward, y left, z up): a wall 20 m ahead, three boxes 5-14 m ahead, the ground 3 m below.
SCENE = BENCH.BOXES_AND_WALL
VARIANTS = ("boundary", "ring phase", "jitter", "shuffled")


def realistic_scan(spec: LidarSpec, variant: str, seed: int = 0, boxes: np.ndarray = SCENE) -> np.ndarray:
    """The spec's beams moved as ``variant`` says, cast at ``boxes`` (``scripts/bench_lidar.py``'s ``scan``).

    ``boundary``: every beam half a column off the spec's column centres (on the cell edges);
    ``ring phase``: a random azimuth phase per ring; ``jitter``: a random phase per ring plus 0.1 cell of
    noise per beam in azimuth and elevation, and 5% of the beams dropped; ``shuffled``: the spec's beams,
    listed in a random order.
    """
    return BENCH.scan(spec, boxes, variant, seed)


def precision_recall(mask: np.ndarray, visible: np.ndarray) -> tuple[float, float]:
    tp = int((mask & visible).sum())
    return tp / max(int(mask.sum()), 1), tp / max(int(visible.sum()), 1)


@pytest.fixture(scope="module")
def scans() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """variant -> (points, T_cam_lidar, exact visibility of the points that project into the image)."""
    centre, T = rig(CAMERA_OFFSET)
    out = {}
    for variant in VARIANTS:
        points = realistic_scan(PAPER, variant)
        visible = occlusion_mask(points, T, CAMERA, PAPER, "none") & seen_from(points, centre, SCENE)
        out[variant] = (points, T, visible)
    return out


@pytest.mark.parametrize("variant", VARIANTS)
def test_ordering_holds_on_realistic_scans(scans, variant: str) -> None:
    points, T, visible = scans[variant]
    projects = occlusion_mask(points, T, CAMERA, PAPER, "none")
    assert (projects & ~visible).sum() >= 500  # the scene does hide points from this camera
    precision, recall = precision_recall(occlusion_mask(points, T, CAMERA, PAPER, "ordering"), visible)
    assert precision >= 0.995 and recall >= 0.97, (variant, precision, recall)
    assert precision > precision_recall(projects, visible)[0]  # it removes hidden points


@pytest.mark.parametrize("variant", VARIANTS)
def test_zbuffer_and_hpr_defaults_are_reasonable(scans, variant: str) -> None:
    points, T, visible = scans[variant]
    for method, bar in (("zbuffer", (0.99, 0.95)), ("hpr", (0.99, 0.95))):
        precision, recall = precision_recall(occlusion_mask(points, T, CAMERA, PAPER, method), visible)
        assert precision >= bar[0] and recall >= bar[1], (method, variant, precision, recall)


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_return_is_tested(variant: str) -> None:
    """Camera at the LiDAR centre (a pure rotation): nothing is hidden, so a method that tests every return
    keeps every point that projects. A return left out of ``I_LiDAR`` (a lost cell collision) would show."""
    spec = LidarSpec(channels=32, points_per_channel=1024)
    points = realistic_scan(spec, variant, seed=1)
    _, T = rig((0.0, 0.0, 0.0), 15.0)
    projects = occlusion_mask(points, T, CAMERA, spec, "none")
    assert projects.sum() > 10_000
    np.testing.assert_array_equal(occlusion_mask(points, T, CAMERA, spec, "ordering"), projects)
    ring, position, _ = organize_scan(points, spec)
    assert (ring >= 0).all()  # every return has its ring...
    assert len(np.unique(ring * len(points) + position)) == len(points)  # ...and its own place in it


@pytest.mark.parametrize("variant", VARIANTS)
def test_implementations_agree_on_realistic_scans(variant: str) -> None:
    """The compiled, vectorised and loop implementations return the same mask when sectors hold 0-2 points."""
    spec = LidarSpec(channels=16, points_per_channel=256)
    points = realistic_scan(spec, variant, seed=2)
    _, T = rig((0.1, 0.5, -0.4), 10.0)
    for options in ({}, {"elevation_tolerance": 0.5}, {"elevation_tolerance": -0.25, "azimuth_window": 8}):
        expected = ordering_reference(points, T, CAMERA, spec, **options)
        for implementation in ("numba", "vectorised"):
            got = ordering_mask(points, T, CAMERA, spec, implementation, **options)
            np.testing.assert_array_equal(got, expected, err_msg=f"{implementation} {options}")
        assert 0 < expected.sum() < occlusion_mask(points, T, CAMERA, spec, "none").sum()
