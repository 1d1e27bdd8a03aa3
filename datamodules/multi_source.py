"""Several sources served as one dataset per split: the concatenation, its training sampler.

The sources come resolved from :mod:`datamodules.sources`. :func:`open_split` opens one split of every source with
the run's camera, task and classes; :class:`MultiSourceDataset` concatenates them. Training draws from the
concatenation with an :class:`~datamodules.sampling.EpochSeededSampler` (each frame once per epoch), or, with
``weight`` on every source, a :class:`SourceMixtureSampler` (sources in those proportions). Every served sample
carries its ``source`` name and a ``sample_id`` prefixed with it, so that evaluation can score each source apart
(docs/design.md, "More than one source").
"""

from __future__ import annotations

import bisect
import logging
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import Dataset

from airfisheye_bench.constants import IMAGENET_MEAN, IMAGENET_STD
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.serving import serve_camera
from airfisheye_bench.io.datasets import DatasetSource
from airfisheye_bench.specs import get_task
from datamodules.dataset import AirFisheyeDataset
from datamodules.sampling import EpochSeededSampler, draw_seed
from datamodules.sources import CommonClasses, SourceConfig, class_lut, naming_source

log = logging.getLogger(__name__)


class MultiSourceDataset(Dataset):
    """One split of several sources, concatenated in ``data.sources`` order.

    Index ``i`` is frame ``i - offset`` of the source whose range holds it. A served sample is its source's, with
    ``source`` (the name) added, ``sample_id`` prefixed ``<source>/`` (two sources may share ids) and ``label``
    mapped to the common classes.

    Args:
        datasets: The split of each source, by source name.
        common: The run's classes.
        luts: Per source, its training id -> common id table (``None``: the same classes).
        served: Per source, its camera as served here and the rows padded above and below its frames (``None``:
            each dataset's own camera, no padding).
    """

    def __init__(
        self,
        datasets: Mapping[str, AirFisheyeDataset],
        common: CommonClasses,
        luts: Mapping[str, torch.Tensor | None] | None = None,
        served: Mapping[str, tuple[Any, int]] | None = None,
    ) -> None:
        self.datasets = dict(datasets)
        self.names = list(self.datasets)
        self.spec = common
        self.luts = dict(luts or {})
        sizes = [len(d) for d in self.datasets.values()]
        #: Index of each source's first frame in the concatenation.
        self.offsets = [int(x) for x in np.cumsum([0, *sizes[:-1]])]
        self.sizes = sizes
        self.sample_ids = [f"{n}/{s}" for n, d in self.datasets.items() for s in d.sample_ids]
        self.served = dict(served or {n: (d.camera, 0) for n, d in self.datasets.items()})
        self.camera = self.served[self.names[0]][0]
        first = next(iter(self.datasets.values()))
        self.task = first.task

    def __len__(self) -> int:
        return sum(self.sizes)

    def locate(self, index: int) -> tuple[str, int]:
        """``(source name, index in that source)`` of a concatenated index."""
        if not 0 <= index < len(self):
            raise IndexError(f"index {index} out of range for {len(self)} frames")
        k = bisect.bisect_right(self.offsets, index) - 1
        return self.names[k], index - self.offsets[k]

    def __getitem__(self, index: int) -> dict | None:
        name, local = self.locate(index)
        sample = self.datasets[name][local]
        if sample is None:  # skip_bad_frames: collate drops and counts it
            return None
        top = self.served[name][1]
        if top:
            _pad_rows(sample, top, self.datasets[name].spec.ignore_index)
        sample["sample_id"] = f"{name}/{sample['sample_id']}"
        sample["source"] = name
        lut = self.luts.get(name)
        if lut is not None and "label" in sample:
            sample["label"] = lut[sample["label"]]
        return sample

    def set_epoch(self, epoch: int) -> None:
        for dataset in self.datasets.values():
            dataset.set_epoch(epoch)

    def warm_up(self) -> None:
        for dataset in self.datasets.values():
            dataset.warm_up()

    def source_camera(self, name: str) -> Any:
        """The camera a source's frames are served with here (padded to the common size where needed)."""
        return self.served[name][0]

    @property
    def ray_map(self) -> torch.Tensor:
        """The first source's ray map as its frames carry it here (padded as they are): the run's camera's."""
        name = self.names[0]
        top = self.served[name][1]
        rays = self.datasets[name].ray_map
        return F.pad(rays, (0, 0, top, top), value=0.0) if top else rays


