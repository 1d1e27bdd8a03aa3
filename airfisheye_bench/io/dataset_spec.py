"""``dataset.yaml``: the description of a dataset release that every reader goes through.

The file names the dataset, its raw categories and training classes (with colours), the raw -> training mapping,
the sensors, the file encodings, the path layout, which modalities the release contains, how the splits were made
and (for generated data) the generator settings. A different release is read by writing a different
``dataset.yaml``, not by changing code. :meth:`DatasetSpec.load` validates the file and every error names the
file and the offending key.

A minimal file::

    format_version: 1
    name: my-release
    classes:
      ignore_index: 255
      raw:   [{id: 0, name: sky, color: [70, 130, 180]}, {id: 1, name: road, color: [128, 64, 128]}]
      train: [{id: 0, name: sky, color: [70, 130, 180]}, {id: 1, name: ground, color: [128, 64, 128]}]
      raw_to_train: {0: 0, 1: 1}
    sensors: {cubemap: {face_size: 1024}}
    files: {rgb: png, seg: png, depth: png16, depth_scale: 256.0}
    contents: [cubemap, fisheye, lidar]
    splits: {by: location, files: {train: splits/train.txt, val: splits/val.txt, test: splits/test.txt}}
"""

from __future__ import annotations

import string
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from airfisheye_bench.geometry.cubemap import FACE_NAMES
from airfisheye_bench.geometry.gimbal import Gimbal
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.yamlio import FieldReader, check_int, read_yaml, write_yaml

FORMAT_VERSION = 1
DATASET_YAML = "dataset.yaml"

#: Modalities a release may contain (``contents`` key). ``equirect``: equirectangular panoramas (a public dataset's,
#: ``data.format=omni360``; ``sensors.equirect`` gives their ``height`` and ``width``).
KNOWN_CONTENTS = (
    "cubemap",
    "fisheye",
    "equirect",
    "lidar",
    "lidar_visible",
    "lidar_beam",
    "lidar_scan",
    "poses",
    "imu",
)
#: The stored images a loader can serve from: the raw cube faces or equirectangular panoramas (remapped on the fly), or
#: pre-rendered fisheye.
IMAGE_SOURCES = ("cubemap", "fisheye", "equirect")
#: The image sources remapped on the fly to any lens.
REMAP_SOURCES = ("cubemap", "equirect")
#: Where the cube faces become the fisheye image (``data.remap_on``): in the loader's worker processes, or on the
#: model's device after the batch is transferred (the workers then only decode the faces and project the LiDAR).
REMAP_SITES = ("worker", "device")
RGB_ENCODINGS = ("png", "jpg")
SEG_ENCODINGS = ("png",)
DEPTH_ENCODINGS = ("png16", "npy", "pfm")

#: Path templates relative to the root. Placeholders: ``{env} {traj} {frame} {face} {modality} {ext}``.
DEFAULT_LAYOUT: dict[str, str] = {
    "calib": "{env}/{traj}/calib.yaml",
    "poses": "{env}/{traj}/poses.csv",
    "imu": "{env}/{traj}/imu.csv",
    "cubemap": "{env}/{traj}/cubemap/{face}/{modality}/{frame}.{ext}",
    "fisheye": "{env}/{traj}/fisheye/{modality}/{frame}.{ext}",
    "lidar": "{env}/{traj}/lidar/{frame}.npy",
    "lidar_visible": "{env}/{traj}/lidar_visible/{frame}.npy",
    "lidar_beam": "{env}/{traj}/lidar_beam/{frame}.npy",
    "lidar_scan": "{env}/{traj}/lidar_scan.csv",
}
#: Templates written to ``dataset.yaml`` only when the release contains them (they came after format 1 shipped,
#: and releases without them keep their bytes): the synthetic generator's record of a realistic scan,
#: ``lidar_beam`` (int32 [N] per frame: ``channel * N_PC + column`` of the beam that measured each point, its true
#: cell of ``I_LiDAR``) and ``lidar_scan`` (``frame,phase_rad`` per trajectory: the scan's azimuth phase).
OPTIONAL_TEMPLATES = ("lidar_beam", "lidar_scan")
_LAYOUT_FIELDS = {
    "calib": {"env", "traj"},
    "poses": {"env", "traj"},
    "imu": {"env", "traj"},
    "cubemap": {"env", "traj", "frame", "face", "modality", "ext"},
    "fisheye": {"env", "traj", "frame", "modality", "ext"},
    "lidar": {"env", "traj", "frame"},
    "lidar_visible": {"env", "traj", "frame"},
    "lidar_beam": {"env", "traj", "frame"},
    "lidar_scan": {"env", "traj"},
}


