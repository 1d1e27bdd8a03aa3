"""TartanAir V2 (``data.format=tartanair``) read in place, in the layout its toolkit documents.

Data CC BY 4.0, toolkit MIT. Read from github:castacks/tartanairpy at commit
e8535a8b68687d8f58365bfd06afd334b53f3997 (``docs/modalities.rst``, ``docs/index.rst``, ``tartanair/reader.py``,
``tartanair/customizer.py``, ``tartanair/iterator.py``, ``tartanair/visualizer.py``, ``segfiles.zip``) and its
submodules github:castacks/image_sampler 620f75b06b83a43a426e01fa7922fb14a4ccd584 (``six_images_numba.py``
``sample_coor``, ``six_images_common.py``, ``planar_as_base.py``), github:castacks/mvs_utils
ce2786af22b1dbe3796ada3b96a712b87e70d99f (``simulated_lidar_pre_def_models.py``, ``point_cloud_helper.py``) and
github:Amigoshan/data_cacher eb79b6df08be0bea7aee7fedeff67642753e8b24 (``modality_type/tartanair_types.py``,
``modality_type/ply_io.py``, ``o3d_camera.npz``)::

    <root>/<env>/seg_label_map.json                      {"name_map": {label name: seg PNG value}}
    <root>/<env>/Data_easy|Data_hard/P000/
        image_lcam_<face>/000000_lcam_<face>.png         RGB, 640x640, 90 deg pinhole (f = 320, centre 320)
        depth_lcam_<face>/000000_lcam_<face>_depth.png   float32 planar depth packed into the 4 bytes of RGBA
        seg_lcam_<face>/000000_lcam_<face>_seg.png       uint8 label values of the environment's name_map
        lidar/000000_lcam_front_lidar.ply                x, y, z float32 (VLP-16 pattern sampled from the depth)
        pose_lcam_front.txt                              x y z qx qy qz qw per frame, NED

``<face>`` is front, back, left, right, top, bottom. The toolkit's six-face sampler (``sample_coor``) reads the
faces in the camera frame x right / y down / z forward with exactly :mod:`~airfisheye_bench.geometry.cubemap`'s
axes and texel centres (top = ``up``, bottom = ``down``; tests/io/datasets/test_tartanair.py checks a point
through it), so the faces are used as they are. What is converted (``docs/design.md``, "TartanAir V2"): planar
depth -> range per texel; seg values -> training ids through the environment's names
(:mod:`~airfisheye_bench.io.datasets.tartanair_labels`); LiDAR points -> FLU. The LiDAR is the dataset's scan, or with
``data.lidar.preset`` that sensor's beams cast into the six depth faces (:meth:`TartanAirSource.cast_scan`).

Example:
    >>> src = TartanAirSource("/data/tartanair", environments=["OldTownFall"])  # doctest: +SKIP
    >>> sid = src.split("train")[0]; faces = src.cubemap(sid, "depth")           # doctest: +SKIP
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import ClassVar

import numpy as np
from PIL import Image

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.cameras import ideal_camera
from airfisheye_bench.geometry.cube_depth import (
    SIX_FACE_NAMES,
    lidar_from_faces,
    planar_to_range,
    sample_range,
)
from airfisheye_bench.geometry.cubemap import FACE_NAMES
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_presets import LIDAR_PRESETS
from airfisheye_bench.geometry.transforms import CAM_FROM_FLU, make_transform, quaternion_to_matrix
from airfisheye_bench.io.calib_yaml import Calibration
from airfisheye_bench.io.dataset_spec import ClassDef, DatasetSpec, SplitsSpec
from airfisheye_bench.io.datasets.base import OWN_LIDAR, DatasetSource, legacy_lidar
from airfisheye_bench.io.datasets.tartanair_labels import IGNORE, TRAIN_CLASSES, label_lut
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.scan import Scan, load_scan
from airfisheye_bench.io.splits import frame_blocks

log = logging.getLogger(__name__)

#: Our face name -> TartanAir's (``tartanair_module.py`` ``camera_directions``).
TARTANAIR_FACE = {
    "front": "front",
    "left": "left",
    "right": "right",
    "up": "top",
    "down": "bottom",
    "back": "back",
}
DIFFICULTIES = ("easy", "hard")
SIDE = "lcam"  # the LiDAR and the poses are the left camera rig's
#: The dataset's own LiDAR: mvs_utils ``VELODYNE_VLP_16`` (elevations -15..15 deg every 2 deg, 0.1 deg azimuth
#: steps -> 3600 per channel; data_cacher ``LiDARBase``: at most 57600 = 16 x 3600 points), from the cube's centre.
TARTANAIR_VLP16 = LidarSpec(
    points_per_channel=3600,
    hfov_deg=360.0,
    max_range=100.0,
    elevations_deg=tuple(float(e) for e in range(-15, 16, 2)),
    name="tartanair-vlp16",
)
#: Candidate axes of the LiDAR PLY -> the rotation to FLU (``lidar_frame``; ``auto`` picks the one the depth agrees
#: with). The toolkit says only "aligned with the left camera frame" (``docs/modalities.rst``).
LIDAR_FRAMES: dict[str, np.ndarray] = {
    "flu": np.eye(3),
    "ned": np.diag([1.0, -1.0, -1.0]),  # x forward, y right, z down (the pose files' body axes)
    "camera": CAM_FROM_FLU.T,  # x right, y down, z forward
}
#: NED body <- OpenCV camera (``customizer.py`` ``sample_flow_worker``: ``NED_R_cam``).
NED_FROM_CAM = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_AGREE = 0.05  # relative range tolerance of a LiDAR point against the depth face it falls on


class TartanAirSource(DatasetSource):
    """A TartanAir V2 root (``data.format=tartanair``; its ``data.format_options`` are the keyword arguments).

    Args:
        root: The folder holding the environment folders.
        environments: Environment names to use (``None``: every environment folder found).
        difficulties: ``easy`` and/or ``hard`` (the ``Data_<difficulty>`` folders).
        split_period: Splits by trajectory: the selected trajectories sorted by environment, difficulty, id; the
            k-th goes to ``val`` when ``k % split_period == split_period - 2``, ``test`` when ``split_period - 1``,
            else ``train`` (10: 80/10/10). With fewer trajectories than ``split_period`` (a small download), by
            frame blocks instead: each trajectory's frames in order, the last ``2 / split_period`` of them (at least
            one each; none from a trajectory of under 3 frames) in a ``val`` then a ``test`` block
            (:func:`~airfisheye_bench.io.splits.frame_blocks`).
        frame_stride: Use every n-th frame (10 Hz frames are near-duplicates).
        lidar: Deprecated (``data.lidar.preset`` picks the LiDAR, :meth:`cast_scan`): for one more release
            ``dataset`` (``lidar/*_lcam_front_lidar.ply``, as ``None``) or a preset of
            :data:`~airfisheye_bench.geometry.lidar_presets.LIDAR_PRESETS`, cast into the six depth faces as the
            source's own sensor (warned).
        lidar_frame: Axes of the PLY points: ``auto`` (the candidate of :data:`LIDAR_FRAMES` whose ranges match the
            depth faces, checked on each trajectory's first frame), ``flu``, ``ned`` or ``camera``.

    Example:
        >>> TartanAirSource.format, TartanAirSource.OPTIONS["split_period"], TARTANAIR_FACE["up"]
        ('tartanair', 10, 'top')
    """

    format: ClassVar[str] = "tartanair"
    OPTIONS: ClassVar[dict[str, object]] = {
        "environments": None,
        "difficulties": list(DIFFICULTIES),
        "split_period": 10,
        "frame_stride": 1,
        "lidar": None,  # deprecated: data.lidar.preset (base.legacy_lidar)
        "lidar_frame": "auto",
    }

    def __init__(
        self,
        root: str | Path,
        environments: list[str] | None = None,
        difficulties: list[str] | tuple[str, ...] = DIFFICULTIES,
        split_period: int = 10,
        frame_stride: int = 1,
        lidar: str | None = None,
        lidar_frame: str = "auto",
    ) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise DatasetFormatError(
                self.root, "not a folder (the TartanAir V2 root holds <env>/Data_easy/...)"
            )
        bad = sorted(set(difficulties) - set(DIFFICULTIES))
        if bad or not difficulties:
            raise ConfigError(
                f"data.format_options.difficulties: expected some of {list(DIFFICULTIES)}, got {bad}"
            )
        if int(split_period) != split_period or split_period < 3:
            raise ConfigError(f"data.format_options.split_period must be an integer >= 3, got {split_period}")
        if int(frame_stride) != frame_stride or frame_stride < 1:
            raise ConfigError(
                f"data.format_options.frame_stride must be a positive integer, got {frame_stride}"
            )
        if lidar not in (None, OWN_LIDAR) and lidar not in LIDAR_PRESETS:
            raise ConfigError(
                f"data.format_options.lidar: expected dataset or one of {sorted(LIDAR_PRESETS)}"
            )
        if lidar_frame != "auto" and lidar_frame not in LIDAR_FRAMES:
            raise ConfigError(
                f"data.format_options.lidar_frame: expected auto or one of {sorted(LIDAR_FRAMES)}"
            )
        self.options = {"split_period": int(split_period), "frame_stride": int(frame_stride)}
        preset = legacy_lidar(lidar)
        self.lidar_mode, self.lidar_frame = preset or OWN_LIDAR, lidar_frame
        self._lidar = TARTANAIR_VLP16 if preset is None else LidarSpec.from_preset(preset)
        self._trajs = self._find_trajectories(environments, tuple(difficulties))
        self._frames = {key: self._list_frames(key) for key in self._trajs}
        # Most downloads hold a few trajectories: splitting those by trajectory would leave val or test empty.
        self._by_frames = len(self._trajs) < self.options["split_period"]
        if self._by_frames:
            log.info(
                "tartanair: %d trajectories, fewer than split_period=%d: split by frame blocks within each",
                len(self._trajs),
                split_period,
            )
        self._cache: dict[tuple[str, str], object] = {}
        front = self._face_file(self._first_sample(), "front", "rgb")
        classes = tuple(ClassDef(i, name, color) for i, (name, color) in enumerate(TRAIN_CLASSES))
        self.spec = DatasetSpec(
            name="tartanair-v2",
            raw_classes=classes,  # the source maps each environment's values to these ids itself
            train_classes=classes,
            raw_to_train={c.id: c.id for c in classes},
            ignore_index=IGNORE,
            splits=SplitsSpec(
                files={s: s for s in ("train", "val", "test")},
                by="frame_blocks" if self._by_frames else "trajectory",
            ),
            sensors={"cubemap": {"face_size": self._image_size(front)}},
            contents=("cubemap", "lidar"),  # poses: T_world_cam, not the AirFisheye pose table
            description="TartanAir V2 (CC BY 4.0), read in place",
        )

    # ------------------------------------------------------------------------------------ discovery
    def _find_trajectories(self, environments, difficulties) -> dict[str, Path]:
        envs = sorted(p.name for p in self.root.iterdir() if p.is_dir())
        if environments is not None:
            missing = sorted(set(environments) - set(envs))
            if missing:
                raise DatasetFormatError(self.root, f"data.format_options.environments: no folder {missing}")
            envs = sorted(environments)
        trajs = {}
        for env in envs:
            for diff in difficulties:
                folder = self.root / env / f"Data_{diff}"
                for traj in sorted(folder.glob("P*")) if folder.is_dir() else []:
                    if (traj / f"image_{SIDE}_front").is_dir():
                        trajs[f"{env}/{diff}_{traj.name}"] = traj
        if not trajs:
            raise DatasetFormatError(
                self.root,
                f"no TartanAir V2 trajectory: expected <env>/Data_easy|Data_hard/P000/image_{SIDE}_front/",
            )
        return trajs

    def _list_frames(self, key: str) -> list[str]:
        folder = self._trajs[key] / f"image_{SIDE}_front"
        frames = sorted(p.name.split("_", 1)[0] for p in folder.glob(f"*_{SIDE}_front.png"))
        if not frames:
            raise DatasetFormatError(folder, f"no images named <frame>_{SIDE}_front.png")
        return frames[:: self.options["frame_stride"]]

    def _first_sample(self) -> str:
        key = next(iter(self._trajs))
        return f"{key}/{self._frames[key][0]}"

    # ---------------------------------------------------------------------------------- splits
    @property
    def split_names(self) -> list[str]:
        return ["train", "val", "test"]

    def split(self, name: str) -> list[str]:
        """Sample ids ``<env>/<difficulty>_<Pxxx>/<frame>`` of split ``name`` (see ``split_period``)."""
        if name not in self.split_names:
            raise ValueError(f"split must be one of {self.split_names}, got {name!r}")
        return [
            f"{key}/{frame}" for key in self.trajectories(name) for frame in self._split_frames(key, name)
        ]

    def trajectories(self, split: str | None = None) -> list[str]:
        """``<env>/<difficulty>_<Pxxx>`` with frames in ``split`` (all when ``None``), sorted."""
        if split is None:
            return list(self._trajs)
        if self._by_frames:
            return [key for key in self._trajs if self._split_frames(key, split)]
        period = self.options["split_period"]
        names = {period - 2: "val", period - 1: "test"}
        return [key for k, key in enumerate(self._trajs) if names.get(k % period, "train") == split]

    def split_rule(self, name: str) -> str:
        period, stride = self.options["split_period"], self.options["frame_stride"]
        if not self._by_frames:
            return (
                f"the {name} trajectories of the {len(self._trajs)} sorted ones (k % {period} == {period - 2}: val, "
                f"{period - 1}: test, else train; data.format_options.split_period)"
            )
        return (
            f"the {name} block of each trajectory's frames: the {len(self._trajs)} trajectories (fewer than "
            f"data.format_options.split_period={period}) are split by frame blocks, and only a trajectory of at "
            f"least 3 frames (after frame_stride={stride}) has val and test blocks"
        )

    def _split_frames(self, key: str, split: str) -> list[str]:
        """The frames of trajectory ``key`` in ``split`` (all of them when it splits by trajectory)."""
        if self._by_frames:
            return frame_blocks(self._frames[key], self.options["split_period"])[split]
        return self._frames[key]

    # ---------------------------------------------------------------------------- calibration
    def calib(self, sample_id: str) -> Calibration:
        """The default fisheye (equidistant 190 deg, twice the face size), the faces, the LiDAR: all at the left
        camera's centre, the same rendered instant; body = that camera's FLU axes."""
        key = self._key(sample_id)

        def build() -> Calibration:
            size = self._image_size(self._face_file(f"{key}/{self._frames[key][0]}", "front", "rgb"))
            camera = ideal_camera(2 * size, 2 * size, fov_deg=190.0, model="equidistant")
            T_body_cam = make_transform(CAM_FROM_FLU.T, np.zeros(3))
            return Calibration(camera.to_dict(), size, T_body_cam, np.eye(4), self._lidar.to_dict())

        return self._cached("calib", key, build)

    def T_cam_lidar(self, sample_id: str) -> np.ndarray:
        """LiDAR (FLU) -> camera: a pure rotation; both are rendered at the same instant (no motion between)."""
        return make_transform(CAM_FROM_FLU, np.zeros(3))

    def T_world_cam(self, sample_id: str) -> np.ndarray:
        """``[4, 4]`` camera (OpenCV axes) -> world (NED) of a frame, from ``pose_lcam_front.txt``."""
        key, frame = self._key(sample_id), sample_id.rsplit("/", 1)[1]
        path = self._trajs[key] / f"pose_{SIDE}_front.txt"
        poses = self._cached("poses", key, lambda: _read_poses(path))
        if int(frame) >= len(poses):
            raise DatasetFormatError(path, f"{len(poses)} poses, none for frame {frame}")
        t, q_xyzw = poses[int(frame), :3], poses[int(frame), 3:]
        R_world_ned = quaternion_to_matrix(np.roll(q_xyzw, 1))  # the file is x y z w (scipy order)
        return make_transform(R_world_ned @ NED_FROM_CAM, t)

    # ------------------------------------------------------------------------------- images
    def cubemap(self, sample_id: str, modality: str) -> np.ndarray:
        """The five faces in ``FACE_NAMES`` order: rgb uint8, seg training ids (255 unmapped), depth range."""
        return np.stack([self.face(sample_id, face, modality) for face in FACE_NAMES])

    def face(self, sample_id: str, face: str, modality: str) -> np.ndarray:
        """One face (any of ``SIX_FACE_NAMES``) of ``modality`` (depth as range)."""
        path = self._face_file(sample_id, face, modality)
        if not path.is_file():
            raise DatasetFormatError(
                path,
                "missing (the fisheye needs the lcam front, left, right, top and bottom faces; a cast LiDAR the back too)",
            )
        if modality == "rgb":
            return _read_image(path, "RGB")
        if modality == "seg":
            seg = _read_image(path, None)
            if seg.ndim != 2 or seg.dtype != np.uint8:
                raise DatasetFormatError(
                    path, f"expected a single-channel 8-bit label PNG, got {seg.shape} {seg.dtype}"
                )
            return self._label_lut(sample_id.split("/", 1)[0])[seg]
        # Sky is a very large finite value in the toolkit's data; anything non-finite is no depth (0).
        return planar_to_range(np.nan_to_num(read_depth_png(path), nan=0.0, posinf=0.0, neginf=0.0))

    def fisheye(self, sample_id: str, modality: str) -> np.ndarray:
        raise DatasetFormatError(self._trajs[self._key(sample_id)], self.missing_reason("fisheye"))

    def _face_file(self, sample_id: str, face: str, modality: str) -> Path:
        key, frame = self._key(sample_id), sample_id.rsplit("/", 1)[1]
        name = f"{SIDE}_{TARTANAIR_FACE[face]}"
        folder, suffix = {"rgb": ("image", ""), "depth": ("depth", "_depth"), "seg": ("seg", "_seg")}[
            modality
        ]
        return self._trajs[key] / f"{folder}_{name}" / f"{frame}_{name}{suffix}.png"

    def _label_lut(self, env: str) -> np.ndarray:
        path = self.root / env / "seg_label_map.json"

        def load() -> np.ndarray:
            try:
                name_map = json.loads(path.read_text())["name_map"]
                return label_lut({str(k): int(v) for k, v in name_map.items()})
            except FileNotFoundError:
                raise DatasetFormatError(path, "missing (each environment's label names)") from None
            except (ValueError, KeyError, TypeError, AttributeError, IndexError) as err:
                raise DatasetFormatError(path, f"expected {{'name_map': {{name: 0..255}}}} ({err})") from None

        return self._cached("labels", env, load)

    # --------------------------------------------------------------------------------- LiDAR
    def lidar_scan(self, sample_id: str) -> Scan:
        """The dataset's scan (points turned to FLU) or, with the deprecated ``lidar=<preset>``, one cast into the
        depth faces."""
        if self.lidar_mode != OWN_LIDAR:
            return self.cast_scan(sample_id, self._lidar)
        scan = load_scan(self._lidar_file(sample_id))
        R = LIDAR_FRAMES[self._lidar_axes(sample_id)]
        return Scan(
            scan.points @ R.T, scan.intensity, scan.rings, False, scan.no_returns, scan.path, scan.format
        )

    def cast_scan(self, sample_id: str, spec: LidarSpec) -> Scan:
        """A scan of ``spec`` (``data.lidar.preset``) cast from the cube's centre into the frame's six depth faces
        (nearest texel, its plane), in FLU, its rings known; beams without depth or beyond ``spec.max_range``
        return nothing (counted)."""
        points, rings = lidar_from_faces(self._planar_faces(sample_id), spec)
        beams = spec.channels * spec.points_per_channel
        path = self._face_file(sample_id, "front", "depth").parent
        return Scan(points, None, rings, False, beams - len(points), path, "tartanair_depth")

    def _lidar_file(self, sample_id: str) -> Path:
        key, frame = self._key(sample_id), sample_id.rsplit("/", 1)[1]
        path = self._trajs[key] / "lidar" / f"{frame}_{SIDE}_front_lidar.ply"
        if not path.is_file():
            raise DatasetFormatError(
                path, "missing (the LiDAR scan of this frame; data.lidar.preset casts one from the depth)"
            )
        return path

    def _planar_faces(self, sample_id: str) -> np.ndarray:
        return np.stack([read_depth_png(self._face_file(sample_id, f, "depth")) for f in SIX_FACE_NAMES])

    def lidar_agreement(self, sample_id: str) -> dict[str, float]:
        """Per :data:`LIDAR_FRAMES` candidate, the fraction of the frame's PLY points whose range matches the depth
        face along their direction (within 5 %)."""
        points = load_scan(self._lidar_file(sample_id)).points
        faces, norm = self._planar_faces(sample_id), np.linalg.norm(points, axis=1)
        out = {}
        for name, R in LIDAR_FRAMES.items():
            rng = sample_range((points @ R.T) @ CAM_FROM_FLU.T, faces)
            out[name] = float(np.mean(np.abs(rng - norm) <= _AGREE * norm)) if len(points) else 0.0
        return out

    def _lidar_axes(self, sample_id: str) -> str:
        if self.lidar_frame != "auto":
            return self.lidar_frame
        key = self._key(sample_id)

        def detect() -> str:
            first = f"{key}/{self._frames[key][0]}"
            agree = self.lidar_agreement(first)
            best = max(agree, key=agree.get)
            if agree[best] < 0.5:
                shares = ", ".join(f"{k} {v:.0%}" for k, v in agree.items())
                raise DatasetFormatError(
                    self._lidar_file(first),
                    f"the points match the depth faces in no candidate frame ({shares}); set "
                    "data.format_options.lidar_frame or data.lidar.preset",
                )
            return best

        return self._cached("lidar_axes", key, detect)

    # ------------------------------------------------------------------------------- helpers
    def path_of(self, sample_id: str, modality: str, source: str) -> Path:
        return self._face_file(sample_id, "front", modality)

    def missing_reason(self, content: str) -> str:
        if content == "fisheye":
            return (
                f"{self.root}: TartanAir V2 is read from its cube faces (its lcam_fish images are a Linear Spherical "
                "resampling this reader does not serve); use data.source=cubemap"
            )
        return f"{self.root}: the TartanAir V2 reader serves no {content}"

    def _key(self, sample_id: str) -> str:
        key = sample_id.rsplit("/", 1)[0]
        if key not in self._trajs:
            raise ValueError(
                f"sample id {sample_id!r} is not <env>/<difficulty>_<Pxxx>/<frame> of {self.root}"
            )
        return key

    def _image_size(self, path: Path) -> int:
        try:
            with Image.open(path) as img:
                w, h = img.size
        except FileNotFoundError:
            raise DatasetFormatError(path, "missing") from None
        except OSError as err:
            raise DatasetFormatError(path, f"unreadable image ({err})") from None
        if w != h:
            raise DatasetFormatError(path, f"cube faces are square; this one is {w}x{h}")
        return w

    def _cached(self, kind: str, key: str, load):
        if (kind, key) not in self._cache:
            self._cache[(kind, key)] = load()
        return self._cache[(kind, key)]


def read_depth_png(path: Path) -> np.ndarray:
    """Planar depth ``float32 [S, S]`` of a TartanAir V2 depth PNG.

    The toolkit writes ``depth.view("<u1")`` (4 bytes per pixel, little-endian) with OpenCV, which stores channel
    0 as PNG blue, and decodes ``cv2.imread(..., IMREAD_UNCHANGED).view("<f4")`` (``tartanair/reader.py``
    ``write_float_depth`` / ``read_depth``): float byte order = PNG B, G, R, A.
    """
    rgba = _read_image(path, None)
    if rgba.ndim != 3 or rgba.shape[2] != 4 or rgba.dtype != np.uint8:
        raise DatasetFormatError(
            path, f"expected an 8-bit RGBA PNG (float32 depth in its bytes), got {rgba.shape}"
        )
    return np.ascontiguousarray(rgba[..., [2, 1, 0, 3]]).view("<f4")[..., 0].astype(np.float32)


def _read_image(path: Path, mode: str | None) -> np.ndarray:
    try:
        with Image.open(path) as img:
            return np.asarray(img.convert(mode) if mode and img.mode != mode else img)
    except FileNotFoundError:
        raise DatasetFormatError(path, "missing") from None
    except OSError as err:
        raise DatasetFormatError(path, f"unreadable image ({err})") from None


def _read_poses(path: Path) -> np.ndarray:
    try:
        rows = [line.split() for line in path.read_text().splitlines() if line.strip()]
        poses = np.array(rows, dtype=np.float64)
    except FileNotFoundError:
        raise DatasetFormatError(path, "missing (the left front camera's poses)") from None
    except ValueError:
        raise DatasetFormatError(path, "expected 7 numbers per line: x y z qx qy qz qw") from None
    if poses.ndim != 2 or poses.shape[1] != 7:
        raise DatasetFormatError(path, "expected 7 numbers per line: x y z qx qy qz qw")
    return poses


__all__ = ["LIDAR_FRAMES", "TARTANAIR_VLP16", "TartanAirSource", "read_depth_png"]
