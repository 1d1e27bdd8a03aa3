"""AirSim360 / Omni360-X (``data.format=omni360``): drone flights rendered in Unreal Engine 5 as equirectangular
(ERP) panoramas with range depth, semantic and instance labels, read in place.

Read from github:Insta360-Research-Team/AirSim360 (``data/demo_sample/``: ``README.md``,
``PANORAMIC_DATA_FORMAT.md``, ``scripts/read_demo_ground_truth.py``, ``depth/check_depth.py``, ``instance/README.md``,
``instance/read_instance_labels_example.py``; the root ``README.md``). The files and their decoding are
:mod:`.omni360_files`, the class lists :mod:`.omni360_labels`. What this source serves (``docs/design.md``,
"AirSim360 / Omni360-X"):

- **Panoramas, not a fisheye.** ``spec.contents`` has ``equirect``: the datamodule remaps every panorama on the fly to
  the served lens (``data.source=equirect``) with :class:`~airfisheye_bench.geometry.equirect.EquirectToFisheye`.
  The recorded camera (``pano_rotation``, ``R_pano_cam0``) looks at the panorama's middle column on the horizon;
  ``data.gimbal`` turns it (docs/design.md, "Virtual gimbal"). The calibrated camera is the default lens:
  equidistant, 190 deg, as many pixels across as the panorama has rows.
- **Depth** is range already (the distance from the optical centre along the ray): served as stored, the far plane
  (1000 m, sky) and non-finite values as 0.
- **LiDAR** is cast from the depth panorama by a :class:`~airfisheye_bench.geometry.lidar.LidarSpec`
  (``data.lidar.preset``: :meth:`Omni360Source.cast_scan`; null: :data:`OWN_SENSOR`), its FLU axes the recorded
  camera's (x along its optical axis), at the camera's centre: each beam takes the range of the texel its direction falls in
  (:func:`~airfisheye_bench.geometry.equirect_lidar.lidar_from_equirect`; no interpolation across depth edges). A
  sensor at the camera's centre sees no parallax, so no point it returns is hidden from the camera:
  ``parallax_free`` tells the datamodule to project these scans without an occlusion correction, whatever
  ``data.occlusion`` says.
- **Classes** per scene's list, as the dataset's (``classes: dataset``) or the benchmark's 13 (``benchmark``).
- **Splits**: no official split. By frame blocks within each scene (:func:`~airfisheye_bench.io.splits.frame_blocks`,
  ``split_period``), or by whole scenes (``split_scenes``).

Example:
    >>> src = Omni360Source("/data/Omni360-Scene", scenes=["NYC"])  # doctest: +SKIP
    >>> sid = src.split("train")[0]; src.equirect(sid, "depth").shape  # doctest: +SKIP
    (1024, 2048)
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import ClassVar

import numpy as np

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.cameras.ideal import ideal_camera
from airfisheye_bench.geometry.equirect_lidar import lidar_from_equirect
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_presets import LIDAR_PRESETS
from airfisheye_bench.geometry.transforms import CAM_FROM_FLU, make_transform
from airfisheye_bench.io.benchmark_classes import BENCHMARK_CLASSES
from airfisheye_bench.io.calib_yaml import Calibration
from airfisheye_bench.io.dataset_spec import DatasetSpec, SplitsSpec
from airfisheye_bench.io.datasets.base import DatasetSource, legacy_lidar
from airfisheye_bench.io.datasets.omni360_files import (
    DEPTH_EXTS,
    LABEL_EXTS,
    Scene,
    depth_candidates,
    find_scenes,
    image_size,
    read_alpha,
    read_depth,
    read_instance,
    read_panorama,
)
from airfisheye_bench.io.datasets.omni360_labels import (
    IGNORE,
    ClassList,
    LabelTable,
    benchmark_table,
    check_benchmark_map,
    dataset_classes,
    dataset_table,
    read_class_list,
)
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.scan import Scan
from airfisheye_bench.io.splits import frame_blocks

__all__ = ["CLASS_SETS", "OWN_SENSOR", "SPLITS", "Omni360Source"]

log = logging.getLogger(__name__)

SPLITS = ("train", "val", "test")
CLASS_SETS = ("dataset", "benchmark")
#: The served fisheye's field of view (the project's default lens).
FOV_DEG = 190.0
#: The LiDAR preset cast when ``data.lidar.preset`` is null: the paper's sensor.
OWN_SENSOR = "paper"


class Omni360Source(DatasetSource):
    """An AirSim360 / Omni360-X root (``data.format=omni360``; its ``data.format_options`` are the keyword arguments).

    Args:
        root: A scene folder (``panorama/``, ``depth/``, ... or ``<prefix>_Raw/``, ``<prefix>_Depth/``, ...) or a
            folder of scene folders (Omni360-Scene's ``CityPark/``, ``DTW/``, ``NYC/``).
        scenes: The scene folders to use (``None``: every one found).
        classes: ``dataset`` (the scenes' own class names) or ``benchmark`` (mapped onto the benchmark's 13).
        benchmark_map: With ``benchmark``: ``{class name: benchmark class or None}``, added to and overriding
            :data:`~airfisheye_bench.io.datasets.omni360_labels.OMNI360_TO_BENCHMARK`.
        split_period: Frame blocks: each scene's frames (natural order of their names, after ``frame_stride``),
            the first ones ``train``, then ``len // split_period`` (at least one) ``val``, then as many ``test``.
        split_scenes: ``{train: [scenes], val: [...], test: [...]}``: split by whole scenes instead (scenes it does
            not name are not used; val and test may share scenes, train shares none).
        frame_stride: Use every n-th frame of a scene.
        lidar: Deprecated (``data.lidar.preset`` picks the LiDAR, :meth:`cast_scan`): for one more release, the
            preset (:data:`~airfisheye_bench.geometry.lidar_presets.LIDAR_PRESETS`) cast as the source's own sensor
            instead of :data:`OWN_SENSOR` (warned).

    Example:
        >>> Omni360Source.format, Omni360Source.OPTIONS["split_period"], Omni360Source.parallax_free
        ('omni360', 10, True)
    """

    format: ClassVar[str] = "omni360"
    OPTIONS: ClassVar[dict[str, object]] = {
        "scenes": None,
        "classes": "dataset",
        "benchmark_map": None,
        "split_period": 10,
        "split_scenes": None,
        "frame_stride": 1,
        "lidar": None,  # deprecated: data.lidar.preset (base.legacy_lidar)
    }
    #: The LiDAR is cast at the camera's centre: nothing it returns is hidden from the camera (module docstring).
    parallax_free: ClassVar[bool] = True

    def __init__(
        self,
        root: str | Path,
        scenes: list[str] | None = None,
        classes: str = "dataset",
        benchmark_map: Mapping[str, str | None] | None = None,
        split_period: int = 10,
        split_scenes: Mapping[str, list[str]] | None = None,
        frame_stride: int = 1,
        lidar: str | None = None,
    ) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise DatasetFormatError(self.root, "not a folder (an Omni360 scene, or a folder of scenes)")
        if classes not in CLASS_SETS:
            raise ConfigError(
                f"data.format_options.classes={classes!r}: expected one of {', '.join(CLASS_SETS)}"
            )
        if benchmark_map is not None and classes != "benchmark":
            raise ConfigError(
                "data.format_options.benchmark_map maps names onto the benchmark's classes: set classes=benchmark"
            )
        for key, value, least in (("split_period", split_period, 3), ("frame_stride", frame_stride, 1)):
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ConfigError(f"data.format_options.{key}={value!r}: expected an integer >= {least}")
        if lidar is not None and lidar not in LIDAR_PRESETS:
            raise ConfigError(f"data.format_options.lidar={lidar!r}: expected one of {sorted(LIDAR_PRESETS)}")
        self.classes = classes
        self.split_period, self.frame_stride = int(split_period), int(frame_stride)
        self.lidar_preset = legacy_lidar(lidar) or OWN_SENSOR
        #: ``R_pano_cam0``: the recorded camera's directions -> the panorama's frame. A panorama records no camera:
        #: it looks at the middle column on the horizon (data.gimbal turns the served one from there).
        self.pano_rotation = np.eye(3)
        self._scenes = self._select(find_scenes(self.root), scenes)
        self._split_scenes = self._check_split_scenes(split_scenes)
        self._frames = {s.name: list(s.frames)[:: self.frame_stride] for s in self._scenes.values()}
        self._cache: dict[tuple[str, str], object] = {}
        first = next(iter(self._scenes.values()))
        width, height = image_size(next(iter(first.frames.values())))
        self.erp_size = (height, width)
        self.modalities = tuple(m for m in ("rgb", "seg", "depth") if self._lacking(m) is None)
        lists = self._class_lists() if "seg" in self.modalities else {}
        self._benchmark_map = check_benchmark_map(benchmark_map, list(lists.values()))
        self.spec = self._build_spec(lists)

    # ------------------------------------------------------------------------------------------- discovery
    @staticmethod
    def _select(found: list[Scene], names: list[str] | None) -> dict[str, Scene]:
        by_name = {s.name: s for s in found}
        if names is None:
            return by_name
        if isinstance(names, str) or not names:
            raise ConfigError(f"data.format_options.scenes={names!r}: expected a list of scene folder names")
        missing = [n for n in names if n not in by_name]
        if missing:
            raise ConfigError(
                f"data.format_options.scenes: no scene {missing} under {found[0].folder.parent} "
                f"(it has {sorted(by_name)})"
            )
        return {n: by_name[n] for n in sorted(set(names))}

    def _check_split_scenes(self, split_scenes: Mapping | None) -> dict[str, list[str]] | None:
        if split_scenes is None:
            return None
        key = "data.format_options.split_scenes"
        if not isinstance(split_scenes, Mapping) or set(split_scenes) - set(SPLITS):
            raise ConfigError(
                f"{key}={split_scenes!r}: expected {{train: [scenes], val: [...], test: [...]}}"
            )
        out: dict[str, list[str]] = {}
        seen: dict[str, str] = {}
        for split in SPLITS:
            names = split_scenes.get(split) or []
            if isinstance(names, str):
                names = [names]
            for name in names:
                if name not in self._scenes:
                    raise ConfigError(
                        f"{key}.{split}: no scene {name!r} (the scenes are {sorted(self._scenes)})"
                    )
                if "train" in (seen.get(name), split) and seen.get(name, split) != split:
                    # val and test may be one held-out scene; training on it would score seen frames
                    raise ConfigError(
                        f"{key}: scene {name!r} is in {seen[name]} and {split}; train on other scenes"
                    )
                seen.setdefault(name, split)
            out[split] = [str(n) for n in names]
        return out

    def _lacking(self, modality: str) -> str | None:
        """Why ``modality`` cannot be served (the first scene that lacks it), or ``None``."""
        for scene in self._scenes.values():
            if modality == "depth" and scene.depth is None:
                return f"{scene.folder}: no depth folder (depth/ or <prefix>_Depth/)"
            if modality == "seg" and scene.semantic is None and scene.instance is None:
                return (
                    f"{scene.folder}: no label folder (semantic/ or <prefix>_seg_panorama/, or instance/ or "
                    "<prefix>_instance_panorama/)"
                )
            if modality == "seg" and scene.class_list is None:
                return (
                    f"{scene.folder}: no class list (semantic_lists_<env>.txt or <prefix>_semantic_list) for the "
                    "label ids"
                )
        return None

    def _class_lists(self) -> dict[str, ClassList]:
        return {name: read_class_list(scene.class_list) for name, scene in self._scenes.items()}

    def _build_spec(self, lists: dict[str, ClassList]) -> DatasetSpec:
        if self.classes == "dataset" and lists:
            classes = dataset_classes(list(lists.values()))
            self._tables = {name: dataset_table(cl, classes) for name, cl in lists.items()}
        else:  # the benchmark's (also the placeholder when there are no labels: seg is then refused first)
            classes = BENCHMARK_CLASSES
            self._tables = {name: benchmark_table(cl, self._benchmark_map) for name, cl in lists.items()}
        return DatasetSpec(
            name=f"omni360-{self.classes}",
            raw_classes=classes,  # the source maps each scene's ids to these itself
            train_classes=classes,
            raw_to_train={c.id: c.id for c in classes},
            ignore_index=IGNORE,
            splits=SplitsSpec(
                files={s: s for s in SPLITS}, by="scene" if self._split_scenes is not None else "frame_blocks"
            ),
            sensors={"equirect": {"height": self.erp_size[0], "width": self.erp_size[1]}},
            contents=("equirect", "lidar") if "depth" in self.modalities else ("equirect",),
            description="AirSim360 / Omni360-X (github:Insta360-Research-Team/AirSim360), read in place",
        )

    # ----------------------------------------------------------------------------------------------- splits
    @property
    def split_names(self) -> list[str]:
        return list(SPLITS)

    def scenes(self) -> list[str]:
        """The selected scene names, sorted."""
        return list(self._scenes)

    def split(self, name: str) -> list[str]:
        """Sample ids ``<scene>/<stem>`` of split ``name`` (module docstring), scenes sorted, frames in order."""
        if name not in SPLITS:
            raise ValueError(f"split must be one of {list(SPLITS)}, got {name!r}")
        if self._split_scenes is not None:
            return [f"{s}/{f}" for s in sorted(self._split_scenes[name]) for f in self._frames[s]]
        return [
            f"{s}/{f}" for s in self._scenes for f in frame_blocks(self._frames[s], self.split_period)[name]
        ]

    def split_rule(self, name: str) -> str:
        if self._split_scenes is not None:
            return f"the frames of the scenes data.format_options.split_scenes.{name} lists"
        return (
            f"the {name} block of each scene's frames (split by frame blocks, data.format_options.split_period="
            f"{self.split_period}): only a scene of at least 3 frames (after frame_stride={self.frame_stride}) "
            "has val and test blocks"
        )

    # ------------------------------------------------------------------------------------------ calibration
    def calib(self, sample_id: str) -> Calibration:
        """The default lens (equidistant, 190 deg, ``H x H`` for an ``H``-row panorama) at the panorama's centre;
        body = the panorama's FLU axes (its middle column ahead, its top up), the LiDAR on the recorded camera's
        axes."""
        self._scene(sample_id)
        height = self.erp_size[0]
        camera = ideal_camera(height, height, fov_deg=FOV_DEG, model="equidistant")
        R_body_cam = CAM_FROM_FLU.T @ self.pano_rotation
        return Calibration(
            camera.to_dict(),
            None,
            make_transform(R_body_cam, np.zeros(3)),
            make_transform(R_body_cam @ CAM_FROM_FLU, np.zeros(3)),
            self.lidar_spec().to_dict(),
        )

    def lidar_spec(self) -> LidarSpec:
        """The LiDAR cast by :meth:`lidar_scan`: :data:`OWN_SENSOR` (or the deprecated ``format_options.lidar``)."""
        return LidarSpec.from_preset(self.lidar_preset)

    def T_cam_lidar(self, sample_id: str) -> np.ndarray:
        """LiDAR (FLU) -> camera: a pure rotation; both see from the panorama's centre at one rendered instant."""
        return make_transform(CAM_FROM_FLU, np.zeros(3))

    # ----------------------------------------------------------------------------------------------- images
    def equirect(self, sample_id: str, modality: str) -> np.ndarray:
        """A frame's panorama ``[H, W(, 3)]``: rgb uint8, seg uint8 training ids (255 ignored), depth float32 range."""
        path = self.path_of(sample_id, modality, "equirect")
        if modality == "rgb":
            image = read_panorama(path)
        elif modality == "seg":
            image = self._labels(sample_id, path)
        elif modality == "depth":
            if not path.is_file():
                scene, stem = self._scene(sample_id), self._stem(sample_id)
                raise DatasetFormatError(
                    path.parent,
                    f"no depth file for {scene.frames[stem].name} (looked for {', '.join(depth_candidates(stem))})",
                )
            image = read_depth(path)
        else:
            raise ValueError(f"modality must be rgb, seg or depth, got {modality!r}")
        if image.shape[:2] != self.erp_size:
            raise DatasetFormatError(
                path,
                f"{modality} is {image.shape[1]}x{image.shape[0]}, the panoramas are "
                f"{self.erp_size[1]}x{self.erp_size[0]} (the first panorama's size)",
            )
        return image

    def instance(self, sample_id: str) -> np.ndarray:
        """``int64 [H, W]`` object ids ``A << 24 | R << 16 | G << 8 | B`` of the frame's instance PNG (0: none)."""
        scene, stem = self._scene(sample_id), self._stem(sample_id)
        if scene.instance is None:
            raise DatasetFormatError(
                scene.folder, "no instance folder (instance/ or <prefix>_instance_panorama/)"
            )
        return read_instance(self._label_file(scene, scene.instance, stem))

    def _labels(self, sample_id: str, path: Path) -> np.ndarray:
        alpha = read_alpha(path)
        table: LabelTable = self._tables[self._scene(sample_id).name]
        unknown = np.unique(alpha[~table.known[alpha]])
        if unknown.size:
            raise DatasetFormatError(
                path, f"class ids {unknown.tolist()} in the alpha channel are not in {table.path.name}"
            )
        return table.lut[alpha]

    def fisheye(self, sample_id: str, modality: str) -> np.ndarray:
        folder = self._scene(sample_id).folder
        raise DatasetFormatError(folder, f"{self.missing_reason('fisheye')}; use data.source=equirect")

    def cubemap(self, sample_id: str, modality: str) -> np.ndarray:
        folder = self._scene(sample_id).folder
        raise DatasetFormatError(folder, f"{self.missing_reason('cubemap')}; use data.source=equirect")

    # ------------------------------------------------------------------------------------------------ files
    def path_of(self, sample_id: str, modality: str, source: str) -> Path:
        scene, stem = self._scene(sample_id), self._stem(sample_id)
        if modality == "rgb":
            return scene.frames[stem]
        if modality == "seg":
            folder = scene.semantic if scene.semantic is not None else scene.instance
            if folder is None:
                return scene.folder / "semantic" / f"{stem}.png"
            return self._label_file(scene, folder, stem)
        if modality == "depth":
            if scene.depth is None:
                return scene.folder / "depth" / f"{stem}{DEPTH_EXTS[0]}"
            names = self._listing(scene, scene.depth)
            found = next((n for n in depth_candidates(stem) if n in names), None)
            return scene.depth / (found or depth_candidates(stem)[0])
        raise ValueError(f"modality must be rgb, seg or depth, got {modality!r}")

    def _label_file(self, scene: Scene, folder: Path, stem: str) -> Path:
        names = self._listing(scene, folder)
        return folder / next((stem + e for e in LABEL_EXTS if stem + e in names), stem + LABEL_EXTS[0])

    def _listing(self, scene: Scene, folder: Path) -> dict[str, Path]:
        return self._cached("listing", str(folder), lambda: scene.file_names(folder))

    def missing_reason(self, content: str) -> str:
        if content in ("fisheye", "cubemap"):
            return (
                f"{self.root}: Omni360 frames are equirectangular panoramas (no {content}), remapped on the fly to the "
                "served lens"
            )
        lacking = self._lacking("depth" if content == "lidar" else content)
        if lacking is not None:
            return f"{lacking} (the LiDAR is cast from it)" if content == "lidar" else lacking
        return f"{self.root}: the Omni360 reader serves no {content}"

    # ------------------------------------------------------------------------------------------------ LiDAR
    def lidar_scan(self, sample_id: str) -> Scan:
        """The scan of :meth:`lidar_spec`'s sensor cast into the frame's depth panorama (:meth:`cast_scan`)."""
        return self.cast_scan(sample_id, self.lidar_spec())

    def cast_scan(self, sample_id: str, spec: LidarSpec) -> Scan:
        """A scan of ``spec`` (``data.lidar.preset``) cast into the frame's depth panorama from its centre, in the
        LiDAR's FLU frame, its rings known; beams without depth (sky) or beyond ``spec.max_range`` return nothing
        (counted)."""
        depth = self.equirect(sample_id, "depth")
        R_pano_lidar = self.pano_rotation @ CAM_FROM_FLU
        points, rings = lidar_from_equirect(depth, spec, R_pano_lidar)
        beams = spec.channels * spec.points_per_channel
        path = self.path_of(sample_id, "depth", "equirect")
        return Scan(points, None, rings, False, beams - len(points), path, "omni360_depth")

    # ---------------------------------------------------------------------------------------------- helpers
    def _scene(self, sample_id: str) -> Scene:
        name, _, stem = sample_id.partition("/")
        scene = self._scenes.get(name)
        if scene is None or stem not in scene.frames:
            raise ValueError(f"sample id {sample_id!r} is not <scene>/<stem> of {self.root}")
        return scene

    @staticmethod
    def _stem(sample_id: str) -> str:
        return sample_id.partition("/")[2]

    def _cached(self, kind: str, key: str, load):
        if (kind, key) not in self._cache:
            self._cache[(kind, key)] = load()
        return self._cache[(kind, key)]