@dataclass(frozen=True)
class ClassDef:
    """One semantic class: integer id, name and RGB display colour."""

    id: int
    name: str
    color: tuple[int, int, int]

    def to_dict(self) -> dict:
        return {"id": int(self.id), "name": self.name, "color": [int(c) for c in self.color]}


@dataclass(frozen=True)
class FileEncodings:
    """How the per-frame files are encoded.

    Attributes:
        rgb: ``png`` or ``jpg``.
        seg: ``png`` (8-bit raw ids; 255 = ignore / outside the image circle).
        depth: ``png16`` (``round(range * depth_scale)``, 0 = invalid, saturating at 65535), ``npy`` or ``pfm``.
        depth_scale: Scale of ``png16`` depth.
    """

    rgb: str = "png"
    seg: str = "png"
    depth: str = "png16"
    depth_scale: float = 256.0

    def extension(self, modality: str) -> str:
        """File extension (no dot) of ``rgb``, ``seg`` or ``depth`` files."""
        if modality == "rgb":
            return self.rgb
        if modality == "seg":
            return "png"
        if modality == "depth":
            return "png" if self.depth == "png16" else self.depth
        raise ValueError(f"modality must be 'rgb', 'seg' or 'depth', got {modality!r}")

    def to_dict(self) -> dict:
        return {
            "rgb": self.rgb,
            "seg": self.seg,
            "depth": self.depth,
            "depth_scale": float(self.depth_scale),
            "lidar": "npy float32 [N, 4]: x, y, z (LiDAR frame, metres), raw semantic id",
            "lidar_visible": "npy bool [N], aligned with lidar/<frame>.npy",
        }


@dataclass(frozen=True)
class SplitsSpec:
    """How the samples are split.

    Attributes:
        files: Split name -> list file relative to the root (one ``<env>/<traj>/<frame>`` per line).
        by: What the split is based on (``location``: whole trajectories / areas go to one split).
        ratios: Target fraction of frames per split (informational).
        locations: ``<env>/<traj>`` -> split name (informational; the list files are authoritative).
    """

    files: dict[str, str]
    by: str = "location"
    ratios: dict[str, float] = field(default_factory=dict)
    locations: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict:
        out: dict[str, Any] = {"by": self.by, "files": dict(self.files)}
        if self.ratios:
            out["ratios"] = {k: float(v) for k, v in self.ratios.items()}
        if self.locations:
            out["locations"] = dict(self.locations)
        return out


