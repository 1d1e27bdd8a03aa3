"""``AirFisheyeDataset``: one split of a dataset in the AirFisheye layout, served for one task.

A sample is a dict:

=================  ============================  ==========================================================
key                shape, dtype                  meaning
=================  ============================  ==========================================================
``image``          ``[3, H, W]`` float32         RGB normalised with ImageNet mean/std
``valid_mask``     ``[H, W]`` bool               inside the image circle and seen by a cube face
``label``          ``[H, W]`` int64              training class, 255 = ignore (incl. outside)
``depth``          ``[1, H, W]`` float32         range in metres, 0 = invalid
``sparse_depth``   ``[1, H, W]`` float32         LiDAR range map after occlusion correction
``sample_id``      str                           ``<env>/<trajectory>/<frame>``
``lens``           ``[]`` int64                  the sample's lens in ``data.camera.lenses`` (0 without a list)
``lens_params``    ``[3 + D]`` float32           its jitter: focal factor, principal-point shift x, y (pixels),
                                                 the factors of its model's ``distortion_params`` (1 beyond
                                                 them); ``lens_camera(lens, lens_params)`` rebuilds the camera
``rays``           ``[4, H, W]`` float32         the sample's lens as a ray map: each pixel's unit ray in the
                                                 camera frame and 1 where it carries data (0 elsewhere, rays too)
=================  ============================  ==========================================================

``lens`` and ``lens_params`` are served with ``data.camera.lenses`` or ``data.camera.jitter`` only
(docs/design.md, "Lenses drawn per sample"): each sample's image, masks, maps and LiDAR go through that lens.

``rays`` is served with ``camera_input="rays"`` only (``data.camera_input``, following ``model.camera_input``):
:meth:`~datamodules.serving_remaps.RemapServing.sample_rays` (docs/design.md, "Ray map").

A source that has no dense depth images but gives its depth target as LiDAR points (``depth_from_points``,
``depth_points``: KITTI-360) gets ``depth`` by projecting them at the served camera with the sample's augmentation,
as ``sparse_depth``.

``image``, ``valid_mask`` and ``sample_id`` are always served; of the others, the keys the task's spec names
(its ``target`` and its model ``inputs``, :data:`SAMPLE_KEYS`): ``seg`` gets ``label``, ``depth`` gets ``depth``,
``completion`` gets ``depth`` and ``sparse_depth``.

Sources: ``cubemap`` remaps the raw cube faces on the fly with :class:`~airfisheye_bench.geometry.CubemapToFisheye`
at the requested camera (any lens, FOV and size, no re-generation: the lookup table is built directly at the
training resolution); ``equirect`` remaps equirectangular panoramas the same way with
:class:`~airfisheye_bench.geometry.EquirectToFisheye`, the camera turned by the source's ``pano_rotation``;
``fisheye`` reads the pre-rendered fisheye files (resized if the camera asks for another size).

LiDAR (``sparse_depth``): the scan's rings come from where they are known (docs/design.md, "Rings": a ring field
or the generator's ``lidar_beam``, the firing order of KITTI ``.bin``, else the channel table), then returns closer
than ``lidar_min_range`` and returns no channel explains are removed and counted (``lidar_counts``; logged for
the first frame a process serves), and with a paper reading of ``lidar_density`` (``paper`` = ``paper_1536``,
``paper_512``) only the returns of a fixed subset of beams are served, of those the occlusion correction kept on the
whole scan at the reading image's pixel scale. The scan is the
source's own (``lidar_scan``) or, with ``lidar_spec`` (``data.lidar.preset``), that sensor's (``cast_scan``: cast
into the depth by a source that simulates its LiDAR, the recorded scan otherwise); one whose LiDAR sees from the
camera's centre (``parallax_free``) has no point the camera cannot see, and its scans are projected without
occlusion correction.

Every member of the reader used here is declared by the contract of
:class:`~airfisheye_bench.io.datasets.base.DatasetSource`, with its default (``tests/io/datasets/test_contract.py``).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import Dataset

from airfisheye_bench.config_checks.data_options import default
from airfisheye_bench.constants import IMAGENET_MEAN, IMAGENET_STD
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry import CubemapToFisheye, EquirectToFisheye
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.gimbal import Gimbal, View
from airfisheye_bench.geometry.lens_draws import LensDraw, LensDraws
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.occlusion import (
    ORACLE,
    Occlusion,
    sparse_input,
)
from airfisheye_bench.geometry.scan_filter import DEFAULT_MIN_RANGE
from airfisheye_bench.geometry.serving import ServedCamera
from airfisheye_bench.io import DatasetFormatError, EmptySplitError
from airfisheye_bench.io.dataset_spec import IMAGE_SOURCES, REMAP_SOURCES
from airfisheye_bench.io.datasets import DatasetSource, dataset_format, open_dataset, unserved_modality
from airfisheye_bench.specs import get_task
from datamodules.augment import AugmentParams, FisheyeAugment, augment_sample
from datamodules.augment_batch import pack_params
from datamodules.camera_config import CameraConfig
from datamodules.device_remap import AUGMENT_KEY, CUBE_KEYS
from datamodules.oracle import require_visibility
from datamodules.sampling import SharedEpoch, draw_seed
from datamodules.serving_lidar import LidarServing
from datamodules.serving_remaps import RemapServing

log = logging.getLogger(__name__)

#: The task-dependent keys a sample can hold, in the order they are loaded.
SAMPLE_KEYS = ("label", "depth", "sparse_depth")
#: The paper's occlusion correction (III-C) with its default options.
PAPER_OCCLUSION = Occlusion("ordering")


class AirFisheyeDataset(RemapServing, LidarServing, Dataset):
    """One split of a dataset of any format, for one task, served through its reader.

    It takes resolved objects only, checked where they were built (the datamodule, from a config checked once): a
    reader (:func:`open_reader`), an :class:`~airfisheye_bench.geometry.occlusion.Occlusion` or the oracle
    (:func:`~airfisheye_bench.geometry.occlusion.sparse_input`), a :class:`CameraConfig`, a LiDAR spec.
    :meth:`from_root` opens a folder for a script or a test.

    Args:
        reader: The dataset's reader, opened once for every split of it (:func:`open_reader`).
        split: Split name (``train``, ``val``, ``test``).
        task: A registered task (``seg``, ``depth``, ``completion``, see :mod:`airfisheye_bench.specs`).
        source: ``cubemap`` or ``equirect`` (remap the cube faces or the panoramas on the fly) or ``fisheye``
            (pre-rendered files).
        camera: The served camera (see :class:`CameraConfig`).
        occlusion: The LiDAR occlusion correction for ``completion``, an
            :class:`~airfisheye_bench.geometry.occlusion.Occlusion` (the paper's ``ordering`` by default); or
            ``"oracle"``, the generator's exact visibility (synthetic releases only, see :mod:`datamodules.oracle`).
        motion_compensation: Use ``T_cam_lidar`` from both sensors' poses at their own timestamps; ``False`` uses
            the static extrinsics (for comparison).
        max_depth: Ground truth and sparse depth beyond this range are invalid (paper: 120 m).
        augment: Random augmentation, or ``None`` (evaluation). Its draws depend only on ``(seed, epoch, index)``.
        seed: Seed of the augmentation draws.
        skip_bad_frames: Return ``None`` for a frame that fails to load (logged) instead of raising;
            :func:`collate` drops it and counts it.
        lidar_spec: The LiDAR served (``data.lidar.preset``): the reader casts it (``cast_scan``: the recorded scan,
            which it describes, where the LiDAR is recorded); ``None``: the reader's own scans and each frame's
            calibration's spec.
        lidar_min_range: Returns closer than this (metres) are self-hits: removed and counted.
        lidar_density: ``native`` serves every return; ``paper_1536`` (or ``paper``) and ``paper_512`` a fixed
            subset of the scan's beams with which the served image gets the returns per pixel of the paper's sensor
            on its 1536^2 or its 512^2 image (:mod:`~airfisheye_bench.geometry.lidar_density`), of the returns the
            occlusion correction kept on the whole scan at that image's pixel scale (``paper_scale_camera``).
        gimbal: A virtual gimbal for this split (``Gimbal.parse(data.gimbal).for_split(training)``): each sample's
            camera is turned to its view before the remap (``source=cubemap`` or ``equirect``), and the LiDAR with it;
            ``None``: the recorded orientation.
        source_fallback: When the dataset has no ``source`` recording but the other raw one (``cubemap`` <->
            ``equirect``), remap that one instead (logged): a source of a mixture that ``data.source`` does not fit
            (a synthetic preset beside panoramas).
        training: Whether this is the training split: its samples draw their lens (``camera.lenses``, jitter) per
            epoch; an evaluation split serves sample ``i`` through lens ``i mod n``, unjittered. ``None``: ``split
            == "train"``.
        camera_input: ``rays``: serve each sample's ray map as ``rays``; ``none``: do not.

    Example:
        >>> ds = AirFisheyeDataset("/data/airfisheye", "train", "completion")  # doctest: +SKIP
        >>> sorted(ds[0])                                                     # doctest: +SKIP
        ['depth', 'image', 'sample_id', 'sparse_depth', 'valid_mask']
    """

    def __init__(
        self,
        reader: DatasetSource,
        split: str,
        task: str,
        source: str = default("source"),
        camera: CameraConfig | None = None,
        occlusion: Occlusion | str = PAPER_OCCLUSION,
        motion_compensation: bool = default("motion_compensation"),
        max_depth: float = default("max_depth"),
        augment: FisheyeAugment | None = None,
        skip_bad_frames: bool = default("skip_bad_frames"),
        seed: int = default("seed"),
        lidar_spec: LidarSpec | None = None,
        lidar_min_range: float = DEFAULT_MIN_RANGE,
        # Every return, as recorded, for a folder opened directly (from_root); the run's declared default
        # (data.lidar.density: paper) is the datamodule's, which hands its choice on.
        lidar_density: str = "native",
        gimbal: Gimbal | None = None,
        source_fallback: bool = False,
        training: bool | None = None,
        camera_input: str = default("camera_input"),
    ) -> None:
        task_spec = get_task(task)
        if gimbal is not None and source not in REMAP_SOURCES:
            raise ConfigError(
                "data.gimbal turns the camera of a remap source: it needs data.source=cubemap or equirect "
                "(pre-rendered fisheye images have a fixed orientation)"
            )
        needed = _needed_keys(task)
        self.reader = reader
        self.spec = self.reader.spec
        self.split = split
        self.task = task
        if source_fallback and source in REMAP_SOURCES and not self.spec.has(source):
            other = next((s for s in REMAP_SOURCES if self.spec.has(s)), None)
            if other is not None:
                log.info("%s has no %s: its %s are remapped instead", self.spec.name, source, other)
                source = other
        self.source = source
        self.occlusion = occlusion  # every frame is projected with it as it is
        # _paper_scale_visible's masks by frame and lens of the list
        self._visible_cache: dict[tuple[str, int], np.ndarray] = {}
        self.motion_compensation = motion_compensation
        self.max_depth = float(max_depth)
        self.augment = augment
        self.skip_bad_frames = skip_bad_frames
        self.seed = int(seed)
        self.lidar_spec = lidar_spec
        self.lidar_min_range = float(lidar_min_range)
        self.lidar_density = lidar_density
        #: Returns removed from the scans served by this process, by reason, and the ring sources used.
        self.lidar_counts: dict[str, int] = {}
        self._epoch = SharedEpoch()
        self.sample_ids = self.reader.split(split)
        if not self.sample_ids:  # a partial download: say what the split takes, not only that it has nothing
            raise EmptySplitError(
                self.reader.root,
                f"split {split!r} is empty (data.format={self.reader.format}): expected "
                f"{self.reader.split_rule(split)}",
            )
        if source in REMAP_SOURCES and not self.spec.has(source):
            served = [s for s in IMAGE_SOURCES if self.spec.has(s)] or ["fisheye"]
            raise ConfigError(f"{self.reader.missing_reason(source)}; use data.source={' or '.join(served)}")
        for content in task_spec.requires:
            if not self.spec.has(content):
                raise ConfigError(f"{self.reader.missing_reason(content)}; task={task} needs it")
        # A source without dense depth images may give its depth target as LiDAR points (``depth_points``).
        self._depth_from_points = self.reader.depth_from_points
        # And what this download lacks (an Omni360 scene without its depth folder), now that it is read.
        modality = unserved_modality(self.reader, needed)
        if modality is not None:
            raise ConfigError(f"{self.reader.missing_reason(modality)}; task={task} needs it")
        if needed - set(SAMPLE_KEYS):
            raise ValueError(
                f"task={task} needs sample keys {sorted(needed - set(SAMPLE_KEYS))} that the dataset cannot serve "
                f"(it serves image, {', '.join(SAMPLE_KEYS)})"
            )
        self.sample_keys = tuple(k for k in SAMPLE_KEYS if k in needed)
        self.serves_rays = camera_input == "rays"
        # A LiDAR at the camera's centre (cast from its depth) returns only points the camera sees.
        self.parallax_free = self.reader.parallax_free
        if self.parallax_free and "sparse_depth" in self.sample_keys:
            log.info(
                "%s: the LiDAR sees from the camera's centre (no parallax): its scans are projected without "
                "occlusion correction (data.occlusion applies to sources with a LiDAR apart from the camera)",
                self.spec.name,
            )
        elif occlusion == ORACLE and "sparse_depth" in self.sample_keys:
            require_visibility(self.reader, self.reader.root)

        first_calib = self.reader.calib(self.sample_ids[0])
        self.calibrated_camera = first_calib.fisheye_camera()
        camera = camera or CameraConfig()
        if camera.draws_lenses and source not in REMAP_SOURCES:
            raise ConfigError(
                f"data.camera.lenses / data.camera.jitter remap each sample through its own lens: they need "
                f"data.source=cubemap or equirect (data.source={source} files have the release's lens)"
            )
        configs, weights = camera.served_lenses
        #: Each lens of ``data.camera.lenses`` as served (one without a list); ``served`` is the first.
        self.served_lenses = tuple(c.resolve(self.calibrated_camera, source) for c in configs)
        self.served = self.served_lenses[0]
        #: The served camera's log line, if it says more than the release's lens (the datamodule logs it once).
        self.camera_line = (
            camera.describe(self.served) if len(configs) == 1 else _lenses_line(self.served_lenses)
        )
        #: The served camera (with ``data.camera.lenses``: the first lens, evaluation sample 0's).
        self.camera = self.served.camera
        # Pixels beyond a padded calibration's sensor, per lens: no data there (None when every pixel is on it).
        self._outside_frames = tuple(_beyond_sensor(s) for s in self.served_lenses)
        self._outside_frame = self._outside_frames[0]
        #: How this split's samples get their lens (``None``: every sample the one lens of ``data.camera``).
        self.lens_draws = (
            LensDraws(
                weights,
                camera.lens_jitter,
                tuple(len(s.camera.distortion_params) for s in self.served_lenses),
            ).for_split(split == "train" if training is None else training)
            if camera.draws_lenses
            else None
        )
        self.face_size = first_calib.face_size
        self.label_lut = torch.from_numpy(self.spec.label_lut())
        self.gimbal = gimbal
        fixed = gimbal.fixed if gimbal is not None else None
        # The remap of the split's one orientation (recorded, or the gimbal's fixed view) and first lens; per-sample
        # views and lenses get theirs, the latest of them kept in a cache of what the table budget holds.
        self._base_view: View = fixed or (0.0, 0.0, 0.0)
        self._remap = self._build_remap(self._base_view, None) if source in REMAP_SOURCES else None
        self._remaps = self._table_cache()
        self._mean = torch.tensor(IMAGENET_MEAN).view(3, 1, 1)
        self._std = torch.tensor(IMAGENET_STD).view(3, 1, 1)

    @classmethod
    def from_root(
        cls,
        root: str | Path,
        split: str,
        task: str,
        format: str = "airfisheye",
        format_options: Mapping[str, Any] | None = None,
        occlusion: str = "ordering",
        occlusion_options: Mapping[str, Any] | None = None,
        **kwargs: Any,
    ) -> AirFisheyeDataset:
        """A split of the dataset folder ``root`` (laid out as ``format``), for a script or a test: the folder is
        opened by :func:`open_reader` and the occlusion resolved by
        :func:`~airfisheye_bench.geometry.occlusion.sparse_input`, as the datamodule does; ``kwargs`` are the
        constructor's.

        Example:
            >>> ds = AirFisheyeDataset.from_root(root, "val", "seg", camera=CameraConfig(size=32))  # doctest: +SKIP
        """
        reader = open_reader(root, format, format_options, task)
        return cls(reader, split, task, occlusion=sparse_input(occlusion, occlusion_options), **kwargs)

    def __len__(self) -> int:
        return len(self.sample_ids)

    def __getitem__(self, index: int) -> dict | None:
        return self._guarded(self._load, index)

    def load_faces(self, index: int) -> dict | None:
        """What a worker serves under ``data.remap_on=device``: the decoded cube faces, the LiDAR depth and the
        augmentation draw, for :class:`~datamodules.device_remap.DeviceRemap` to finish on the model's device."""
        return self._guarded(self._load_faces, index)

    def _guarded(self, load, index: int) -> dict | None:
        sample_id = self.sample_ids[index]
        try:
            return load(sample_id, index)
        except (DatasetFormatError, OSError, ValueError) as err:
            if not self.skip_bad_frames:
                raise
            log.warning("skipping bad frame %s: %s", sample_id, err)
            return None

    # ------------------------------------------------------------------------------------------------ loading
    def set_epoch(self, epoch: int) -> None:
        """Select the augmentation draws of ``epoch`` (visible to persistent workers too)."""
        self._epoch.set(epoch)

    def _draw(self, index: int) -> AugmentParams | None:
        """The sample's augmentation (``None`` without): it depends only on ``(seed, epoch, index)``."""
        if self.augment is None:
            return None
        generator = torch.Generator().manual_seed(draw_seed(self.seed, self._epoch.get(), index))
        return self.augment.sample(generator)

    def _load(self, sample_id: str, index: int) -> dict:
        params = self._draw(index)
        view = self.sample_view(index)
        lens = self.sample_lens(index)
        remap = None if self._remap is None else self._remap_for(view or self._base_view, lens)
        # The sample's lens: its image, masks, maps and LiDAR are all served through it.
        camera = self.camera if remap is None else remap.camera
        outside = self._outside_frame if lens is None else self._outside_frames[lens.lens]
        valid = served_valid = self.valid_mask if remap is self._remap else self._valid(remap, outside)
        turn = None if view is None else Gimbal.rotation(view)  # R_src_cam: the LiDAR turns with the camera
        rgb = self._dense(sample_id, "rgb", remap)  # uint8 [3, H, W]
        out: dict = {"sample_id": sample_id}
        if "label" in self.sample_keys:
            out["label"] = self._label(sample_id, remap)
        if "depth" in self.sample_keys and self._depth_from_points:
            out["depth"] = self._point_depth(
                sample_id, params, turn, camera
            )  # at the served, augmented camera
        elif "depth" in self.sample_keys:
            out["depth"] = self._clip_depth(self._dense(sample_id, "depth", remap))  # float32 [1, H, W]
        if "sparse_depth" in self.sample_keys:
            out["sparse_depth"] = self._sparse_depth(sample_id, params, turn, camera)
        if outside is not None:  # a padded calibration: the bands beyond its sensor show nothing
            rgb = rgb.masked_fill(outside, 0)
            if "label" in out:
                out["label"] = out["label"].masked_fill(outside, self.spec.ignore_index)
            if "depth" in out:
                out["depth"] = out["depth"].masked_fill(outside, 0.0)

        if params is not None:
            rgb, valid, out = self._augment(rgb, valid, out, params, camera)
        if "label" in out:
            out["label"] = out["label"].long()
        for key in ("sparse_depth", "depth") if self._depth_from_points else ("sparse_depth",):
            if key in out:
                # A point just inside FOV/2 can round to a border pixel whose centre is just outside the circle.
                out[key].mul_(valid)
        if rgb.dtype == torch.uint8:
            rgb = rgb.float().div_(255.0)
        out["image"] = rgb.sub_(self._mean).div_(self._std)  # rgb is this sample's own buffer: in place
        out["valid_mask"] = valid
        self._add_lens(out, lens)
        if self.serves_rays:  # the lens's map, before the augmentation moved the mask (it keeps the rays)
            out["rays"] = self.sample_rays(remap, served_valid)
        return out

    def _add_lens(self, out: dict, lens: LensDraw | None) -> None:
        """A sample's lens draw, collatable: ``lens`` (int64) and ``lens_params`` (float32 ``[3 + D]``)."""
        if self.lens_draws is not None and lens is not None:
            out["lens"] = torch.tensor(lens.lens, dtype=torch.int64)
            out["lens_params"] = lens.params(self.lens_draws.width)

    def _load_faces(self, sample_id: str, index: int) -> dict:
        """:meth:`load_faces` of one frame: the checks that name a file are made here, on the texels the fisheye
        sees, so a bad file fails in the worker (and ``skip_bad_frames`` skips it) as it does on the worker path."""
        params = self._draw(index)
        out: dict = {
            "sample_id": sample_id,
            CUBE_KEYS["rgb"]: torch.from_numpy(self._checked_faces(sample_id, "rgb")),
        }
        if "label" in self.sample_keys:
            raw = self._checked_faces(sample_id, "seg")
            unknown = self.spec.unknown_label_ids(raw.reshape(-1)[self._seen_texels])
            if unknown:
                raise DatasetFormatError(
                    self._path(sample_id, "seg"), f"label ids {unknown} are not raw classes of dataset.yaml"
                )
            out[CUBE_KEYS["seg"]] = torch.from_numpy(raw)
        if "depth" in self.sample_keys:
            depth = self._checked_faces(sample_id, "depth")
            self._check_finite(torch.from_numpy(depth.reshape(-1)[self._seen_texels]), sample_id, "depth")
            out[CUBE_KEYS["depth"]] = torch.from_numpy(depth).float()
        if "sparse_depth" in self.sample_keys:  # masked on the device, by the moved mask
            view = self.sample_view(index)  # the split's one view (device_remap refuses views that vary)
            turn = None if view is None else Gimbal.rotation(view)
            out["sparse_depth"] = self._sparse_depth(sample_id, params, turn)
        if params is not None:
            out[AUGMENT_KEY] = pack_params(params)
        # The split's one lens (device_remap refuses lenses that vary).
        self._add_lens(out, self.sample_lens(index))
        if self.serves_rays:
            out["rays"] = self.ray_map
        return out

    @cached_property
    def _seen_texels(self) -> np.ndarray:
        """Flat indices of the face texels the served fisheye shows (the nearest table's)."""
        return np.unique(self._remap.table("nearest").index[:, 0].numpy())

    def _augment(
        self, rgb: torch.Tensor, valid: torch.Tensor, out: dict, params, camera: CameraModel
    ) -> tuple:
        """Flip, rotate and colour-jitter every map of a sample consistently, in one fused pass."""
        maps, fills = [], []
        if "label" in out:
            maps.append(out["label"][None].float())
            fills.append(float(self.spec.ignore_index))
        dense_depth = "depth" in out and not self._depth_from_points  # point depth is projected already moved
        if dense_depth:
            maps.append(out["depth"])
            fills.append(0.0)
        h, w = valid.shape
        rgb, valid, moved = augment_sample(
            rgb,
            valid,
            torch.cat(maps) if maps else torch.zeros(0, h, w),
            fills,
            params,
            camera.cx,
            camera.cy,
        )
        if "label" in out:
            out["label"] = moved[0].to(out["label"].dtype)
        if dense_depth:
            out["depth"] = moved[-1:]
        return rgb, valid, out

    def _label(self, sample_id: str, remap: CubemapToFisheye | EquirectToFisheye | None) -> torch.Tensor:
        """Training-class ids ``[H, W]`` (raw ids mapped through ``dataset.yaml``; unknown raw ids are an error)."""
        raw = self._dense(sample_id, "seg", remap)[0]
        unknown = self.spec.unknown_label_ids(raw.numpy())
        if unknown:
            raise DatasetFormatError(
                self._path(sample_id, "seg"), f"label ids {unknown} are not raw classes of dataset.yaml"
            )
        return self.label_lut[raw.long()]

    def _dense(
        self, sample_id: str, modality: str, remap: CubemapToFisheye | EquirectToFisheye | None
    ) -> torch.Tensor:
        """One dense modality at the served camera (through ``remap``: the sample's view): ``[C, H, W]`` (uint8 RGB
        / raw labels, float32 depth)."""
        if remap is not None:
            faces = (
                self._faces(sample_id, modality)
                if self.source == "cubemap"
                else self._panorama(sample_id, modality)
            )
            if modality == "rgb":
                return remap(faces, "bilinear")
            out = remap(faces, "nearest", fill=self.spec.ignore_index if modality == "seg" else 0)
            if modality == "depth":  # only the texels the fisheye sees matter
                self._check_finite(out, sample_id, modality)
            return out
        image = self.reader.fisheye(sample_id, modality)
        expected = (self.calibrated_camera.height, self.calibrated_camera.width)
        if image.shape[:2] != expected:
            raise DatasetFormatError(
                self._path(sample_id, modality),
                f"image is {image.shape[1]}x{image.shape[0]}, calib.yaml says {expected[1]}x{expected[0]}",
            )
        x = torch.from_numpy(image)
        x = x.permute(2, 0, 1) if x.ndim == 3 else x[None]
        if modality == "depth":
            self._check_finite(x, sample_id, modality)
        if (self.camera.height, self.camera.width) == expected:
            return x.contiguous()
        size = (self.camera.height, self.camera.width)
        if modality == "rgb":  # antialiased downsampling, as renderers do
            return F.interpolate(x[None].float(), size=size, mode="area")[0].round().to(torch.uint8)
        return F.interpolate(x[None], size=size, mode="nearest-exact")[0]

    def _faces(self, sample_id: str, modality: str) -> torch.Tensor:
        """Stacked faces ``[5, C, S, S]``; RGB stays channels-last in memory (no copy) for the remap kernel."""
        x = torch.from_numpy(self._checked_faces(sample_id, modality))
        return x.permute(0, 3, 1, 2) if x.ndim == 4 else x[:, None]

    def _checked_faces(self, sample_id: str, modality: str) -> np.ndarray:
        """The decoded faces as the reader gives them: ``[5, S, S, 3]`` RGB, ``[5, S, S]`` labels or depth."""
        faces = self.reader.cubemap(sample_id, modality)
        if faces.shape[1:3] != (self.face_size, self.face_size):
            raise DatasetFormatError(
                self._path(sample_id, modality),
                f"cube faces are {faces.shape[2]}x{faces.shape[1]}, calib.yaml says "
                f"face_size={self.face_size}",
            )
        return faces

    def _panorama(self, sample_id: str, modality: str) -> torch.Tensor:
        """A panorama ``[C, H, W]`` (its size checked by the source); RGB stays channels-last in memory (no copy)."""
        x = torch.from_numpy(self.reader.equirect(sample_id, modality))
        return x.permute(2, 0, 1) if x.ndim == 3 else x[None]

    def _clip_depth(self, depth: torch.Tensor) -> torch.Tensor:
        depth = depth.float()
        return depth.masked_fill_(~((depth > 0) & (depth <= self.max_depth)), 0.0)

    def _check_finite(self, x: torch.Tensor, sample_id: str, modality: str) -> None:
        if not torch.isfinite(x).all():
            raise DatasetFormatError(
                self._path(sample_id, modality), "depth contains NaN or inf (0 marks invalid)"
            )

    def _path(self, sample_id: str, modality: str) -> Path:
        return self.reader.path_of(sample_id, modality, self.source)


def open_reader(
    root: str | Path,
    format: str = "airfisheye",
    format_options: Mapping | None = None,
    task: str | None = None,
) -> DatasetSource:
    """The reader of a dataset folder for ``task``: what each split of it reads (the datamodule opens it once per
    source). A map the format never has (WoodScape's depth) is refused before the folder is read: a wrong or empty
    root would otherwise be reported first, for a command that cannot run on any root of that format.

    Raises:
        ConfigError: ``data.format`` unknown, or a map ``task`` needs that the format never has.
        DatasetFormatError: the folder does not hold a dataset of that format (naming the file).
    """
    if task is not None:
        fixed = dataset_format(format)
        modality = unserved_modality(fixed, _needed_keys(task))
        if modality is not None:
            raise ConfigError(f"{fixed.missing_reason(modality)}; task={task} needs it")
    return open_dataset(root, format, dict(format_options or {}))


def _needed_keys(task: str) -> set[str]:
    """The sample keys besides the image that ``task`` trains on (its target and its model inputs)."""
    spec = get_task(task)
    return {spec.target, *spec.inputs} - {"image"}


def _beyond_sensor(served: ServedCamera) -> torch.Tensor | None:
    """``[H, W]`` pixels beyond a padded calibration's sensor (``None`` when every pixel is on it)."""
    outside = ~served.frame_mask() if served.fit == "pad" else None
    return outside if outside is not None and outside.any() else None


def _lenses_line(served: tuple[ServedCamera, ...]) -> str:
    """The log line of ``data.camera.lenses``."""
    lenses = "; ".join(f"{i}: {s.camera!r}" for i, s in enumerate(served))
    return f"camera: {len(served)} lenses, drawn per training sample (evaluation: sample i through lens i mod n): {lenses}"


def collate(samples: list[dict | None]) -> dict:
    """Stack samples, dropping frames that failed to load (``skip_bad_frames``); ``num_skipped`` counts them."""
    kept = [s for s in samples if s is not None]
    if not kept:
        return {"num_skipped": len(samples)}
    batch: dict = {}
    for key in kept[0]:
        values = [s[key] for s in kept]
        batch[key] = torch.stack(values) if isinstance(values[0], torch.Tensor) else values
    batch["num_skipped"] = len(samples) - len(kept)
    return batch


__all__ = ["SAMPLE_KEYS", "AirFisheyeDataset", "CameraConfig", "collate", "open_reader"]
