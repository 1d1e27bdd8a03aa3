"""WoodScape (``data.format=woodscape``): Valeo's surround-view fisheye images with semantic labels.

Sources (github:valeoai/WoodScape at 597d9dda472c09bafea58ea69853948d63197eca):

- ``README.md`` ("Data organization"): ``rgb_images/<id>_<CAM>.png``, ``semantic_annotations/gtLabels/<id>_<CAM>.png``,
  ``calibration_data/<id>_<CAM>.json``; ``CAM`` is ``FV`` (front), ``MVL`` / ``MVR`` (mirror left / right), ``RV``
  (rear). ``omnidet/data_loader/woodscape_loader.py`` reads the calibration from ``calibration_data/calibration/``
  (the folder of the download's ``calibration.zip``); a root may hold ``calibration/`` directly. The first of
  :data:`CALIB_DIRS` that exists is read.
- ``scripts/calibration/calibration_readme.txt``, ``projection.py``: one JSON per image, ``radial_poly`` intrinsics
  and the camera -> vehicle pose (ISO 8855: x forward, y left, z up = the project's FLU body frame), read by
  :mod:`airfisheye_bench.io.calibration_files.woodscape` (not re-parsed here).
- ``scripts/configs/semantic_mapping_9_classes.json`` and ``scripts/parsers/segmentation/image_annotator.py``: the
  ``gtLabels`` PNGs are single-channel class indices, 0 = void (everything not annotated), 1 road, 2 lanemarks,
  3 curb, 4 person, 5 rider, 6 vehicles, 7 bicycle, 8 motorcycle, 9 traffic_sign; colours are that file's (BGR
  there, RGB here). ``omnidet/data/params.yaml`` trains on all 10, void included (``semantic_num_classes: 10``).
- ``omnidet/data/val.txt``: the devkit's validation list (205 images, bundled in ``woodscape_splits/``); ``train`` is
  every other image of the chosen views (``omnidet/data/train.txt`` is exactly that on the released 8234). The
  1766 held-out test images (``omnidet/data/test.txt``) are numbered apart, reuse train ids and come without labels,
  so they form no split here; ``split_lists`` reads other lists (``train.txt``, ``val.txt``, ``test.txt``).
- No LiDAR, no depth: never released (github:valeoai/WoodScape issues #31, #43, #82). ``depth`` and
  ``completion`` are refused through :meth:`WoodScapeSource.missing_reason`.

The served camera: every image has its own calibration file (one per vehicle and camera in fact); the datamodule
serves the first image's camera of a split. :meth:`WoodScapeSource.split` checks that every other camera of the
split maps that camera's pixels within ``calib_tolerance`` (a fraction of the width) of where it puts them; the
labels come with their own image, so only the valid region and the augmentation's centre depend on it. With
``crop_to_4x3`` the images lose their outer rows down to a 4:3 frame (1280x966 -> 1280x960, 3 rows top and bottom):
the datamodule resizes pre-rendered images only to an exact aspect ratio, which 966/1280 reaches at 640 and 1280 only.

Example:
    >>> source = WoodScapeSource("/data/woodscape", views=["FV"])   # doctest: +SKIP
    >>> sid = source.split("val")[0]; source.fisheye(sid, "seg").shape  # doctest: +SKIP
    (960, 1280)
"""

from __future__ import annotations

import json
import logging
import re
from pathlib import Path
from typing import ClassVar

import numpy as np
import torch

from airfisheye_bench.errors import ConfigError, MissingFileError
from airfisheye_bench.geometry.cameras import camera_from_dict
from airfisheye_bench.io import codecs
from airfisheye_bench.io.benchmark_classes import BENCHMARK_CLASSES, BENCHMARK_ID
from airfisheye_bench.io.calib_yaml import Calibration
from airfisheye_bench.io.calibration_files import read_calibration
from airfisheye_bench.io.dataset_spec import ClassDef, DatasetSpec, SplitsSpec
from airfisheye_bench.io.datasets.base import DatasetSource
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.scan import Scan