@dataclass(frozen=True)
class DatasetSpec:
    """Parsed and validated ``dataset.yaml``.

    Attributes:
        name: Release name.
        raw_classes: The raw categories stored in label files and LiDAR ids.
        train_classes: Training classes with ids ``0..K-1``.
        raw_to_train: Raw id -> training id; raw ids absent from the mapping become ``ignore_index``.
        ignore_index: Label ignored by losses and metrics (255).
        sensors: Free-form sensor description; ``sensors.cubemap.face_size`` is required when the release has
            cube faces, ``sensors.visibility`` documents what ``lidar_visible`` means.
        files: File encodings.
        layout: Path templates (defaults: :data:`DEFAULT_LAYOUT`).
        contents: Modalities present (subset of :data:`KNOWN_CONTENTS`).
        splits: Split definition.
        description: Free text.
        generator: Settings of the generator that wrote a synthetic release (``None`` for real data).
        format_version: Version of this schema.

    Example:
        >>> spec = DatasetSpec(
        ...     name="toy",
        ...     raw_classes=(ClassDef(0, "sky", (70, 130, 180)), ClassDef(1, "road", (128, 64, 128))),
        ...     train_classes=(ClassDef(0, "sky", (70, 130, 180)),),
        ...     raw_to_train={0: 0},
        ...     splits=SplitsSpec(files={"train": "splits/train.txt"}),
        ... )
        >>> spec.label_lut()[:3].tolist()
        [0, 255, 255]
    """

    name: str
    raw_classes: tuple[ClassDef, ...]
    train_classes: tuple[ClassDef, ...]
    raw_to_train: dict[int, int]
    splits: SplitsSpec
    ignore_index: int = 255
    sensors: dict = field(default_factory=dict)
    files: FileEncodings = field(default_factory=FileEncodings)
    layout: dict[str, str] = field(default_factory=lambda: dict(DEFAULT_LAYOUT))
    contents: tuple[str, ...] = ("fisheye",)
    description: str = ""
    generator: dict | None = None
    format_version: int = FORMAT_VERSION

    def __post_init__(self) -> None:
        # Validate programmatic construction with the same rules as loading.
        DatasetSpec.from_dict(self.to_dict(), path="<DatasetSpec>")

    # -------------------------------------------------------------------------------------- helpers
    @property
    def num_train_classes(self) -> int:
        return len(self.train_classes)

    @property
    def train_class_names(self) -> list[str]:
        return [c.name for c in self.train_classes]

    @property
    def face_size(self) -> int | None:
        """Cube-face size in pixels, if the release has cube faces."""
        cube = self.sensors.get("cubemap", {})
        return int(cube["face_size"]) if "face_size" in cube else None

    @property
    def equirect_size(self) -> tuple[int, int] | None:
        """``(height, width)`` of the release's equirectangular panoramas, if it has them."""
        pano = self.sensors.get("equirect", {})
        return (int(pano["height"]), int(pano["width"])) if "height" in pano else None

    def has(self, modality: str) -> bool:
        """Whether the release contains ``modality`` (see :data:`KNOWN_CONTENTS`)."""
        return modality in self.contents

    def label_lut(self) -> np.ndarray:
        """``uint8 [256]`` lookup table raw id -> training id (``ignore_index`` where unmapped).

        Apply it with ``lut[raw_label]``; 255 (outside the image circle) stays 255.
        """
        lut = np.full(256, self.ignore_index, dtype=np.uint8)
        for raw, train in self.raw_to_train.items():
            lut[raw] = train
        return lut

    def unknown_label_ids(self, labels: np.ndarray) -> list[int]:
        """Raw ids in ``labels`` (uint8) that are not raw classes; ``ignore_index`` (outside the circle) is allowed."""
        known = np.zeros(256, dtype=bool)
        known[[c.id for c in self.raw_classes]] = True
        known[self.ignore_index] = True
        return np.unique(labels[~known[labels]]).tolist()

    def train_palette(self) -> np.ndarray:
        """``uint8 [256, 3]`` colours indexed by training id (black for unused ids)."""
        pal = np.zeros((256, 3), np.uint8)
        for c in self.train_classes:
            pal[c.id] = c.color
        return pal

    def raw_palette(self) -> np.ndarray:
        """``uint8 [256, 3]`` colours indexed by raw id (black for unused ids)."""
        pal = np.zeros((256, 3), np.uint8)
        for c in self.raw_classes:
            pal[c.id] = c.color
        return pal

    def with_updates(self, **changes: Any) -> DatasetSpec:
        """A copy with fields replaced (validated)."""
        return replace(self, **changes)

    # ------------------------------------------------------------------------------------------ I/O
    def to_dict(self) -> dict:
        out: dict[str, Any] = {
            "format_version": self.format_version,
            "name": self.name,
            "description": self.description,
            "classes": {
                "ignore_index": int(self.ignore_index),
                "raw": [c.to_dict() for c in self.raw_classes],
                "train": [c.to_dict() for c in self.train_classes],
                "raw_to_train": {int(k): int(v) for k, v in sorted(self.raw_to_train.items())},
            },
            "sensors": self.sensors,
            "files": self.files.to_dict(),
            "layout": {
                k: v for k, v in self.layout.items() if k not in OPTIONAL_TEMPLATES or k in self.contents
            },
            "contents": list(self.contents),
            "splits": self.splits.to_dict(),
        }
        if self.generator is not None:
            out["generator"] = self.generator
        return out

    def save(self, path: str | Path) -> None:
        """Atomically write ``dataset.yaml`` (``path`` may be the file or the dataset root)."""
        path = Path(path)
        if path.is_dir():
            path = path / DATASET_YAML
        # The module's first name (io/spec.py): the header is in every written dataset.yaml and so in the checksums
        # of its manifest.json; it stays as the datasets were written.
        header = (
            f"AirFisheye dataset description ({self.name}). Schema: airfisheye_bench.io.spec.DatasetSpec."
        )
        write_yaml(path, self.to_dict(), header=header)

    @classmethod
    def load(cls, path: str | Path) -> DatasetSpec:
        """Read and validate ``dataset.yaml`` (``path`` may be the file or the dataset root)."""
        path = Path(path)
        if path.is_dir():
            path = path / DATASET_YAML
        return cls.from_dict(read_yaml(path), path=path)

    @classmethod
    def from_dict(cls, data: dict, path: str | Path = DATASET_YAML) -> DatasetSpec:
        """Validate a parsed ``dataset.yaml`` mapping; errors name ``path`` and the key."""
        r = FieldReader(path, data)
        version = r.int("format_version", minimum=1)
        if version > FORMAT_VERSION:
            raise r.error(
                "format_version", f"is {version}, newer than this library supports ({FORMAT_VERSION})"
            )
        ignore = r.int("classes.ignore_index", default=255, minimum=0, maximum=255)
        raw = _parse_classes(r, "classes.raw")
        train = _parse_classes(r, "classes.train")
        if [c.id for c in train] != list(range(len(train))):
            raise r.error(
                "classes.train", f"ids must be 0..{len(train) - 1} in order, got {[c.id for c in train]}"
            )
        if any(c.id == ignore for c in raw):
            raise r.error("classes.raw", f"id {ignore} is reserved for ignore_index")
        raw_ids = {c.id for c in raw}
        mapping: dict[int, int] = {}
        for k, v in r.mapping("classes.raw_to_train").items():
            key = f"classes.raw_to_train.{k}"
            try:
                raw_id = int(k)
            except (TypeError, ValueError):
                raise r.error(key, "keys must be raw class ids") from None
            if raw_id not in raw_ids:
                raise r.error(key, f"raw id {raw_id} is not one of classes.raw")
            train_id = check_int(r, key, v, minimum=0, maximum=255)
            if train_id != ignore and train_id >= len(train):
                raise r.error(key, f"maps to {train_id}, which is neither a training id nor ignore_index")
            mapping[raw_id] = train_id

        sensors = r.mapping("sensors", default={})
        if "cubemap" in sensors:
            r.int("sensors.cubemap.face_size", minimum=1)
            faces = r.get("sensors.cubemap.faces", default=list(FACE_NAMES))
            if list(faces) != list(FACE_NAMES):
                raise r.error(
                    "sensors.cubemap.faces", f"must be {list(FACE_NAMES)} (stacking order), got {faces}"
                )

        files = FileEncodings(
            rgb=r.str("files.rgb", default="png", choices=RGB_ENCODINGS),
            seg=r.str("files.seg", default="png", choices=SEG_ENCODINGS),
            depth=r.str("files.depth", default="png16", choices=DEPTH_ENCODINGS),
            depth_scale=r.float("files.depth_scale", default=256.0, positive=True),
        )

        layout = dict(DEFAULT_LAYOUT)
        for name, template in r.mapping("layout", default={}).items():
            key = f"layout.{name}"
            if name not in DEFAULT_LAYOUT:
                raise r.error(key, f"unknown path template; expected one of {sorted(DEFAULT_LAYOUT)}")
            if not isinstance(template, str) or template.startswith("/") or ".." in Path(template).parts:
                raise r.error(key, f"must be a relative path template, got {template!r}")
            try:
                fields = {f for _, f, _, _ in string.Formatter().parse(template) if f}
            except ValueError as exc:
                raise r.error(key, f"invalid template ({exc})") from None
            if not fields <= _LAYOUT_FIELDS[name] or not {"env", "traj"} <= fields:
                raise r.error(
                    key, f"placeholders must be among {sorted(_LAYOUT_FIELDS[name])}, got {sorted(fields)}"
                )
            layout[name] = template

        contents = r.seq("contents", default=["fisheye"])
        for i, item in enumerate(contents):
            if item not in KNOWN_CONTENTS:
                raise r.error(f"contents[{i}]", f"must be one of {list(KNOWN_CONTENTS)}, got {item!r}")
        if "cubemap" in contents and "cubemap" not in sensors:
            raise r.error("sensors.cubemap", "is required when contents lists 'cubemap'")
        if "equirect" in contents:
            for side in ("height", "width"):
                r.int(f"sensors.equirect.{side}", minimum=2)

        split_files = r.mapping("splits.files")
        if not split_files:
            raise r.error("splits.files", "must name at least one split")
        for name, rel in split_files.items():
            if not isinstance(rel, str) or rel.startswith("/") or ".." in Path(rel).parts:
                raise r.error(f"splits.files.{name}", f"must be a relative path, got {rel!r}")
        ratios = {str(k): r.float(f"splits.ratios.{k}") for k in r.mapping("splits.ratios", default={})}
        locations = r.mapping("splits.locations", default={})
        for loc, split in locations.items():
            if split not in split_files:
                raise r.error(
                    f"splits.locations.{loc}", f"names split {split!r}, not one of {sorted(split_files)}"
                )
        generator = r.get("generator", default=None)
        if generator is not None and not isinstance(generator, dict):
            raise r.error("generator", "must be a mapping")

        spec = object.__new__(cls)  # bypass __post_init__ (this *is* the validation)
        values = dict(
            name=r.str("name"),
            raw_classes=raw,
            train_classes=train,
            raw_to_train=mapping,
            splits=SplitsSpec(
                files={str(k): str(v) for k, v in split_files.items()},
                by=r.str("splits.by", default="location"),
                ratios=ratios,
                locations={str(k): str(v) for k, v in locations.items()},
            ),
            ignore_index=ignore,
            sensors=sensors,
            files=files,
            layout=layout,
            contents=tuple(contents),
            description=str(r.get("description", default="") or ""),
            generator=generator,
            format_version=version,
        )
        for k, v in values.items():
            object.__setattr__(spec, k, v)
        return spec


