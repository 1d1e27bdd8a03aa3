"""``AirFisheyeDataModule``: every task of the benchmark from one dataset root, composed from Hydra configs.

``root=None`` means the synthetic dataset of ``preset``, generated on first use and cached
(:func:`airfisheye_bench.synth.cache.ensure_dataset`); a path reads the real release (or any dataset in the layout).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import lightning as L
import numpy as np
import torch
from lightning.pytorch.trainer.states import TrainerFn
from torch.utils.data import DataLoader

from airfisheye_bench.config_checks.data_options import check, default, group
from airfisheye_bench.constants import IMAGENET_MEAN, IMAGENET_STD
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry import CameraModel
from airfisheye_bench.geometry.gimbal import Gimbal
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_presets import LIDAR_PRESETS
from airfisheye_bench.geometry.occlusion import SPARSE_INPUTS, Occlusion, sparse_input
from airfisheye_bench.geometry.scan_filter import DEFAULT_MIN_RANGE
from airfisheye_bench.io.dataset_spec import remap_site_problem
from airfisheye_bench.io.datasets import DatasetSource, lidar_option_conflict
from airfisheye_bench.io.lidar_spec import lidar_preset_problem, load_lidar_spec
from airfisheye_bench.synth.cache import ensure_dataset
from datamodules.augment import FisheyeAugment
from datamodules.dataset import AirFisheyeDataset, CameraConfig, collate, open_reader
from datamodules.device_remap import CubeFaces, DeviceRemap
from datamodules.multi_source import MultiSourceDataset, open_split, training_sampler
from datamodules.sampling import (
    EvaluationLoader,
    batches_per_rank,
    evaluation_sampler,
    training_position,
)
from datamodules.sources import SourceConfig, naming_source, resolve_sources, single_source

log = logging.getLogger(__name__)


class AirFisheyeDataModule(L.LightningDataModule):
    """Train/val/test loaders of a dataset of any format for one task.

    Every default is the declared one (:data:`~airfisheye_bench.config_checks.data_options.DATA_OPTIONS`, the table
    of ``docs/datasets.md``, "Data options"), the same as ``configs/data/synthetic.yaml``'s; ``camera``, ``lidar``
    and ``augment`` are completed key by key from the declarations (``augment=None``: no augmentation).

    Args:
        task: ``seg``, ``depth`` or ``completion``.
        root: Dataset root; ``None`` uses the synthetic ``preset`` (generated on first use into ``cache_dir``).
        preset: Synthetic preset when ``root`` is ``None`` (``tiny``, ``quickstart``, ...).
        cache_dir: Where synthetic datasets are cached (default: ``$AIRFISHEYE_DATA`` or ``~/.cache/airfisheye-bench``).
        source: ``cubemap`` (remap on the fly) or ``fisheye`` (pre-rendered files).
        camera: Served camera: ``{"size": 512, "model": ..., "fov_deg": ..., "k": ...}``, or a calibrated lens
            ``{"size": 512, "calibration": <file>, "camera": <name or index>, "fit": "pad" | "crop"}``; unset keys
            follow the release (``datamodules.dataset.CameraConfig``).
        occlusion: LiDAR occlusion correction for completion: ``ordering`` | ``zbuffer`` | ``hpr`` | ``none`` |
            ``oracle`` (the generator's exact visibility: synthetic releases only).
        occlusion_options: Options of that method, e.g. ``{"elevation_tolerance": -0.25}`` for ``ordering``,
            ``{"kernel": 5, "threshold": 1.0, "relative": False}`` for ``zbuffer``, ``{"radius": 100}`` for
            ``hpr`` (all in :data:`~airfisheye_bench.geometry.occlusion.OCCLUSION_OPTIONS`); unset ones take
            their defaults.
        motion_compensation: Per-frame ``T_cam_lidar`` from both sensors' poses at their own timestamps.
        max_depth: Depth beyond this is invalid (paper: 120 m).
        augment: ``{"hflip": 0.5, "rotate_deg": 0, "color_jitter": [b, c, s, h] | None}`` for training, or ``None``.
        batch_size: Per-process batch size for training (evaluation uses ``eval_batch_size`` or the same).
        num_workers: DataLoader workers (0 loads in the main process).
        pin_memory: Pin host memory (for GPU training).
        persistent_workers: Keep workers alive between epochs.
        skip_bad_frames: Skip (and count) frames that fail to load instead of stopping.
        splits: Names of the train, val and test splits in ``dataset.yaml``.
        seed: Seed of the shuffling and augmentation draws.
        dataset_seed: Seed of the synthetic dataset itself (``root=None``); 0 is the canonical release of each
            preset. Independent of ``seed`` so that changing the training seed never changes the data.
        lidar: ``{"preset": ..., "min_range": 1.0, "density": "paper"}``. ``preset``: the LiDAR of every source (a
            preset name such as ``hdl64e``, or a YAML / JSON / Ouster metadata file): with ``root`` it replaces
            ``calib.yaml``'s spec of a recorded LiDAR (a real release whose calibration has none) and is cast into
            the depth by a source that simulates its LiDAR (TartanAir, Omni360: ``DatasetSource.cast_scan``);
            without, the synthetic ``preset`` is generated with that sensor (cached apart). The deprecated
            ``format_options.lidar`` of TartanAir and Omni360 stands for it for one release (warned), and beside a
            different ``preset`` is refused. ``min_range``: returns closer than this many metres are self-hits, removed and counted.
            ``density``: ``native`` (every return), ``paper_1536`` (or ``paper``) or ``paper_512`` (a fixed subset
            of the beams: the returns per pixel of the paper's sensor on its 1536^2 or its 512^2 image, at any
            served size; docs/design.md, "Sparse input density").
        format: How ``root`` is laid out: ``airfisheye`` (the release's layout, and the synthetic data) or a public
            dataset's own layout (:data:`~airfisheye_bench.io.datasets.DATASET_FORMATS`; ``docs/design.md``,
            "Dataset formats"). Any format but ``airfisheye`` needs ``root``.
        format_options: That format's options (for example which camera of a rig); unset ones take their defaults.
        sources: Several datasets in one run: source names (``datamodules.sources``; ``docs/design.md``, "More
            than one source"). The top-level ``root``, ``format``, ``preset`` are then what names inherit.
        source_options: Each source's settings by name (``format``, ``root``, ``format_options``, ``preset``,
            ``dataset_seed``, ``splits``, ``source``, ``class_map``, ``weight``).
        gimbal: A virtual gimbal turning the served camera relative to the remapped source
            (:mod:`~airfisheye_bench.geometry.gimbal`: a view ``[yaw, pitch(, roll)]`` in degrees, a list of views,
            or ranges ``{pitch_deg: [0, 45], ...}`` drawn per training sample); evaluation splits get fixed views.
        remap_on: Where the cube faces become the fisheye image: ``worker`` (the loader's worker processes) or
            ``device`` (the workers only decode the faces and project the LiDAR; the remap, augmentation and
            normalisation run on the model's device after the transfer, in :meth:`on_after_batch_transfer`, with
            the same tables and the same results: :mod:`datamodules.device_remap`). ``device`` needs
            ``source=cubemap`` and one dataset.
        camera_input: What the model takes of the camera besides the image (``model.camera_input``): ``none``, or
            ``rays``, each sample's ray map as the key ``rays`` (:mod:`airfisheye_bench.geometry.ray_maps`).

    Example:
        >>> dm = AirFisheyeDataModule("seg", preset="tiny", camera={"size": 64}, batch_size=2)  # doctest: +SKIP
        >>> dm.prepare_data(); dm.setup("fit")                                             # doctest: +SKIP
        >>> batch = next(iter(dm.train_dataloader()))                                      # doctest: +SKIP
        >>> batch["image"].shape, batch["label"].shape                                     # doctest: +SKIP
        (torch.Size([2, 3, 64, 64]), torch.Size([2, 64, 64]))
    """

    def __init__(
        self,
        task: str,
        root: str | Path | None = default("root"),
        preset: str | None = default("preset"),
        cache_dir: str | Path | None = default("cache_dir"),
        source: str = default("source"),
        camera: dict[str, Any] | None = None,
        occlusion: str = default("occlusion"),
        occlusion_options: dict[str, Any] | None = default("occlusion_options"),
        motion_compensation: bool = default("motion_compensation"),
        max_depth: float = default("max_depth"),
        augment: dict[str, Any] | None = None,
        batch_size: int = default("batch_size"),
        eval_batch_size: int | None = default("eval_batch_size"),
        num_workers: int = default("num_workers"),
        pin_memory: bool = default("pin_memory"),
        persistent_workers: bool = default("persistent_workers"),
        skip_bad_frames: bool = default("skip_bad_frames"),
        splits: Sequence[str] = default("splits"),
        seed: int = default("seed"),
        dataset_seed: int = default("dataset_seed"),
        lidar: dict[str, Any] | None = None,
        format: str = default("format"),
        format_options: dict[str, Any] | None = default("format_options"),
        sources: list[str] | None = default("sources"),
        source_options: dict[str, dict[str, Any]] | None = default("source_options"),
        gimbal: Any = default("gimbal"),
        remap_on: str = default("remap_on"),
        camera_input: str = default("camera_input"),
    ) -> None:
        super().__init__()
        check("batch_size", batch_size)
        check("camera_input", camera_input)
        problem = remap_site_problem(remap_on, source, sources, gimbal)
        if problem is not None:
            raise ConfigError(f"data.remap_on={remap_on!r}: {problem}")
        self.remap_on = remap_on
        self._device_remap: DeviceRemap | None = None
        location = dict(
            format=format, root=root, format_options=format_options, preset=preset, dataset_seed=dataset_seed
        )
        # One path for one dataset and several: a run without data.sources has one source, the top-level keys'
        # (its samples are served as they are: no source name, no prefix).
        self.mixture = bool(sources)
        self.sources = resolve_sources(sources, source_options, location) or (single_source(location),)
        self.task = task
        self.cache_dir = cache_dir
        self.seed = seed
        self.camera_config = CameraConfig(**_floats(group("camera", camera), "k"))
        # The lens is read once, now: a bad calibration file is refused before any data exists (each of a list's).
        _ = self.camera_config.lens, self.camera_config.served_lenses, self.camera_config.lens_jitter
        # augment=None: no augmentation (evaluation); a mapping: its keys over the declared defaults.
        augment_kwargs = _floats(group("augment", augment), "color_jitter")
        self.augment = FisheyeAugment(**augment_kwargs) if augment is not None else None
        lidar_opts = group("lidar", lidar)
        #: data.lidar.preset: the sensor served for every source (synthetic ones are generated with it).
        self.lidar = _lidar(lidar_opts.get("preset"), self.sources, self.mixture)
        for key in ("min_range", "density"):  # a library caller's; a config's were checked before
            check(f"lidar.{key}", lidar_opts[key])
        min_range = DEFAULT_MIN_RANGE if lidar_opts["min_range"] is None else lidar_opts["min_range"]
        density = lidar_opts["density"]
        self.dataset_kwargs = dict(
            task=task,
            source=source,
            camera=self.camera_config,
            # Checked once, here; the datasets and every frame's projection take it as it is.
            occlusion=_occlusion(occlusion, occlusion_options),
            motion_compensation=motion_compensation,
            max_depth=max_depth,
            skip_bad_frames=skip_bad_frames,
            lidar_min_range=float(min_range),
            lidar_density=density,
            camera_input=camera_input,
        )
        try:
            self.gimbal = Gimbal.parse(gimbal)
        except ValueError as err:
            raise ConfigError(str(err)) from None
        self.batch_size = batch_size
        self.eval_batch_size = eval_batch_size or batch_size
        self.loader_kwargs = dict(
            num_workers=num_workers,
            pin_memory=pin_memory,
            persistent_workers=persistent_workers and num_workers > 0,
            collate_fn=collate,
        )
        self.split_names = tuple(splits)
        self.datasets: dict[str, AirFisheyeDataset | MultiSourceDataset] = {}
        self._resume_position: tuple[int, int] | None = None
        self._source_roots: dict[str, Path] | None = None
        self._readers: dict[str, DatasetSource] = {}
        self._camera_lines: set[str] = set()

    # ----------------------------------------------------------------------------------- Lightning hooks
    def prepare_data(self) -> None:
        """Generate the synthetic dataset (or sources) on first use (once per node)."""
        self.source_roots()

    def setup(self, stage: str | None = None) -> None:
        wanted = {"fit": (0, 1), "validate": (1,), "test": (2,), "predict": (2,), None: (0, 1, 2)}[stage]
        for i in wanted:
            name = self.split_names[i]
            if name not in self.datasets:
                augment = self.augment if i == 0 else None
                self.datasets[name] = self._open_split(i, augment)
                self._log_camera(self.datasets[name])
                # Build the lookup tables before any worker starts: forked workers share them.
                self.datasets[name].warm_up()
                if self.remap_on == "device":
                    self._check_device_remap(self.datasets[name])

    def _log_camera(self, dataset: AirFisheyeDataset | MultiSourceDataset) -> None:
        """Log the served camera (each source's) once: every split resolves the same one."""
        parts = dataset.datasets.values() if isinstance(dataset, MultiSourceDataset) else [dataset]
        for part in parts:
            if part.camera_line is not None and part.camera_line not in self._camera_lines:
                self._camera_lines.add(part.camera_line)
                log.info("%s", part.camera_line)

    def _open_split(
        self, index: int, augment: FisheyeAugment | None
    ) -> AirFisheyeDataset | MultiSourceDataset:
        # Training draws a view per sample and epoch; validation and test serve fixed views.
        gimbal = self.gimbal.for_split(training=index == 0) if self.gimbal is not None else None
        return open_split(
            self.sources,
            self._open_readers(),
            index,
            self.split_names,
            self.seed,
            augment,
            {**self.dataset_kwargs, "gimbal": gimbal, "training": index == 0},
            self.lidar.spec,
            self.mixture,
        )

    def _open_readers(self) -> dict[str, DatasetSource]:
        """Each source's reader, opened once (its ``dataset.yaml`` read and checked) for every split."""
        roots = self.source_roots()
        for src in self.sources:
            if src.name not in self._readers:
                with naming_source(src, self.mixture):
                    self._readers[src.name] = open_reader(
                        roots[src.name], src.format, src.format_options, self.task
                    )
        return self._readers

    def _check_device_remap(self, dataset: AirFisheyeDataset) -> None:
        """Every split is finished by one :class:`DeviceRemap` (a batch does not say which split it is from)."""
        remap = dataset.device_remap()
        if self._device_remap is None:
            self._device_remap = remap
        elif remap.key() != self._device_remap.key():
            raise ConfigError(
                f"data.remap_on=device: split {dataset.split!r} has another camera, cube-face size or data.gimbal "
                "view than the others; use data.remap_on=worker"
            )

    def on_after_batch_transfer(self, batch: Any, dataloader_idx: int) -> Any:
        """Under ``remap_on=device``, finish the batch of cube faces on its device (the batch a worker would have
        served); any other batch is returned as it is."""
        if self._device_remap is not None and isinstance(batch, dict):
            return self._device_remap(batch)
        return batch

    def _served(self, dataset: AirFisheyeDataset) -> AirFisheyeDataset | CubeFaces:
        """What a loader reads: the dataset, or under ``remap_on=device`` its decoded faces."""
        return CubeFaces(dataset) if self.remap_on == "device" else dataset

    def train_dataloader(self) -> DataLoader:
        dataset = self._dataset(0)
        sampler = training_sampler(dataset, self.sources, self.seed)
        if self._resume_position is not None:
            # Lightning creates the first iterator before it sets the epoch of a resumed run: set it here.
            epoch, batches_done = self._resume_position
            self._resume_position = None
            sampler.set_epoch(epoch)
            sampler.start = batches_done * self.batch_size
            self.set_epoch(epoch)
        return DataLoader(
            self._served(dataset),
            batch_size=self.batch_size,
            sampler=sampler,
            drop_last=True,
            generator=_own_generator(),
            **self.loader_kwargs,
        )

    def train_batches_per_rank(self, world_size: int) -> int:
        """Training batches each of ``world_size`` processes gets per epoch (0: it would train nothing)."""
        return batches_per_rank(len(self._dataset(0)), self.batch_size, world_size)

    def state_dict(self) -> dict[str, int]:
        """Where training stands in the epoch's batches, saved in every checkpoint (see ``load_state_dict``)."""
        trainer = self.trainer
        if trainer is None or trainer.state.fn != TrainerFn.FITTING:
            return {}
        epoch, batches_done = training_position(trainer)
        return {"train_epoch": epoch, "train_batches_done": batches_done}

    def load_state_dict(self, state_dict: dict[str, int]) -> None:
        """Make the next training loader continue at the saved position (exact mid-epoch resume)."""
        if "train_epoch" in state_dict:
            self._resume_position = (int(state_dict["train_epoch"]), int(state_dict["train_batches_done"]))

    def set_epoch(self, epoch: int) -> None:
        """Select the training augmentation of ``epoch`` (the task calls this at every epoch start)."""
        if self.split_names[0] in self.datasets:
            self.datasets[self.split_names[0]].set_epoch(epoch)

    def val_dataloader(self) -> DataLoader:
        return self._evaluation_loader(1)

    def test_dataloader(self) -> DataLoader:
        return self._evaluation_loader(2)

    def _evaluation_loader(self, index: int) -> DataLoader:
        # Under DDP each rank evaluates its own frames exactly once (Lightning's default sampler pads with repeats).
        dataset = self._dataset(index)
        sampler = evaluation_sampler(dataset)
        return EvaluationLoader(
            self._served(dataset),
            batch_size=self.eval_batch_size,
            shuffle=False,
            sampler=sampler,
            generator=_own_generator(),
            **self.loader_kwargs,
        )

    # ------------------------------------------------------------------------------------ information
    def dataset_root(self) -> Path:
        """The dataset folder (generating the synthetic preset if needed); a run of several sources has one per
        source (:meth:`source_roots`)."""
        if self.mixture:
            raise ConfigError(
                "data.sources: a run of several sources has one dataset root per source (source_roots())"
            )
        return self.source_roots()[self.sources[0].name]

    def source_roots(self) -> dict[str, Path]:
        """The dataset folder of each source (generating synthetic ones if needed, with ``data.lidar.preset``'s
        sensor)."""
        if self._source_roots is None:
            self._source_roots = {
                src.name: Path(src.root)
                if src.root is not None
                else ensure_dataset(
                    src.preset, root=self.cache_dir, seed=src.dataset_seed, lidar_preset=self.lidar.preset
                )
                for src in self.sources
            }
        return self._source_roots

    @property
    def source_names(self) -> list[str]:
        """The names of ``data.sources`` (empty for a single-dataset run)."""
        return [src.name for src in self.sources] if self.mixture else []

    def camera_of(self, source: str | None = None) -> CameraModel:
        """The served camera of one source (``None``: the run's camera, the first source's)."""
        dataset = self._any_dataset()
        return dataset.source_camera(source) if source is not None else dataset.camera

    @property
    def camera(self) -> CameraModel:
        """The served fisheye camera (after ``setup``)."""
        return self._any_dataset().camera

    def ray_map(self) -> torch.Tensor:
        """``[4, H, W]`` the ray map of :attr:`camera` over its pixels with data, as its samples carry it in
        ``rays`` (docs/design.md, "Ray map"); what an ONNX export with ``bake_camera=true`` holds as a constant."""
        return self._any_dataset().ray_map

    @property
    def num_classes(self) -> int:
        return self._any_dataset().spec.num_train_classes

    @property
    def class_names(self) -> list[str]:
        return self._any_dataset().spec.train_class_names

    @property
    def palette(self) -> np.ndarray:
        """``uint8 [256, 3]`` colours by training class id."""
        return self._any_dataset().spec.train_palette()

    @property
    def normalization(self) -> dict[str, tuple[float, float, float]]:
        return {"mean": IMAGENET_MEAN, "std": IMAGENET_STD}

    def split_dataset(self, split: str) -> AirFisheyeDataset:
        """The dataset of split ``train``, ``val`` or ``test`` (set up on demand; only ``train`` is augmented)."""
        stages = ("train", "val", "test")
        if split not in stages:
            raise ValueError(f"split must be one of {stages}, got {split!r}")
        return self._dataset(stages.index(split))

    def _dataset(self, index: int) -> AirFisheyeDataset:
        name = self.split_names[index]
        if name not in self.datasets:
            self.setup({0: "fit", 1: "validate", 2: "test"}[index])
        return self.datasets[name]

    def _any_dataset(self) -> AirFisheyeDataset:
        if not self.datasets:
            self.setup(None)
        return next(iter(self.datasets.values()))


def _occlusion(method: str, options: dict[str, Any] | None) -> Occlusion | str:
    """``data.occlusion`` with its options, resolved once (:func:`sparse_input`): the dataset takes it as it is."""
    try:
        return sparse_input(method, options)
    except ValueError as err:
        key = (
            f"data.occlusion_options (data.occlusion={method})"
            if method in SPARSE_INPUTS
            else "data.occlusion"
        )
        raise ConfigError(f"{key}: {err}") from None


@dataclass(frozen=True)
class LidarChoice:
    """``data.lidar.preset`` resolved once: the named sensor the synthetic sources are generated with (``None``:
    each preset's own; a spec file serves ``data.root`` releases only), and the spec that replaces ``calib.yaml``'s
    for a ``data.root`` source (``None``: its own)."""

    preset: str | None = None
    spec: LidarSpec | None = None


def _lidar(value: Any, sources: tuple[SourceConfig, ...], mixture: bool) -> LidarChoice:
    """``data.lidar.preset`` for every source of the run, read once (:func:`lidar_preset_problem` is its rule); a
    source's deprecated ``format_options.lidar`` naming another LiDAR is refused (the reader reads it otherwise)."""
    if value is None:
        return LidarChoice()
    for src in sources:
        conflict = lidar_option_conflict(
            src.format_options, value, f"{src.key}.format_options" if mixture else "data.format_options"
        )
        if conflict is not None:
            raise ConfigError(conflict)
        problem = lidar_preset_problem(value, synthetic=src.root is None)
        if problem is not None:
            where = f" (data.sources: source {src.describe()})" if mixture else ""
            raise ConfigError(f"data.lidar.preset={value!r}: {problem}{where}")
    try:
        spec = load_lidar_spec(value)
    except ValueError as err:  # DatasetFormatError (a spec file) is a ValueError too, naming the file
        raise ConfigError(f"data.lidar.preset={value!r}: {err}") from None
    return LidarChoice(str(value) if value in LIDAR_PRESETS else None, spec)


def _own_generator() -> torch.Generator:
    # Every iter() over a DataLoader draws its workers' base seed from this generator, by default the global one:
    # a resumed run, which starts one extra iterator, would then continue with the global RNG (dropout) off by
    # one draw. Samples do not depend on it (their draws are seeded by (seed, epoch, index)).
    return torch.Generator().manual_seed(0)


def _floats(options: dict[str, Any], key: str) -> dict[str, Any]:
    """``options`` with the list under ``key`` (a YAML list) as a tuple of floats."""
    if options.get(key) is not None:
        options[key] = tuple(float(v) for v in options[key])
    return options