__all__ = ["BENCHMARK_MAP", "CALIB_DIRS", "CLASSES", "VIEWS", "WoodScapeSource"]

log = logging.getLogger(__name__)

VIEWS = ("FV", "MVL", "MVR", "RV")
RGB_DIR = "rgb_images"
SEG_DIR = "semantic_annotations/gtLabels"
#: Where the calibration JSONs may be, tried in order (see the module docstring).
CALIB_DIRS = ("calibration", "calibration_data/calibration", "calibration_data")
_SPLITS_DIR = Path(__file__).with_name("woodscape_splits")
_ID = re.compile(r"^\d{5}_(FV|MVL|MVR|RV)$")

#: The ``gtLabels`` ids (``semantic_mapping_9_classes.json``; void is 0), RGB colours of its ``rgbLabels``.
CLASSES: tuple[ClassDef, ...] = (
    ClassDef(0, "void", (0, 0, 0)),
    ClassDef(1, "road", (255, 0, 255)),
    ClassDef(2, "lanemarks", (0, 0, 255)),
    ClassDef(3, "curb", (0, 255, 0)),
    ClassDef(4, "person", (255, 0, 0)),
    ClassDef(5, "rider", (255, 255, 255)),
    ClassDef(6, "vehicles", (0, 255, 255)),
    ClassDef(7, "bicycle", (255, 255, 0)),
    ClassDef(8, "motorcycle", (255, 128, 128)),
    ClassDef(9, "traffic_sign", (128, 128, 0)),
)

#: ``classes: benchmark``: WoodScape class -> benchmark class (:mod:`airfisheye_bench.io.benchmark_classes`).
#: Unlisted ones are ignored: void lumps sky, buildings, vegetation and the ego vehicle together; the benchmark has
#: no person, rider, bicycle or motorcycle class. Lane marks are road and signs are poles, as the synthetic merge
#: has them (``synth/classes.py``); the curb goes with the sidewalk, as Cityscapes labels it.
BENCHMARK_MAP: dict[str, str] = {
    "road": "road",
    "lanemarks": "road",
    "curb": "sidewalk",
    "vehicles": "vehicle",
    "traffic_sign": "pole",
}

_NO_DEPTH = (
    "WoodScape released no LiDAR and no depth ground truth (its 'Lidar and dGPS scenes' never came out: "
    "github:valeoai/WoodScape issues #31, #43, #82)"
)


def woodscape_spec(classes: str = "dataset") -> DatasetSpec:
    """The classes of ``classes: dataset`` (WoodScape's 10, void included) or ``benchmark`` (:data:`BENCHMARK_MAP`).

    Example:
        >>> woodscape_spec("benchmark").label_lut()[[0, 1, 2, 3, 6, 9]].tolist()
        [255, 1, 1, 2, 10, 11]
    """
    if classes == "dataset":
        train, mapping = CLASSES, {c.id: c.id for c in CLASSES}
    elif classes == "benchmark":
        train = BENCHMARK_CLASSES
        mapping = {c.id: BENCHMARK_ID[BENCHMARK_MAP[c.name]] for c in CLASSES if c.name in BENCHMARK_MAP}
    else:
        raise ConfigError(f"data.format_options.classes={classes!r}: expected dataset or benchmark")
    return DatasetSpec(
        name=f"woodscape-{classes}",
        raw_classes=CLASSES,
        train_classes=train,
        raw_to_train=mapping,
        splits=SplitsSpec(files={"train": "rgb_images", "val": "woodscape_splits/val.txt"}, by="image"),
        contents=("fisheye",),
        description="WoodScape (github:valeoai/WoodScape): fisheye RGB and semantic labels, no depth",
    )