def _parse_classes(r: FieldReader, key: str) -> tuple[ClassDef, ...]:
    items = r.seq(key)
    if not items:
        raise r.error(key, "must list at least one class")
    out: list[ClassDef] = []
    for i, item in enumerate(items):
        k = f"{key}[{i}]"
        if not isinstance(item, dict):
            raise r.error(k, "must be a mapping with id, name, color")
        sub = FieldReader(r.path, item)
        try:
            cid = sub.int("id", minimum=0, maximum=255)
            name = sub.str("name")
            color = sub.get("color")
        except DatasetFormatError as exc:
            raise r.error(f"{k}.{exc.key}", exc.message) from None
        if (
            not isinstance(color, list | tuple)
            or len(color) != 3
            or not all(isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 255 for c in color)
        ):
            raise r.error(f"{k}.color", f"must be 3 integers in [0, 255], got {color!r}")
        out.append(ClassDef(cid, name, (color[0], color[1], color[2])))
    ids = [c.id for c in out]
    names = [c.name for c in out]
    if len(set(ids)) != len(ids):
        raise r.error(key, f"ids must be unique, got {ids}")
    if len(set(names)) != len(names):
        raise r.error(key, f"names must be unique, got {names}")
    return tuple(out)


def classes_from(objs) -> tuple[ClassDef, ...]:
    """Convert any objects with ``id``, ``name``, ``color`` attributes (e.g. ``synth.classes.ClassInfo``)."""
    return tuple(ClassDef(int(o.id), str(o.name), tuple(int(c) for c in o.color)) for o in objs)