def _pad_rows(sample: dict, rows: int, ignore_index: int) -> None:
    """Pad every map of a sample with ``rows`` rows above and below: no data there (invalid, ignored, no depth);
    the image gets black, as a padded calibration's bands (``AirFisheyeDataset``), normalised."""
    black = -torch.tensor(IMAGENET_MEAN).view(3, 1, 1) / torch.tensor(IMAGENET_STD).view(3, 1, 1)
    band = black.expand(3, rows, sample["image"].shape[-1])
    sample["image"] = torch.cat([band, sample["image"], band], dim=1)
    sample["valid_mask"] = F.pad(sample["valid_mask"], (0, 0, rows, rows), value=False)
    if "label" in sample:
        sample["label"] = F.pad(sample["label"], (0, 0, rows, rows), value=ignore_index)
    for key in ("depth", "sparse_depth", "rays"):  # no data in the bands: no depth, no ray (invalid)
        if key in sample:
            sample[key] = F.pad(sample[key], (0, 0, rows, rows), value=0.0)


def open_split(
    sources: Sequence[SourceConfig],
    readers: Mapping[str, DatasetSource],
    split_index: int,
    default_splits: Sequence[str],
    seed: int,
    augment: Any,
    dataset_kwargs: Mapping[str, Any],
    lidar_spec: LidarSpec | None = None,
    mixture: bool = True,
) -> AirFisheyeDataset | MultiSourceDataset:
    """One split of every source (each read through its opened reader), as one dataset.

    A run of one source (``mixture`` false: no ``data.sources``) is that source's dataset itself, seeded with
    ``seed``. A mixture's sources are checked to serve the same image size and classes; each source's augmentation
    draws get their own seed (``draw_seed(seed, -3, k)`` for the ``k``-th source), so frame ``i`` of two sources
    is not augmented alike. ``lidar_spec`` (``data.lidar.preset``) replaces the ``calib.yaml`` spec of every source
    read from a root (a synthetic one was generated with that sensor).

    Raises:
        UserError: a source that cannot be served, with (in a mixture) its name in front of the reason.
    """
    common = CommonClasses.benchmark(" + ".join(s.name for s in sources))
    datasets: dict[str, AirFisheyeDataset] = {}
    luts: dict[str, torch.Tensor | None] = {}
    uses_classes = "label" in _task_keys(dataset_kwargs["task"])
    for k, src in enumerate(sources):
        split = (src.splits or tuple(default_splits))[split_index]
        kwargs = dict(dataset_kwargs)
        kwargs["lidar_spec"] = lidar_spec if src.root is not None else None
        if src.source is not None:
            kwargs["source"] = src.source
        elif (
            mixture
        ):  # data.source, or the raw recording this dataset has (a preset's cube faces beside panoramas)
            kwargs["source_fallback"] = True
        with naming_source(src, mixture):
            dataset = AirFisheyeDataset(
                readers[src.name],
                split,
                augment=augment,
                seed=draw_seed(seed, -3, k) if mixture else seed,
                **kwargs,
            )
        if not mixture:
            return dataset
        datasets[src.name] = dataset
        luts[src.name] = (
            class_lut(src, dataset.spec.train_class_names, dataset.spec.ignore_index, common)
            if uses_classes
            else None
        )
    return MultiSourceDataset(datasets, common, luts, _common_size(datasets))


def _task_keys(task: str) -> set[str]:
    spec = get_task(task)
    return {spec.target, *spec.inputs}