class WoodScapeSource(DatasetSource):
    """A WoodScape root read as a :class:`~airfisheye_bench.io.datasets.base.DatasetSource`.

    Args:
        root: The folder holding ``rgb_images/``, ``semantic_annotations/`` and the calibration folder.
        views: The cameras served (``FV``, ``MVL``, ``MVR``, ``RV``).
        classes: ``dataset`` (WoodScape's 10 classes) or ``benchmark`` (mapped onto the synthetic data's 13).
        split_lists: A folder of ``train.txt``, ``val.txt`` (``test.txt``) in OmniDet's format (one
            ``<id>_<CAM>.png`` a line) instead of the devkit's validation list.
        crop_to_4x3: Serve the central 4:3 rows of images taller than that (1280x966 -> 1280x960).
        calib_tolerance: How far (a fraction of the image width) another image's camera may put the served camera's
            pixels before the split is refused.
    """

    format: ClassVar[str] = "woodscape"
    OPTIONS: ClassVar[dict[str, object]] = {
        "views": list(VIEWS),
        "classes": "dataset",
        "split_lists": None,
        "crop_to_4x3": True,
        "calib_tolerance": 0.02,
    }
    #: The dense maps the dataset has (no depth).
    modalities: ClassVar[tuple[str, ...]] = ("rgb", "seg")

    def __init__(
        self,
        root: str | Path,
        views: list[str] | tuple[str, ...] = VIEWS,
        classes: str = "dataset",
        split_lists: str | Path | None = None,
        crop_to_4x3: bool = True,
        calib_tolerance: float = 0.02,
    ) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise ValueError(f"root must be an existing WoodScape folder, got {str(self.root)!r}")
        views = [views] if isinstance(views, str) else list(views)
        if not views or any(v not in VIEWS for v in views):
            raise ConfigError(
                f"data.format_options.views={views}: expected a non-empty list of {list(VIEWS)}"
            )
        if isinstance(calib_tolerance, bool) or not float(calib_tolerance) > 0:
            raise ConfigError(
                f"data.format_options.calib_tolerance={calib_tolerance!r}: expected a number > 0"
            )
        self.views = tuple(v for v in VIEWS if v in views)
        self.classes = classes
        self.spec = woodscape_spec(classes)
        self.split_lists = Path(split_lists) if split_lists is not None else None
        self.crop_to_4x3 = bool(crop_to_4x3)
        self.calib_tolerance = float(calib_tolerance)
        self.rgb_dir = self.root / RGB_DIR
        if not self.rgb_dir.is_dir():
            raise DatasetFormatError(
                self.rgb_dir, "missing: not a WoodScape root (expected rgb_images/<id>_<FV|MVL|MVR|RV>.png)"
            )
        self.seg_dir = self.root / SEG_DIR
        found = [self.root / d for d in CALIB_DIRS if (self.root / d).is_dir()]
        if not found:
            raise DatasetFormatError(
                self.root / CALIB_DIRS[0],
                f"missing: no calibration folder (expected one of {list(CALIB_DIRS)})",
            )
        self.calib_dir = found[0]
        self._split_cache: dict[str, list[str]] = {}
        # A calibration file's contents -> (its camera, T_vehicle_cam): files of one vehicle's camera are equal.
        self._camera_cache: dict[str, tuple[dict, np.ndarray]] = {}

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_camera_cache": {}}

    # ------------------------------------------------------------------------------------------- splits
    @property
    def split_names(self) -> list[str]:
        if self.split_lists is None:
            return ["train", "val"]
        return [n for n in ("train", "val", "test") if (self.split_lists / f"{n}.txt").is_file()]

    def split(self, name: str) -> list[str]:
        """Sample ids ``<id>_<CAM>`` of ``name`` (of the chosen views), in file order; the cameras checked."""
        if name not in self.split_names:
            raise ConfigError(
                f"data.splits: no split {name!r} in data.format=woodscape (it has {', '.join(self.split_names)}; a "
                "test split needs data.format_options.split_lists, a folder holding test.txt)"
            )
        if name not in self._split_cache:
            if self.split_lists is not None:
                ids = self._selected(_read_list(self.split_lists / f"{name}.txt"))
            else:
                val = self._selected(_read_list(_SPLITS_DIR / "val.txt"))
                on_disk = self._on_disk()
                ids = (
                    [s for s in val if s in set(on_disk)]
                    if name == "val"
                    else sorted(set(on_disk) - set(val))
                )
            if ids:
                self._check_cameras(name, ids)
            self._split_cache[name] = ids
        return list(self._split_cache[name])

    def split_rule(self, name: str) -> str:
        images = f"{self.rgb_dir}/<id>_<CAM>.png images of the views {', '.join(self.views)}"
        if self.split_lists is not None:
            return f"{images} listed in {self.split_lists / f'{name}.txt'}"
        if name == "val":
            return (
                f"{images} of the devkit's validation list ({len(_read_list(_SPLITS_DIR / 'val.txt'))} images); "
                "data.format_options.split_lists gives lists of one's own"
            )
        return f"{images} not in the devkit's validation list"

    def _selected(self, ids: list[str]) -> list[str]:
        return [s for s in ids if s.rsplit("_", 1)[1] in self.views]

    def _on_disk(self) -> list[str]:
        ids = sorted(p.stem for p in self.rgb_dir.glob("*.png") if _ID.match(p.stem))
        return self._selected(ids)

    def _check_cameras(self, name: str, ids: list[str]) -> None:
        """Refuse a split whose cameras differ from its first image's by more than ``calib_tolerance``."""
        # A calibration file that cannot be read is named when its image is loaded (the first one's by the dataset).
        try:
            first = self.calib(ids[0]).camera
        except DatasetFormatError:
            return
        served = camera_from_dict(first)
        step = max(1, served.width // 32)
        v, u = torch.meshgrid(
            torch.arange(0, served.height, step, dtype=torch.float64),
            torch.arange(0, served.width, step, dtype=torch.float64),
            indexing="ij",
        )
        grid = torch.stack([u, v], -1).reshape(-1, 2)
        rays = served.unproject(grid)
        inside = torch.isfinite(rays).all(-1)
        worst, seen = 0.0, {}
        for sid in ids:
            try:
                camera = self.calib(sid).camera
            except DatasetFormatError:
                continue
            key = json.dumps(camera, sort_keys=True)
            if key in seen:
                continue
            path = self.path_of(sid, "calib", "fisheye")
            if (camera["width"], camera["height"]) != (first["width"], first["height"]):
                raise DatasetFormatError(
                    path,
                    f"a {camera['width']}x{camera['height']} camera in split {name}, whose first image "
                    f"{ids[0]} has {first['width']}x{first['height']}",
                )
            uv, valid = camera_from_dict(camera).project(rays[inside])
            ok = valid & torch.isfinite(uv).all(-1)
            shift = float((uv[ok] - grid[inside][ok]).norm(dim=-1).max()) if ok.any() else 0.0
            seen[key] = shift
            worst = max(worst, shift)
            if shift > self.calib_tolerance * first["width"]:
                raise DatasetFormatError(
                    path,
                    f"its camera puts pixels up to {shift:.1f} px from where the split's served camera (its first "
                    f"image, {ids[0]}) has them, more than data.format_options.calib_tolerance="
                    f"{self.calib_tolerance} of the width: serve one view (data.format_options.views=[FV]) or "
                    "raise the tolerance",
                )
        log.info(
            "woodscape %s: %d images, %d distinct cameras, within %.2f px of the served one (%s)",
            name,
            len(ids),
            len(seen),
            worst,
            ids[0],
        )

    # -------------------------------------------------------------------------------------- per sample
    def calib(self, sample_id: str) -> Calibration:
        """The image's own camera (cropped to 4:3 when asked) and ``T_body_cam`` = its camera -> vehicle pose."""
        path, camera, pose = self._calibration_file(sample_id)
        camera = dict(camera)
        top, rows = self._crop(camera["width"], camera["height"])
        camera["height"], camera["cy"] = rows, camera["cy"] - top
        return Calibration(camera, None, pose.copy(), np.eye(4), {}, {"calibration_file": str(path)})

    def fisheye(self, sample_id: str, modality: str) -> np.ndarray:
        """The recorded image: ``rgb`` uint8 ``[H, W, 3]`` or ``seg`` raw ids ``[H, W]`` (the 4:3 crop applied)."""
        if modality not in self.modalities:
            raise DatasetFormatError(self.root, self.missing_reason(modality))
        path = self.path_of(sample_id, modality, "fisheye")
        image = codecs.read_rgb(path) if modality == "rgb" else codecs.read_label(path)
        calib_path, camera, _ = self._calibration_file(sample_id)
        width, height = int(camera["width"]), int(camera["height"])
        if image.shape[:2] != (height, width):
            raise DatasetFormatError(
                path,
                f"image is {image.shape[1]}x{image.shape[0]}, its {calib_path.name} says {width}x{height}",
            )
        top, rows = self._crop(width, height)
        return np.ascontiguousarray(image[top : top + rows])

    def cubemap(self, sample_id: str, modality: str) -> np.ndarray:
        raise DatasetFormatError(self.root, self.missing_reason("cubemap"))

    def lidar_scan(self, sample_id: str) -> Scan:
        raise DatasetFormatError(self.root, self.missing_reason("lidar"))

    def T_cam_lidar(self, sample_id: str) -> np.ndarray:
        raise DatasetFormatError(self.root, self.missing_reason("lidar"))

    def path_of(self, sample_id: str, modality: str, source: str) -> Path:
        """``rgb_images/<id>.png``, ``semantic_annotations/gtLabels/<id>.png`` or the calibration JSON (``calib``)."""
        if modality == "seg":
            return self.seg_dir / f"{sample_id}.png"
        if modality == "calib":
            return self.calib_dir / f"{sample_id}.json"
        return self.rgb_dir / f"{sample_id}.png"

    @classmethod  # asked of the class before a root is read (base.unserved_modality)
    def missing_reason(cls, content: str) -> str:
        if content in ("lidar", "depth", "lidar_visible", "lidar_beam", "lidar_scan"):
            return _NO_DEPTH
        if content == "cubemap":
            return "WoodScape has the recorded fisheye images only, no cube faces"
        return f"WoodScape has no {content}"

    # -------------------------------------------------------------------------------------------- helpers
    def _crop(self, width: int, height: int) -> tuple[int, int]:
        """``(first row, rows)`` served of a ``width x height`` image."""
        rows = width * 3 // 4
        if not self.crop_to_4x3 or (width * 3) % 4 or height <= rows:
            return 0, height
        return (height - rows) // 2, rows

    def _calibration_file(self, sample_id: str) -> tuple[Path, dict, np.ndarray]:
        """``(path, camera as the file has it, T_vehicle_cam)``; files with the same contents are parsed once."""
        path = self.path_of(sample_id, "calib", "fisheye")
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise DatasetFormatError(path, "missing: no calibration file for this image") from None
        if text not in self._camera_cache:
            try:
                record = read_calibration(path)
            except MissingFileError:  # removed since it was read
                raise DatasetFormatError(path, "missing: no calibration file for this image") from None
            self._camera_cache[text] = (record.camera, record.extrinsics.get("T_vehicle_cam", np.eye(4)))
        camera, pose = self._camera_cache[text]
        return path, camera, pose


def _read_list(path: Path) -> list[str]:
    """An OmniDet split list: one ``<id>_<CAM>.png`` a line (``#`` comments and blank lines skipped)."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise DatasetFormatError(path, "file does not exist") from None
    ids = []
    for number, line in enumerate(lines, 1):
        name = line.strip()
        if not name or name.startswith("#"):
            continue
        stem = name[:-4] if name.endswith(".png") else name
        if not _ID.match(stem):
            raise DatasetFormatError(
                path, f"expected <5 digits>_<FV|MVL|MVR|RV>.png, got {name!r}", f"line {number}"
            )
        ids.append(stem)
    return ids
