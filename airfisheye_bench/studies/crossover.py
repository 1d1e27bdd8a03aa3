"""Test-time cross-over of the occlusion correction: one trained completion model, every sparse input.

Training one model per occlusion method confounds the method with the seed and the training noise
(docs/results.md, 4.3). The cross-over holds the weights fixed: the same model is tested on the same frames with
each sparse input (``none``, ``zbuffer``, ``hpr``, ``ordering``, ``oracle``), scored on the whole image and on the
regions of :mod:`airfisheye_bench.metrics.regions` (the pixels where ``none`` and the oracle differ, the near
range), computed per frame from that frame's own ``none`` and ``oracle`` maps. The same pass counts how much
each input differs from ``none`` (:func:`input_differences`, also available without a model).

    python scripts/occlusion_crossover.py --ckpt runs/xover --size 256 --json docs/figures/occlusion_crossover.json
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from omegaconf import DictConfig
from torch import Tensor
from torch.utils.data import DataLoader, Dataset, Subset

from airfisheye_bench.errors import MissingFileError
from airfisheye_bench.evaluation.predictors import CheckpointPredictor
from airfisheye_bench.geometry.occlusion import ORACLE, SPARSE_INPUTS
from airfisheye_bench.geometry.occlusion.zbuffer import derived_window_radius
from airfisheye_bench.metrics.functional import completion_errors
from airfisheye_bench.metrics.regions import (
    DEFAULT_NEAR_M,
    DEFAULT_RADIUS_PX,
    REGIONS,
    RegionCompletionMetrics,
    affected_pixels,
    dilate,
    input_difference,
    near_pixels,
)
from airfisheye_bench.runs import resolve_checkpoint, run_config
from airfisheye_bench.studies.paired import paired_differences
from airfisheye_bench.tasks.checkpoint import load_task
from datamodules.config import apply_data_overrides, instantiate_datamodule
from datamodules.dataset import AirFisheyeDataset, CameraConfig, collate

__all__ = [
    "CROSSOVER_ARMS",
    "FRAME_REGIONS",
    "aligned_batches",
    "arm_datasets",
    "arm_datasets_from_config",
    "crossover",
    "crossover_table",
    "difference_table",
    "frame_scores",
    "input_differences",
    "paired_frames_table",
    "run_frame_scores",
    "run_region_scores",
    "spread_frames",
    "window_radius_share",
]

#: Per-frame metrics of the paired comparison of the inputs (``region/metric``).
FRAME_METRICS = ("rmse", "mae", "abs_rel")
#: The inputs a cross-over tests, ``none`` first (the reference of every difference).
CROSSOVER_ARMS = ("none", *(m for m in SPARSE_INPUTS if m != "none"))
_REQUIRED = ("none", ORACLE)  # the affected pixels are where these two differ


def spread_frames(n: int, limit: int | None) -> list[int]:
    """All ``n`` frames, or ``limit`` of them evenly spread (a split's files are grouped by location).

    Example:
        >>> spread_frames(10, 3), spread_frames(4, None)
        ([0, 4, 9], [0, 1, 2, 3])
    """
    if limit is None or limit >= n:
        return list(range(n))
    if limit < 1:
        raise ValueError(f"frames must be >= 1, got {limit}")
    return sorted({round(k * (n - 1) / max(limit - 1, 1)) for k in range(limit)})


def aligned_batches(
    datasets: Mapping[str, Dataset], batch_size: int = 4, frames: int | None = None
) -> Iterator[dict[str, dict]]:
    """``{arm: batch}`` of the same frames from every arm's dataset, in order.

    Raises:
        ValueError: the datasets do not serve the same frames in the same order.
    """
    sizes = {arm: len(ds) for arm, ds in datasets.items()}  # type: ignore[arg-type]
    if len(set(sizes.values())) != 1:
        raise ValueError(f"the arms' datasets differ in length: {sizes}")
    indices = spread_frames(next(iter(sizes.values())), frames)
    loaders = {
        arm: DataLoader(Subset(ds, indices), batch_size=batch_size, shuffle=False, collate_fn=collate)
        for arm, ds in datasets.items()
    }
    for batches in zip(*loaders.values(), strict=True):
        out = dict(zip(loaders, batches, strict=True))
        ids = {arm: tuple(b["sample_id"]) for arm, b in out.items()}
        if len(set(ids.values())) != 1:
            raise ValueError(f"the arms' datasets serve different frames: {ids}")
        yield out


def arm_datasets(
    root: str | Path,
    split: str,
    arms: Sequence[str] = CROSSOVER_ARMS,
    source: str = "fisheye",
    size: int | None = None,
    max_depth: float = 120.0,
    lidar_density: str = "native",
) -> dict[str, AirFisheyeDataset]:
    """``{arm: dataset}``: one split of a release served for completion with each sparse input (evaluation form:
    no augmentation, each method at its default options; ``lidar_density`` as ``data.lidar.density``)."""
    return {
        arm: AirFisheyeDataset.from_root(
            root,
            split,
            "completion",
            source=source,
            camera=CameraConfig(size=size),
            occlusion=arm,
            max_depth=max_depth,
            lidar_density=lidar_density,
        )
        for arm in arms
    }


def arm_datasets_from_config(
    data: DictConfig | Mapping[str, Any],
    split: str,
    arms: Sequence[str] = CROSSOVER_ARMS,
    size: int | None = None,
) -> dict[str, AirFisheyeDataset]:
    """As :func:`arm_datasets`, from a run's ``data`` config (its release, source, camera, LiDAR and bounds); only
    ``data.occlusion`` and, if given, ``data.camera.size`` change. The run's ``occlusion_options`` stay with its own
    method; every other arm takes its defaults."""
    out = {}
    for arm in arms:
        overrides: dict[str, Any] = {"occlusion": arm}
        if arm != data.get("occlusion"):
            overrides["occlusion_options"] = None
        if size is not None:
            overrides["camera.size"] = size
        out[arm] = instantiate_datamodule(
            apply_data_overrides(data, overrides, task="completion")
        ).split_dataset(split)
    return out


def window_radius_share(dataset: AirFisheyeDataset) -> dict[str, float]:
    """Share of the image circle's pixels by radius of the z-buffer's derived window (the first frame's LiDAR).

    A radius of 0 is a window of one pixel: there the derived z-buffer can only compare the points that land
    on the same pixel.
    """
    spec = dataset.lidar_points(dataset.sample_ids[0])[2]
    radius = derived_window_radius(dataset.camera, spec)[dataset.valid_mask.numpy()]
    values, counts = np.unique(radius, return_counts=True)
    return {str(int(v)): float(c) / radius.size for v, c in zip(values, counts, strict=True)}


def _check_arms(datasets: Mapping[str, Dataset]) -> None:
    missing = [a for a in _REQUIRED if a not in datasets]
    if missing:
        raise ValueError(
            f"a cross-over needs the {missing} inputs (the affected pixels are where none and oracle differ)"
        )
    unknown = [a for a in datasets if a not in SPARSE_INPUTS]
    if unknown:
        raise ValueError(f"unknown sparse inputs {unknown}; expected some of {SPARSE_INPUTS}")


def _difference_row(counts: Mapping[str, int]) -> dict[str, float]:
    return {
        **counts,
        "frac_of_sparse": counts["differing"] / counts["sparse"] if counts["sparse"] else float("nan"),
        "frac_of_valid": counts["differing"] / counts["valid"] if counts["valid"] else float("nan"),
    }


def crossover(
    predict: Callable[[dict], Tensor] | None,
    datasets: Mapping[str, Dataset],
    radius: int = DEFAULT_RADIUS_PX,
    near_m: float = DEFAULT_NEAR_M,
    max_depth: float = 120.0,
    batch_size: int = 4,
    frames: int | None = None,
    score: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Score one model on every arm's sparse input of the same frames, by region.

    Args:
        predict: A batch -> depth ``[B, 1, H, W]`` (e.g. a
            :class:`~airfisheye_bench.evaluation.predictors.CheckpointPredictor`); ``None`` only counts the input
            differences.
        datasets: ``{arm: dataset}``: the same split and camera served with each sparse input
            (:class:`~datamodules.AirFisheyeDataset` with ``occlusion=arm``); must hold ``none`` and ``oracle``.
        radius, near_m: The regions (:class:`~airfisheye_bench.metrics.regions.RegionCompletionMetrics`).
        max_depth: Evaluation bound in metres.
        batch_size: Frames per batch.
        frames: At most this many frames, spread over the split.
        score: The arms to predict on (default: all; ``none`` and ``oracle`` are always served, for the regions).

    Returns:
        ``{"frames", "arms": {arm: {region: {metric: value, "pixels", "images"}}}, "paired_frames": {arm:
        {"region/metric": paired difference against none over the frames}}, "input_difference": {arm: counts
        and fractions against none}, "affected": pixel counts of the undilated and dilated affected region,
        "seconds"}`` (``arms`` and ``paired_frames`` empty without ``predict``). ``paired_frames`` pairs the
        frames: one model and one frame under two inputs, the per-frame difference of a region's metric, with its
        95 % t-interval over the frames that have pixels of that region (the frames as the sample; what it says
        about other places depends on how well these four test locations stand for them).
    """
    _check_arms(datasets)
    start = time.perf_counter()
    scored = [a for a in datasets if score is None or a in score] if predict is not None else []
    metrics = {arm: RegionCompletionMetrics(radius, near_m, max_depth) for arm in scored}
    diffs = {arm: {"differing": 0, "sparse": 0, "valid": 0} for arm in datasets}
    affected = {"differing_px": 0, "dilated_px": 0, "valid_px": 0}
    n = 0
    per_frame: dict[str, dict[int, dict[str, float]]] = {arm: {} for arm in metrics}
    for batches in aligned_batches(datasets, batch_size, frames):
        none, oracle = batches["none"]["sparse_depth"], batches[ORACLE]["sparse_depth"]
        valid = batches["none"]["valid_mask"]
        target = batches["none"]["depth"]
        n += len(target)
        affected["differing_px"] += int(affected_pixels(none, oracle, 0, valid).sum())
        affected["dilated_px"] += int(affected_pixels(none, oracle, radius, valid).sum())
        affected["valid_px"] += int(valid.sum())
        for arm, batch in batches.items():
            for key, value in input_difference(batch["sparse_depth"], none, valid).items():
                diffs[arm][key] += value
            if arm in metrics:
                if not torch.equal(batch["depth"], target):
                    raise ValueError(
                        f"arm {arm!r} serves other ground truth than none for {batch['sample_id']}"
                    )
                with torch.no_grad():
                    prediction = predict(batch)
                metrics[arm].update(prediction, target, none, oracle, valid)
                for region, mask in metrics[arm].masks(target, none, oracle, valid).items():
                    errors, num_valid = completion_errors(prediction, target, max_depth, mask=mask)
                    for b in torch.nonzero(num_valid > 0).flatten().tolist():
                        row = per_frame[arm].setdefault(n - len(target) + b, {})
                        row.update({f"{region}/{m}": float(errors[m][b]) for m in FRAME_METRICS})
    return {
        "frames": n,
        "radius_px": radius,
        "near_m": near_m,
        "arms": {arm: m.compute() for arm, m in metrics.items()},
        "paired_frames": paired_differences(per_frame, "none") if "none" in per_frame else {},
        "input_difference": {arm: _difference_row(c) for arm, c in diffs.items()},
        "affected": affected,
        "seconds": time.perf_counter() - start,
    }


def _trained_run(run_dir: str | Path) -> tuple[Path, Any, CheckpointPredictor, str]:
    """A trained run's best checkpoint, its config, its predictor and its own arm (``data.occlusion``).

    Raises:
        MissingFileError: no ``config.yaml`` of the run next to the checkpoint.
    """
    checkpoint = resolve_checkpoint(run_dir)
    run = run_config(checkpoint)
    if run is None:
        raise MissingFileError(f"{checkpoint}: no config.yaml of its run next to it (its data is unknown)")
    return checkpoint, run, CheckpointPredictor(load_task(checkpoint), checkpoint), str(run.data.occlusion)


def run_region_scores(
    run_dir: str | Path,
    split: str = "test",
    radius: int = DEFAULT_RADIUS_PX,
    near_m: float = DEFAULT_NEAR_M,
    batch_size: int = 4,
) -> dict[str, Any]:
    """A trained run's own arm (its ``data.occlusion``) scored by region on ``split``: the ablation's per-run numbers.

    Returns:
        ``{"arm", "checkpoint", "radius_px", "near_m", "frames", "regions": {region: {metric: value, ...}}}``.
    """
    checkpoint, run, predictor, arm = _trained_run(run_dir)
    datasets = arm_datasets_from_config(run.data, split, list(dict.fromkeys(("none", ORACLE, arm))))
    max_depth = float(run.data.get("max_depth", 120.0))
    result = crossover(predictor, datasets, radius, near_m, max_depth, batch_size, score=[arm])
    return {
        "arm": arm,
        "checkpoint": str(checkpoint),
        "radius_px": radius,
        "near_m": near_m,
        "frames": result["frames"],
        "regions": result["arms"][arm],
    }


def input_differences(
    datasets: Mapping[str, Dataset], radius: int = DEFAULT_RADIUS_PX, frames: int | None = None
) -> dict[str, Any]:
    """:func:`crossover` without a model: how much each arm's input differs from ``none``."""
    return crossover(None, datasets, radius=radius, frames=frames)


def crossover_table(result: Mapping[str, Any], metrics: Sequence[str] = ("rmse", "mae", "abs_rel")) -> str:
    """Markdown: one row per arm, ``metric`` per region, and each region's difference to ``none``."""
    arms = result["arms"]
    head = [f"{region} {m}" for region in REGIONS for m in metrics]
    lines = ["| input | " + " | ".join(head) + " |", "|---|" + "---:|" * len(head)]
    ref = arms.get("none")
    for arm, regions in arms.items():
        cells = []
        for region in REGIONS:
            for m in metrics:
                value = regions[region][m]
                cell = f"{value:.4f}"
                if ref is not None and arm != "none":
                    cell += f" ({value - ref[region][m]:+.4f})"
                cells.append(cell)
        lines.append(f"| `{arm}` | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def paired_frames_table(
    result: Mapping[str, Any],
    metrics: Sequence[str] = ("all/rmse", "affected/rmse", "affected/abs_rel", "near/rmse"),
) -> str:
    """Markdown: per arm, the mean per-frame difference to ``none`` with its 95 % t-interval over the frames."""
    lines = ["| input − none (per frame) | " + " | ".join(metrics) + " |", "|---|" + "---:|" * len(metrics)]
    for arm, by_metric in result.get("paired_frames", {}).items():
        cells = []
        for m in metrics:
            d = by_metric.get(m)
            if d is None:
                cells.append("-")
            else:
                lo, hi = d["ci95"]
                cells.append(f"{d['mean']:+.4f} [{lo:+.4f}, {hi:+.4f}] (n={d['n']})")
        lines.append(f"| `{arm}` | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def difference_table(result: Mapping[str, Any]) -> str:
    """Markdown: per arm, the pixels whose input differs from ``none``, of the sparse and of the valid pixels."""
    lines = [
        "| input | differing px | of sparse px | of valid px |",
        "|---|---:|---:|---:|",
    ]
    for arm, row in result["input_difference"].items():
        lines.append(
            f"| `{arm}` | {row['differing']:,} | {100 * row['frac_of_sparse']:.2f} % of {row['sparse']:,} "
            f"| {100 * row['frac_of_valid']:.3f} % of {row['valid']:,} |"
        )
    return "\n".join(lines)


#: The regions of :func:`frame_scores`: ``changed`` is method-neutral (the pixels any input changes).
FRAME_REGIONS = ("all", "changed", "affected", "near")


def frame_scores(
    predict: Callable[[dict], Tensor],
    datasets: Mapping[str, Dataset],
    arm: str,
    radius: int = DEFAULT_RADIUS_PX,
    near_m: float = DEFAULT_NEAR_M,
    max_depth: float = 120.0,
    batch_size: int = 4,
) -> list[dict[str, Any]]:
    """One model tested on ``arm``'s input, scored per frame on every region of :data:`FRAME_REGIONS`.

    ``changed`` favours no method: the valid pixels where *any* arm of ``datasets`` (all of
    :data:`CROSSOVER_ARMS` for a study) serves another sparse value than ``none``, dilated by ``radius``. It holds
    every method's changes, its wrong removals included, where ``affected`` (``none`` against the oracle only)
    holds all of the oracle's and part of the others'.

    Returns:
        One row per frame: ``{"sample_id", "regions": {region: {"rmse", "mae", "abs_rel", "pixels"}}}`` (a region
        without a valid pixel in the frame is left out of its row).
    """
    _check_arms(datasets)
    if arm not in datasets:
        raise ValueError(f"arm {arm!r} is not among the datasets' arms {list(datasets)}")
    rows: list[dict[str, Any]] = []
    for batches in aligned_batches(datasets, batch_size):
        none, oracle = batches["none"]["sparse_depth"], batches[ORACLE]["sparse_depth"]
        target = batches["none"]["depth"]
        base = batches["none"]["valid_mask"].bool()
        base = (base[:, 0] if base.ndim == 4 else base).expand(target.shape[0], *target.shape[-2:])
        changed = torch.zeros_like(base)
        for batch in batches.values():
            changed |= (batch["sparse_depth"] != none)[:, 0]
        masks = {
            "all": base,
            "changed": dilate(changed, radius) & base,
            "affected": affected_pixels(none, oracle, radius, base),
            "near": near_pixels(target, near_m) & base,
        }
        with torch.no_grad():
            prediction = predict(batches[arm])
        per_region = {}
        for region, mask in masks.items():
            errors, num_valid = completion_errors(prediction, target, max_depth, mask=mask)
            per_region[region] = (errors, num_valid)
        for b, sample_id in enumerate(batches[arm]["sample_id"]):
            row: dict[str, Any] = {"sample_id": str(sample_id), "regions": {}}
            for region, (errors, num_valid) in per_region.items():
                if int(num_valid[b]) > 0:
                    row["regions"][region] = {m: float(errors[m][b]) for m in FRAME_METRICS}
                    row["regions"][region]["pixels"] = int(num_valid[b])
            rows.append(row)
    return rows


def run_frame_scores(
    run_dir: str | Path,
    split: str = "test",
    radius: int = DEFAULT_RADIUS_PX,
    near_m: float = DEFAULT_NEAR_M,
    batch_size: int = 4,
) -> dict[str, Any]:
    """A trained run's best checkpoint on its own input (its ``data.occlusion``), per frame and region
    (:func:`frame_scores`, with every arm served for the ``changed`` region).

    Returns:
        ``{"arm", "checkpoint", "radius_px", "near_m", "frames": [rows]}``.
    """
    checkpoint, run, predictor, arm = _trained_run(run_dir)
    datasets = arm_datasets_from_config(run.data, split, CROSSOVER_ARMS)
    max_depth = float(run.data.get("max_depth", 120.0))
    rows = frame_scores(predictor, datasets, arm, radius, near_m, max_depth, batch_size)
    return {"arm": arm, "checkpoint": str(checkpoint), "radius_px": radius, "near_m": near_m, "frames": rows}
