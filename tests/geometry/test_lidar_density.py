"""``data.lidar.density``'s beam subsets (geometry/lidar_density.py): which beams, and that they give the paper
sensor's pixels with a beam per pixel on its 1536^2 image (``paper``, ``paper_1536``) or on a 512^2 one
(``paper_512``)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry import CAM_FROM_FLU, CameraModel, LidarSpec, ideal_camera
from airfisheye_bench.geometry.lidar_density import (
    BeamSubset,
    beam_pixels,
    evenly_spaced,
    paper_camera,
    paper_density_subset,
    shared_pixels,
)
from airfisheye_bench.metrics import DEFAULT_RING_EDGES_DEG

QUICKSTART = LidarSpec(points_per_channel=256)
TINY = LidarSpec(channels=16, points_per_channel=128)


@pytest.mark.parametrize("count", [2, 16, 64, 256])
@pytest.mark.parametrize("stride", [1.0, 1.7, 3.0, 12.5])
def test_evenly_spaced_keeps_both_ends_and_about_one_in_stride(count: int, stride: float) -> None:
    kept = np.flatnonzero(evenly_spaced(count, stride))
    assert kept[0] == 0 and kept[-1] == count - 1
    assert len(kept) == pytest.approx((count - 1) / stride + 1, abs=1)
    assert np.diff(kept).max() - np.diff(kept).min() <= 1  # even gaps


@pytest.mark.parametrize(("spec", "size"), [(QUICKSTART, 128), (QUICKSTART, 64), (TINY, 64), (TINY, 128)])
def test_the_subset_gives_the_paper_beams_per_pixel(spec: LidarSpec, size: int) -> None:
    """Beams per square degree times pixel area: the paper's 64 x 2048 at 1536^2, within the rounding of counts."""
    subset = paper_density_subset(spec, size)
    beams = spec.channels * spec.points_per_channel * subset.fraction
    per_pixel_area = (
        size / 1536
    ) ** 2  # the same FOV (-45..15 deg, 270 deg): beams scale with the pixel count
    assert beams == pytest.approx(64 * 2048 * per_pixel_area, rel=0.1)
    # A square angular grid: the kept channel and column spacings agree within a rounding step.
    dv = 60.0 / (subset.channels.sum() - 1)
    dh = 270.0 / subset.columns.sum()
    assert 0.6 < dv / dh < 1.6


def test_the_paper_sensor_at_its_own_size_and_a_sparse_sensor_keep_every_beam() -> None:
    assert paper_density_subset(LidarSpec(), 1536).fraction == 1.0
    assert paper_density_subset(TINY, 512).fraction == 1.0  # sparser than the paper at 512^2: nothing to drop


def test_the_subset_is_a_function_of_beams_only() -> None:
    """The same beams in every frame, whatever the point order: a return is kept by its (ring, sector)."""
    subset = paper_density_subset(QUICKSTART, 128)
    beams = QUICKSTART.beam_directions().double().numpy().reshape(-1, 3)
    rings = np.repeat(np.arange(QUICKSTART.channels), QUICKSTART.points_per_channel)
    rng = np.random.default_rng(0)
    for _ in range(3):  # another frame: other ranges, another order
        order = rng.permutation(len(beams))
        points = beams[order] * rng.uniform(2.0, 100.0, (len(beams), 1))
        kept = subset.mask(points, rings[order], QUICKSTART)
        expected = (subset.channels[:, None] & subset.columns[None, :]).reshape(-1)[order]
        np.testing.assert_array_equal(kept, expected)
    assert not subset.mask(beams[:1], np.array([-1]), QUICKSTART).any()  # no ring: no beam fired it


def test_the_subset_covers_the_rings_as_the_paper_sensor_does() -> None:
    """Geometrically (every beam returns): pixels hit per pixel of the image circle, by ring, at 64^2 and 128^2
    against the paper's 1536^2 (an equidistant ring holds pi f^2 (theta_hi^2 - theta_lo^2) pixels)."""

    def coverage(spec: LidarSpec, camera: CameraModel, subset: BeamSubset | None) -> np.ndarray:
        hit = beam_pixels(spec, camera, np.asarray(CAM_FROM_FLU), subset)
        theta = torch.acos(camera.unproject(hit.double())[:, 2].clamp(-1, 1))
        edges = np.radians(DEFAULT_RING_EDGES_DEG)
        counts = np.histogram(theta.numpy(), edges)[0]
        f = camera.width / np.radians(190.0)
        return counts / (np.pi * f**2 * np.diff(edges**2))

    paper = coverage(LidarSpec(), paper_camera(), None)
    assert paper == pytest.approx([0.10, 0.063, 0.036, 0.028], abs=0.005)  # a few per cent, centre to rim
    for spec, size in ((QUICKSTART, 128), (TINY, 64)):
        served = coverage(spec, ideal_camera(size, size), paper_density_subset(spec, size))
        np.testing.assert_allclose(served, paper, rtol=0.25)


def test_the_512_reading_covers_the_rings_as_the_paper_sensor_does_at_512() -> None:
    """The paper sensor projected at 512^2: its columns share pixels, so its pixels with a beam are 2.7 times fewer
    than its beams' count would give (``shared_pixels``); the subset covers each ring as that image does."""

    def coverage(spec: LidarSpec, camera: CameraModel, subset: BeamSubset | None) -> np.ndarray:
        hit = beam_pixels(spec, camera, np.asarray(CAM_FROM_FLU), subset)
        theta = torch.acos(camera.unproject(hit.double())[:, 2].clamp(-1, 1))
        edges = np.radians(DEFAULT_RING_EDGES_DEG)
        f = camera.width / np.radians(190.0)
        return np.histogram(theta.numpy(), edges)[0] / (np.pi * f**2 * np.diff(edges**2))

    at_512 = coverage(LidarSpec(), paper_camera(512), None)
    at_1536 = coverage(LidarSpec(), paper_camera(), None)
    assert 2.5 < shared_pixels(LidarSpec(), 512) < 3.0
    assert np.all(at_512 > 2.5 * at_1536) and np.all(at_512 < 9 * at_1536)  # denser, not nine times
    served = coverage(
        QUICKSTART, ideal_camera(128, 128), paper_density_subset(QUICKSTART, 128, image_size=512)
    )
    np.testing.assert_allclose(served, at_512, rtol=0.25)