def _common_size(datasets: Mapping[str, AirFisheyeDataset]) -> dict[str, tuple[Any, int]]:
    """Frames of all sources are batched together, so they are served at one size: the largest side ``S`` squared.

    A source served narrower (a 4:3 recording kept at its aspect, ``S x 3S/4``) is padded above and below to
    ``S x S``, as ``data.camera.fit=pad`` serves a calibration: its camera is that padded one
    (:func:`~airfisheye_bench.geometry.serving.serve_camera`), the bands are invalid. Lenses may differ (logged).

    Returns:
        Per source, its served camera at ``S x S`` and the rows of padding above (0: none).

    Raises:
        ConfigError: a source that cannot be padded to ``S x S`` that way, naming it.
    """
    size = max(max(d.camera.width, d.camera.height) for d in datasets.values())
    out: dict[str, tuple[Any, int]] = {}
    for name, d in datasets.items():
        if (d.camera.width, d.camera.height) == (size, size):
            out[name] = (d.camera, 0)
            continue
        padded = serve_camera(d.served.source, size, "pad")
        top = padded.offset[1]
        fits = d.camera.width == size and padded.offset[0] == 0 and top == int(top)
        if not fits or abs(padded.scale - d.served.scale) > 1e-12 or 2 * int(top) + d.camera.height != size:
            raise ConfigError(
                f"data.sources: source {name} is served at {d.camera.width}x{d.camera.height}, which does not pad "
                f"to the other sources' {size}x{size}: give data.camera.size (a size at which its frame height "
                "differs from the width by an even number of rows)"
            )
        out[name] = (padded.camera, int(top))
    lenses = {n: camera.to_dict() for n, (camera, _) in out.items()}
    if len({str(lens) for lens in lenses.values()}) > 1:
        log.info(
            "sources served with their own lenses at %dx%d: %s",
            size,
            size,
            "; ".join(
                f"{n}: {c.model} {c.coverage_deg:.0f} deg"
                + (f", padded {t} rows above and below" if t else "")
                for n, (c, t) in out.items()
            ),
        )
    return out


# ------------------------------------------------------------------------------------------------- sampling


class SourceMixtureSampler(EpochSeededSampler):
    """An epoch of ``len(dataset)`` draws, each source in proportion to its weight, resumable like its base.

    Source ``s`` gets ``round(w_s / sum(w) * N)`` draws (largest remainders, so they add up to ``N``): its frames
    in a permutation seeded by ``(seed, epoch, s)``, repeated when it has fewer frames than draws; the draws of all
    sources are then shuffled together by ``(seed, epoch)``. Only the order depends on the epoch, so a resumed run
    continues with the draws an uninterrupted one makes (``start``, :class:`EpochSeededSampler`).

    Example:
        >>> s = SourceMixtureSampler([2, 6], [3.0, 1.0], seed=0, num_replicas=1, rank=0)
        >>> order = list(s)
        >>> len(order), sum(i < 2 for i in order), sum(i >= 2 for i in order)
        (8, 6, 2)
        >>> s.start = 5
        >>> list(s) == order[5:]
        True
    """

    def __init__(
        self,
        sizes: Sequence[int],
        weights: Sequence[float],
        seed: int = 0,
        num_replicas: int | None = None,
        rank: int | None = None,
    ) -> None:
        super().__init__(sum(sizes), seed, num_replicas=num_replicas, rank=rank)
        self.sizes = [int(n) for n in sizes]
        self.counts = _proportional_counts([float(w) for w in weights], sum(self.sizes))

    def epoch_order(self) -> list[int]:
        draws: list[int] = []
        offset = 0
        for s, (size, count) in enumerate(zip(self.sizes, self.counts, strict=True)):
            generator = torch.Generator().manual_seed(draw_seed(self.seed, self.epoch, -2 - s))
            rounds = -(-count // size) if size else 0
            picks = (
                torch.cat([torch.randperm(size, generator=generator) for _ in range(rounds)])
                if rounds
                else []
            )
            draws += [offset + int(i) for i in list(picks)[:count]]
            offset += size
        generator = torch.Generator().manual_seed(draw_seed(self.seed, self.epoch, -1))
        return [draws[i] for i in torch.randperm(len(draws), generator=generator).tolist()]


def _proportional_counts(weights: Sequence[float], total: int) -> list[int]:
    """Whole counts adding up to ``total`` in the proportions of ``weights`` (largest remainders).

    Example:
        >>> _proportional_counts([1.0, 1.0, 1.0], 10), _proportional_counts([3.0, 1.0], 8)
        ([4, 3, 3], [6, 2])
    """
    shares = [w / sum(weights) * total for w in weights]
    counts = [int(x) for x in shares]
    by_remainder = sorted(range(len(shares)), key=lambda i: (counts[i] - shares[i], i))
    for i in by_remainder[: total - sum(counts)]:
        counts[i] += 1
    return counts


def training_sampler(
    dataset: AirFisheyeDataset | MultiSourceDataset, sources: Sequence[SourceConfig], seed: int
) -> EpochSeededSampler:
    """The training sampler: weighted when the sources have weights (a mixture), else the plain epoch order."""
    if sources and sources[0].weight is not None:
        return SourceMixtureSampler(dataset.sizes, [s.weight for s in sources], seed)
    return EpochSeededSampler(len(dataset), seed)


__all__ = ["MultiSourceDataset", "SourceMixtureSampler", "open_split", "training_sampler"]