def remap_site_problem(remap_on: Any, source: Any, sources: Any = None, gimbal: Any = None) -> str | None:
    """Why ``data.remap_on`` cannot be served with ``data.source`` / ``data.sources`` / ``data.gimbal``, or ``None``.

    The device remaps a batch with one lookup table: a gimbal whose views vary from sample to sample (one table per
    view) is refused; one fixed view per split is served (a ``data.gimbal`` the gimbal's own check refuses is left
    to it).

    Example:
        >>> remap_site_problem("device", "cubemap") is None
        True
        >>> remap_site_problem("device", "fisheye")
        'data.source=fisheye has no cube faces to remap; use data.remap_on=worker or data.source=cubemap'
    """
    if remap_on not in REMAP_SITES:
        return f"expected one of {', '.join(REMAP_SITES)}"
    if remap_on == "worker":
        return None
    if source == "fisheye":
        return (
            "data.source=fisheye has no cube faces to remap; use data.remap_on=worker or data.source=cubemap"
        )
    if source != "cubemap":
        return f"data.source={source}: the device remaps cube faces only; use data.remap_on=worker"
    if sources:
        return "data.sources mixes datasets with their own lenses and face sizes; use data.remap_on=worker"
    try:
        parsed = Gimbal.parse(gimbal)
    except ValueError:
        return None
    if parsed is not None and any(parsed.for_split(training).fixed is None for training in (True, False)):
        return (
            "data.gimbal turns the samples of a split to views of their own, each with its own lookup table, and the "
            "device remaps a batch with one; use data.remap_on=worker, or one fixed view (data.gimbal=[yaw,pitch])"
        )
    return None
