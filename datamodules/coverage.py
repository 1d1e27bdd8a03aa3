"""How densely the served sparse LiDAR covers the ground truth, by incidence-angle ring, and how densely the paper's
sensor would cover the same frames on the paper's images (docs/design.md, "Sparse input density").

:func:`sparse_coverage` measures the ``sparse_depth`` of every ``every``-th frame exactly as the split serves it,
and beside it the yardstick of each reading of the paper's density, *modelled*, not measured: the pixels of a
190 deg fisheye of 1536^2 (``model_1536``) or 512^2 (``model_512``) that a nominal beam of the assumed 64 x 2048
sensor lands on (turned by the frame's ``T_cam_lidar``), counted where the frame has ground truth (a pixel of the
model's image has it where the served pixel it lies in has; the ground-truth pixels of a ring are the served ones
times the pixel area ratio). All are sparse pixels per ground-truth pixel; the paper sensor's returns beyond its
range or outside its field of view have no ground truth or no beam either way.

:func:`dataset_coverage` measures a dataset folder every way it can be served (every return, and each reading:
``data.lidar.density=paper_1536|paper_512``) on a few frames, and :func:`format_coverage` prints it:
``airfisheye-inspect`` states it for every dataset with LiDAR.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch

from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_density import PAPER_READINGS, beam_pixels, paper_camera
from airfisheye_bench.io.datasets.airfisheye import DatasetReader
from airfisheye_bench.metrics import RingCoverage, ring_edges_for
from airfisheye_bench.specs import get_task
from datamodules.datamodule import AirFisheyeDataModule
from datamodules.dataset import AirFisheyeDataset
from datamodules.multi_source import MultiSourceDataset

__all__ = ["FRAMES", "SERVED", "dataset_coverage", "format_coverage", "input_coverage", "sparse_coverage"]

#: Frames :func:`dataset_coverage` measures by default, spread over the split: a few seconds on any release.
FRAMES = 4


def _parts(dataset: AirFisheyeDataset | MultiSourceDataset) -> list[AirFisheyeDataset]:
    return list(dataset.datasets.values()) if isinstance(dataset, MultiSourceDataset) else [dataset]


def _edges(parts: list[AirFisheyeDataset]) -> tuple[float, ...]:
    return ring_edges_for(max(part.camera.coverage_deg for part in parts))


def sparse_coverage(
    dataset: AirFisheyeDataset | MultiSourceDataset, every: int = 1, reference: LidarSpec | None = None
) -> dict[str, dict[str, float]]:
    """Sparse pixels per ground-truth pixel by ring over every ``every``-th frame of a completion split (every
    source of a mixture pooled): ``{"served": {"ring_0-30": ...}}``, and with a ``reference`` sensor (the paper's
    assumed one: ``LidarSpec()``) its modelled coverage of the same frames on each reading's image
    (:data:`~airfisheye_bench.geometry.lidar_density.PAPER_READINGS`) as ``"model_1536"`` and ``"model_512"``."""
    parts = _parts(dataset)
    edges = _edges(parts)
    served = [RingCoverage(torch.rad2deg(part.camera.theta_grid()), edges) for part in parts]
    sizes = sorted(set(PAPER_READINGS.values()), reverse=True) if reference is not None else []
    models = {size: (RingCoverage(torch.zeros(0), edges), paper_camera(size)) for size in sizes}
    for part, coverage in zip(parts, served, strict=True):
        for index in range(0, len(part), every):
            sample = part[index]
            truth = sample["depth"][0]
            coverage.update(sample["sparse_depth"][0], truth)
            for (
                model,
                camera,
            ) in models.values():  # the model's pixels hit by a beam, where the truth has depth
                hit = beam_pixels(reference, camera, part.T_cam_lidar(sample["sample_id"]))
                theta = torch.rad2deg(torch.acos(camera.unproject(hit.double())[:, 2].clamp(-1.0, 1.0)))
                scale = part.camera.width / camera.width
                u, v = ((hit + 0.5) * scale).long().clamp(max=part.camera.width - 1).unbind(-1)
                has_truth = truth[v, u] > 0
                model.add_pixels(theta[has_truth], coverage.theta[truth > 0], truth_weight=scale**-2)
    for coverage in served[1:]:
        served[0].add(coverage)
    out = {"served": served[0].compute()}
    out.update({f"model_{size}": model.compute() for size, (model, _) in models.items()})
    return out


def input_coverage(dataset: AirFisheyeDataset | MultiSourceDataset, task: str) -> dict[str, float] | None:
    """``results.json``'s ``sparse_coverage``: how densely ``task``'s sparse input covers the ground truth of the
    split, by ring (one more pass over its inputs as served); ``None`` for a task without one."""
    if "sparse_depth" not in get_task(task).inputs:
        return None
    return sparse_coverage(dataset)["served"]


#: The densities :func:`dataset_coverage` serves: every return and each reading (``paper`` is ``paper_1536``).
SERVED = ("native", *PAPER_READINGS)


def dataset_coverage(
    root: str | Path, size: int, every: int | None = None, split: str = "test"
) -> dict[str, Any] | None:
    """The completion input's coverage of a dataset folder, by ring, as training serves it at ``size``^2: with
    every return (``native``) and under each reading of the paper's density (``paper_1536``, ``paper_512``), beside
    the assumed paper sensor modelled on each reading's image (``model_1536``, ``model_512``), over every
    ``every``-th frame of ``split``.

    Args:
        root: A dataset in the AirFisheye layout.
        size: The served image size (``data.camera.size``).
        every: Measure every ``every``-th frame; ``None``: about :data:`FRAMES` frames spread over the split.
        split: The split measured.

    Returns:
        ``{"split", "size", "every", "frames", "rings": {density or model: {"ring_0-30": ...}}}``; ``None`` for a
        dataset without LiDAR (no completion input).
    """
    if not DatasetReader(root).spec.has("lidar"):
        return None
    rings: dict[str, dict[str, float]] = {}
    for density in SERVED:
        datamodule = AirFisheyeDataModule(
            "completion", root=root, preset=None, camera={"size": size}, lidar={"density": density}
        )
        dataset = datamodule.split_dataset(split)
        every = every or max(1, len(dataset) // FRAMES)
        # The modelled sensor depends on the frames, not on the served density: computed once.
        coverage = sparse_coverage(dataset, every, reference=LidarSpec() if density == "native" else None)
        rings[density] = coverage.pop("served")
        rings.update(coverage)
    frames = len(range(0, len(dataset), every))
    return {"split": split, "size": size, "every": every, "frames": frames, "rings": rings}


def format_coverage(coverage: dict[str, Any]) -> str:
    """:func:`dataset_coverage` as a few lines: one per ring, the served input (every return, each reading of the
    paper's density) beside the paper sensor modelled on each reading's image.

    Example:
        >>> rings = {"native": {"ring_0-30": 0.918}, "paper_1536": {"ring_0-30": 0.11}, "paper_512": {"ring_0-30": 0.8},
        ...          "model_1536": {"ring_0-30": 0.112}, "model_512": {"ring_0-30": 0.81}}
        >>> print(format_coverage({"split": "test", "size": 128, "every": 8, "frames": 3, "rings": rings}))
        sparse LiDAR coverage (completion input, sparse pixels per ground-truth pixel), test split, 3 frames (every=8):
          ring         native 128^2   paper_1536 128^2   paper_512 128^2   model 1536^2   model 512^2
          ring_0-30          0.9180             0.1100            0.8000         0.1120        0.8100
          (paper_1536, paper_512: data.lidar.density, the paper sensor's returns per pixel of its 1536^2 or 512^2
          image at the served size; model: the assumed 64 x 2048 sensor's nominal beams on that image, modelled,
          not measured)
    """
    size, rings = coverage["size"], coverage["rings"]
    keys = (*SERVED, *(f"model_{s}" for s in sorted(set(PAPER_READINGS.values()), reverse=True)))
    columns = [f"{k} {size}^2" if k in SERVED else f"model {k.removeprefix('model_')}^2" for k in keys]
    lines = [
        "sparse LiDAR coverage (completion input, sparse pixels per ground-truth pixel), "
        f"{coverage['split']} split, {coverage['frames']} frames (every={coverage['every']}):",
        f"  {'ring':<10}" + "".join(f"{c:>{len(c) + 3}}" for c in columns),
    ]
    for ring in rings["native"]:
        values = (rings.get(k, {}).get(ring, float("nan")) for k in keys)
        lines.append(
            f"  {ring:<10}" + "".join(f"{v:>{len(c) + 3}.4f}" for c, v in zip(columns, values, strict=True))
        )
    lines += [
        "  (paper_1536, paper_512: data.lidar.density, the paper sensor's returns per pixel of its 1536^2 or 512^2",
        "  image at the served size; model: the assumed 64 x 2048 sensor's nominal beams on that image, modelled,",
        "  not measured)",
    ]
    return "\n".join(lines)
