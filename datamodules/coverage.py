"""How densely the served sparse LiDAR covers the ground truth, by incidence-angle ring, and how densely the paper's
sensor covers the same frames on the paper's 1536^2 image (docs/design.md, "Sparse input density").

:func:`sparse_coverage` measures the ``sparse_depth`` of every ``every``-th frame exactly as the split serves it,
and beside it the yardstick, computed from the LiDAR spec and the camera: the pixels of the paper's
1536^2, 190 deg fisheye that a nominal beam of its 64 x 2048 sensor lands on (turned by the frame's
``T_cam_lidar``), counted where the frame has ground truth (a 1536^2 pixel has it where the served pixel it lies in has; the
ground-truth pixels of a ring are the served ones times the pixel area ratio). Both are sparse pixels per ground-truth pixel; the paper sensor's returns beyond its range
or outside its field of view have no ground truth or no beam either way.
"""

from __future__ import annotations

import torch

from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_density import beam_pixels, paper_camera
from airfisheye_bench.metrics import RingCoverage, ring_edges_for
from airfisheye_bench.specs import get_task
from datamodules.dataset import AirFisheyeDataset
from datamodules.multi_source import MultiSourceDataset

__all__ = ["input_coverage", "sparse_coverage"]


def _parts(dataset: AirFisheyeDataset | MultiSourceDataset) -> list[AirFisheyeDataset]:
    return list(dataset.datasets.values()) if isinstance(dataset, MultiSourceDataset) else [dataset]


def _edges(parts: list[AirFisheyeDataset]) -> tuple[float, ...]:
    return ring_edges_for(max(part.camera.coverage_deg for part in parts))


def sparse_coverage(
    dataset: AirFisheyeDataset | MultiSourceDataset, every: int = 1, reference: LidarSpec | None = None
) -> dict[str, dict[str, float]]:
    """Sparse pixels per ground-truth pixel by ring over every ``every``-th frame of a completion split (every
    source of a mixture pooled): ``{"served": {"ring_0-30": ...}}``, and with a ``reference`` sensor (the paper's:
    ``LidarSpec()``) its coverage of the same frames on the paper's 1536^2 image as ``"paper_1536"``."""
    parts = _parts(dataset)
    edges = _edges(parts)
    served = [RingCoverage(torch.rad2deg(part.camera.theta_grid()), edges) for part in parts]
    paper, camera = RingCoverage(torch.zeros(0), edges), paper_camera()
    for part, coverage in zip(parts, served, strict=True):
        for index in range(0, len(part), every):
            sample = part[index]
            truth = sample["depth"][0]
            coverage.update(sample["sparse_depth"][0], truth)
            if reference is not None:  # the paper's pixels hit by a beam, where the served truth has depth
                hit = beam_pixels(reference, camera, part.T_cam_lidar(sample["sample_id"]))
                theta = torch.rad2deg(torch.acos(camera.unproject(hit.double())[:, 2].clamp(-1.0, 1.0)))
                scale = part.camera.width / camera.width
                u, v = ((hit + 0.5) * scale).long().clamp(max=part.camera.width - 1).unbind(-1)
                has_truth = truth[v, u] > 0
                paper.add_pixels(theta[has_truth], coverage.theta[truth > 0], truth_weight=scale**-2)
    for coverage in served[1:]:
        served[0].add(coverage)
    out = {"served": served[0].compute()}
    if reference is not None:
        out["paper_1536"] = paper.compute()
    return out


def input_coverage(dataset: AirFisheyeDataset | MultiSourceDataset, task: str) -> dict[str, float] | None:
    """``results.json``'s ``sparse_coverage``: how densely ``task``'s sparse input covers the ground truth of the
    split, by ring (one more pass over its inputs as served); ``None`` for a task without one."""
    if "sparse_depth" not in get_task(task).inputs:
        return None
    return sparse_coverage(dataset)["served"]
