"""``data.lidar.density=paper`` (``paper_1536``) and ``paper_512`` as served: the sparse input of the tiny preset has
the paper sensor's pixels per ground-truth pixel on its 1536^2 image, ring by ring, from a fixed subset of every
frame's beams; the 512^2 reading serves more of them, with the correction deciding at 512^2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_density import paper_density_subset, paper_scale_camera, reading_size
from airfisheye_bench.geometry.occlusion import lidar_depth_map, occlusion_mask
from datamodules import AirFisheyeDataModule
from datamodules.coverage import sparse_coverage


def _split(tiny_dataset: Path, density: str, split: str = "train"):
    dm = AirFisheyeDataModule(
        "completion", root=tiny_dataset, camera={"size": 64}, lidar={"density": density}
    )
    return dm.split_dataset(split)


def test_paper_density_matches_the_paper_sensor_at_1536_by_ring(tiny_dataset: Path) -> None:
    """The tiny preset at its own size (64^2, a 16 x 128 scan): within 25 % of the paper's 64 x 2048 at 1536^2."""
    coverage = sparse_coverage(_split(tiny_dataset, "paper"), every=2, reference=LidarSpec())
    served, paper = coverage["served"], coverage["model_1536"]
    assert set(served) == set(paper) == {"ring_0-30", "ring_30-60", "ring_60-80", "ring_80-95"}
    for ring, value in served.items():
        assert value == pytest.approx(paper[ring], rel=0.25), ring
    assert all(value < 0.15 for value in served.values())  # a few per cent, not the native 30-75 %


def test_the_same_beams_are_served_in_every_frame(tiny_dataset: Path) -> None:
    """Every sparse return comes from a kept (ring, sector) cell, the density is native's thinned by the subset,
    and serving a frame twice gives the same map (deterministic)."""
    native, paper = _split(tiny_dataset, "native"), _split(tiny_dataset, "paper")
    subset = paper_density_subset(LidarSpec(channels=16, points_per_channel=128), 64)
    for index in range(0, len(paper), 3):
        sample_id = paper.sample_ids[index]
        points, rings, spec = paper.lidar_points(sample_id)
        kept = subset.mask(points, rings, spec)
        assert kept.mean() == pytest.approx(subset.fraction, rel=0.5)
        sparse = paper[index]["sparse_depth"]
        torch.testing.assert_close(sparse, paper[index]["sparse_depth"])
        on_native = native[index]["sparse_depth"]
        # The subset's returns are a subset of the scan: where paper serves a range, native serves one too.
        assert bool((on_native[sparse > 0] > 0).all())
        assert 0 < int((sparse > 0).sum()) < int((on_native > 0).sum()) / 3
    assert np.array_equal(subset.channels, paper_density_subset(spec, 64).channels)


def test_a_bad_density_is_refused_naming_the_key(tiny_dataset: Path) -> None:
    with pytest.raises(
        ConfigError,
        match=r"^data\.lidar\.density='sparse': expected one of native, paper, paper_1536, paper_512 \(",
    ):
        AirFisheyeDataModule("completion", root=tiny_dataset, lidar={"density": "sparse"})


@pytest.mark.parametrize(
    ("method", "density"), [("ordering", "paper"), ("zbuffer", "paper"), ("ordering", "paper_512")]
)
def test_the_correction_decides_on_the_whole_scan_at_the_reading_scale(
    tiny_dataset: Path, method: str, density: str
) -> None:
    """With a paper reading the served input is the subset's share of what the method keeps on the whole scan in
    the same lens at the reading's pixels per degree (1536 or 512 px over 190 deg), not what it keeps of the subset
    at 64^2."""
    dm = AirFisheyeDataModule(
        "completion", root=tiny_dataset, camera={"size": 64}, lidar={"density": density}, occlusion=method
    )
    ds = dm.split_dataset("val")  # tiny's val location has hidden points in view (test_oracle_input)
    size = reading_size(density)
    decides = paper_scale_camera(ds.camera, size)
    assert decides.width == round(64 * size / 190 * ds.camera.coverage_deg / 64)
    for index, sample_id in enumerate(ds.sample_ids):
        points, rings, spec = ds.lidar_points(sample_id)
        T = ds.T_cam_lidar(sample_id)
        subset = paper_density_subset(spec, 64, ds.camera.coverage_deg, image_size=size)
        visible = occlusion_mask(points, T, decides, spec, method, rings)
        served = visible & subset.mask(points, rings, spec)
        expected = lidar_depth_map(points[served], T, ds.camera, spec, "none", max_depth=ds.max_depth)
        sample = ds[index]  # a return rounded onto a border pixel outside the image circle is not served
        expected = torch.from_numpy(expected) * sample["valid_mask"].reshape(expected.shape)
        torch.testing.assert_close(sample["sparse_depth"][0], expected)


def test_paper_is_the_1536_reading_and_512_serves_more_returns(tiny_dataset: Path) -> None:
    """``paper`` serves exactly ``paper_1536`` (a config or record that says ``paper`` keeps its meaning); the 512^2
    reading, nine times the returns per pixel where the scan has them, serves more, and no more than every return."""
    alias, named = _split(tiny_dataset, "paper", "val"), _split(tiny_dataset, "paper_1536", "val")
    dense, native = _split(tiny_dataset, "paper_512", "val"), _split(tiny_dataset, "native", "val")
    for index in range(len(alias)):
        torch.testing.assert_close(alias[index]["sparse_depth"], named[index]["sparse_depth"])
        counts = [int((ds[index]["sparse_depth"] > 0).sum()) for ds in (named, dense, native)]
        assert counts[0] < counts[1] <= counts[2], counts
