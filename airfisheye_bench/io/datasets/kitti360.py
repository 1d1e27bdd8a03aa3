"""KITTI-360's fisheye cameras and Velodyne (``data.format=kitti360``): images, MEI calibration, scans and poses.

KITTI-360 (www.cvlibs.net/datasets/kitti-360, CC BY-NC-SA 3.0: never copied into this repository) as its devkit
github:autonomousvision/kitti360Scripts (commit 40ee015) reads it. Files (``<seq>`` =
``2013_05_28_drive_XXXX_sync``, ``<frame>`` = ``%010d``)::

    calibration/image_02.yaml, image_03.yaml           MEI fisheye intrinsics (helpers/project.py CameraFisheye)
    calibration/calib_cam_to_pose.txt                  image_0X -> GPS/IMU pose frame (commons/loadCalibration.py)
    calibration/calib_cam_to_velo.txt                  image_00 -> Velodyne (loadCalibrationRigid)
    data_2d_raw/<seq>/image_0X/data_rgb/<frame>.png    fisheye images (viewer/kitti360Viewer3DRaw.py)
    data_2d_raw/<seq>/image_0X/timestamps.txt          camera time stamps (optional here)
    data_3d_raw/<seq>/velodyne_points/data/<frame>.bin float32 x y z reflectance (loadVelodyneData)
    data_3d_raw/<seq>/velodyne_points/timestamps.txt   scan time stamps (accumuLaser/src/accumulation.cpp)
    data_poses/<seq>/poses.txt                         frame + 3x4 pose -> world, posed frames only

Transforms, as ``viewer/kitti360Viewer3DRaw.py`` ``loadExtrinsics`` builds them (lines 78-96 at 40ee015):
``T_pose_velo = T_pose_cam0 @ inv(T_velo_cam0)`` (``TrVeloToPose``), and for camera X
``T_camX_velo = inv(T_velo_cam0 @ inv(T_pose_cam0) @ T_pose_camX)`` (``TrVeloToCam``); a fisheye camera has no
rectification (``projectVeloToImage``: ``TrVeloToRect = TrVeloToCam`` for cameras 2, 3). Here the "body" of the
:class:`~airfisheye_bench.io.calib_yaml.Calibration` is that pose frame (axes as ``poses.txt`` has them, not re-axed):
``T_body_cam = T_pose_camX``, ``T_body_lidar = T_pose_velo``. The Velodyne frame is x forward, y left, z up
(KITTI's), the project's FLU LiDAR frame, so scans are used as read (:func:`~airfisheye_bench.io.scan.load_scan`,
rings from the ``.bin`` firing order).

Motion compensation (docs/design.md, "KITTI-360"): the raw scans are not ego-motion corrected
(kitti360Scripts issue #87); :meth:`Kitti360Source.deskew` curls them as the devkit does
(:mod:`airfisheye_bench.geometry.deskew`), with each point's time from its azimuth and the scan period from
``timestamps.txt``; :meth:`Kitti360Source.T_cam_lidar` adds the camera's time offset where the camera has time
stamps. :meth:`Kitti360Source.depth_points` builds the depth target: the scan, or the scans of the ``accumulate``
posed frames either side moved into it through the poses.

Example:
    >>> src = Kitti360Source("/data/KITTI-360", camera="image_03")   # doctest: +SKIP
    >>> sid = src.split("train")[0]; sid                               # doctest: +SKIP
    '2013_05_28_drive_0000_sync/0000000001'
"""

from __future__ import annotations

import logging
from collections import OrderedDict
from functools import cached_property
from pathlib import Path
from typing import ClassVar

import numpy as np

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.deskew import curl_points, fraction_transform, scan_fraction
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.transforms import invert_rigid
from airfisheye_bench.io import codecs
from airfisheye_bench.io.calib_yaml import Calibration
from airfisheye_bench.io.calibration_files import load_camera
from airfisheye_bench.io.dataset_spec import ClassDef, DatasetSpec, SplitsSpec
from airfisheye_bench.io.datasets.base import DatasetSource, DepthPoints
from airfisheye_bench.io.datasets.kitti360_files import (
    read_cam_to_pose,
    read_poses,
    read_rigid,
    read_timestamps,
)
from airfisheye_bench.io.datasets.kitti360_splits import (
    SPLITS,
    check_sequences,
    frame_numbers,
    split_by_sequence,
    usable_sequences,
)
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.scan import Scan, load_scan

log = logging.getLogger(__name__)

TARGET_OCCLUSION = ("zbuffer", "hpr", "none")
_NO_LABELS = (
    "KITTI-360 has no semantic labels for its fisheye images (only the perspective cameras image_00/01 are "
    "labelled; kitti360Scripts issue #1)"
)


class Kitti360Source(DatasetSource):
    """One KITTI-360 root, one fisheye camera (the :class:`~airfisheye_bench.io.datasets.base.DatasetSource`).

    Args:
        root: The KITTI-360 root (holding ``calibration/``, ``data_2d_raw/``, ``data_3d_raw/``, ``data_poses/``).
        camera: ``image_02`` (left fisheye) or ``image_03`` (right).
        accumulate: The depth target holds the scans of this many posed frames either side (0: the frame's own).
        target_occlusion: Occlusion of the depth target's points: ``zbuffer``, ``hpr`` or ``none``.
        sequences: ``{split: [sequence, ...]}`` instead of the default rule (by sequence, see :meth:`split`).
        frame_step: Keep every ``frame_step``-th sample of a sequence.
    """

    format: ClassVar[str] = "kitti360"
    OPTIONS: ClassVar[dict[str, object]] = {
        "camera": "image_02",
        "accumulate": 0,
        "target_occlusion": "zbuffer",
        "sequences": None,
        "frame_step": 1,
    }
    modalities: ClassVar[tuple[str, ...]] = ("rgb",)
    #: The depth target is the projected Velodyne scans (:meth:`depth_points`), not a dense map.
    depth_from_points: ClassVar[bool] = True

    def __init__(
        self,
        root: str | Path,
        camera: str = "image_02",
        accumulate: int = 0,
        target_occlusion: str = "zbuffer",
        sequences: dict | None = None,
        frame_step: int = 1,
    ) -> None:
        opt = "data.format_options"
        if camera not in ("image_02", "image_03"):
            raise ConfigError(f"{opt}.camera={camera!r}: expected image_02 or image_03 (the fisheye cameras)")
        for key, value in (("accumulate", accumulate), ("frame_step", frame_step)):
            if (
                isinstance(value, bool)
                or not isinstance(value, int)
                or value < (0 if key == "accumulate" else 1)
            ):
                raise ConfigError(f"{opt}.{key}={value!r}: expected an integer >= {int(key == 'frame_step')}")
        if target_occlusion not in TARGET_OCCLUSION:
            raise ConfigError(
                f"{opt}.target_occlusion={target_occlusion!r}: expected one of {', '.join(TARGET_OCCLUSION)} "
                "(accumulated points have no rings for ordering)"
            )
        self.root = Path(root)
        self.camera = camera
        self.accumulate = accumulate
        self.target_occlusion = target_occlusion
        self.frame_step = frame_step
        self._sequences = check_sequences(self.root, sequences)
        self._cache: dict[tuple[str, str], object] = {}
        self._recent: OrderedDict[tuple[str, int, float], np.ndarray] = OrderedDict()

    def __getstate__(self) -> dict:  # caches are per process
        skip = ("_cache", "_recent", "spec", "_all_sequences")
        return {k: v for k, v in self.__dict__.items() if k not in skip}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._cache = {}
        self._recent = OrderedDict()

    # ------------------------------------------------------------------------------------------- contents
    @cached_property
    def spec(self) -> DatasetSpec:
        void = ClassDef(0, "unlabelled", (0, 0, 0))
        return DatasetSpec(
            name="kitti360",
            raw_classes=(void,),
            train_classes=(void,),
            raw_to_train={0: 0},
            splits=SplitsSpec(
                files={name: "data_2d_raw" for name in SPLITS},
                by="sequence",
                locations={seq: name for name in SPLITS for seq in self._split_sequences()[name]},
            ),
            contents=("fisheye", "lidar", "poses"),
            sensors={"camera": self.camera, "lidar": "hdl64e"},
            description="KITTI-360 fisheye images and Velodyne scans (CC BY-NC-SA 3.0)",
        )

    @classmethod  # asked of the class before a root is read (base.unserved_modality)
    def missing_reason(cls, content: str) -> str:
        if content in ("seg", "label"):
            return _NO_LABELS
        if content == "cubemap":
            return "KITTI-360 has recorded fisheye images, no cube faces"
        if content == "depth":
            return "KITTI-360 has no dense depth images: the depth target is the projected Velodyne scans"
        return f"KITTI-360 (data.format=kitti360) has no {content} data"

    # ----------------------------------------------------------------------------------------------- splits
    @property
    def split_names(self) -> list[str]:
        return list(SPLITS)

    def split(self, name: str) -> list[str]:
        """Sample ids ``<seq>/<frame>`` of ``name``: the split's sequences, in order, every ``frame_step``-th.

        Default rule (no official fisheye split exists): the sequences under ``data_2d_raw`` sorted by name; the
        last is ``test``, the one before ``val``, the others ``train``. Two sequences: ``train`` the first, ``val``
        and ``test`` the second; one: every split is that one (logged). ``sequences`` overrides it. A sample is a
        frame of ``poses.txt`` whose image and scan exist (the devkit projects posed frames only).
        """
        if name not in SPLITS:
            raise ValueError(f"split must be one of {SPLITS}, got {name!r}")
        out: list[str] = []
        for seq in self._split_sequences()[name]:
            out += [f"{seq}/{frame:010d}" for frame in self._frames(seq)[:: self.frame_step]]
        return out

    def split_rule(self, name: str) -> str:
        seqs = ", ".join(self._split_sequences()[name]) or "none"
        return (
            f"frames of data_poses/<seq>/poses.txt with a data_2d_raw/<seq>/{self.camera}/data_rgb image and a "
            f"velodyne scan, in the split's sequences: {seqs}"
        )

    @cached_property
    def _all_sequences(self) -> list[str]:
        return usable_sequences(self.root, self.camera)

    def _split_sequences(self) -> dict[str, list[str]]:
        return self._sequences if self._sequences is not None else split_by_sequence(self._all_sequences)

    def _frames(self, seq: str) -> np.ndarray:
        """Posed frames of ``seq`` that have an image and a scan."""

        def load() -> np.ndarray:
            frames = self._poses(seq)[0]
            images = frame_numbers(self._image_path(seq, 0).parent, ".png")
            scans = frame_numbers(self._scan_path(seq, 0).parent, ".bin")
            return frames[np.isin(frames, images) & np.isin(frames, scans)]

        return self._cached("frames", seq, load)

    # ------------------------------------------------------------------------------------------- sensors
    def calib(self, sample_id: str) -> Calibration:
        def load() -> Calibration:
            yaml_path = self.root / "calibration" / f"{self.camera}.yaml"
            if not yaml_path.is_file():
                raise DatasetFormatError(yaml_path, "no such file (the fisheye's MEI calibration)")
            cam = load_camera(yaml_path)  # its errors are DatasetFormatErrors naming the file and the key
            to_pose = read_cam_to_pose(self.root / "calibration" / "calib_cam_to_pose.txt")
            T_velo_cam0 = read_rigid(self.root / "calibration" / "calib_cam_to_velo.txt")
            T_pose_velo = to_pose["image_00"] @ invert_rigid(T_velo_cam0)  # TrVeloToPose
            return Calibration(
                camera=cam.to_dict(),
                face_size=None,
                T_body_cam=to_pose[self.camera],
                T_body_lidar=T_pose_velo,
                lidar=LidarSpec.from_preset("hdl64e").to_dict(),
                extras={"body": "KITTI-360 GPS/IMU pose frame (poses.txt)"},
            )

        return self._cached("calib", "", load)

    def cubemap(self, sample_id: str, modality: str) -> np.ndarray:
        raise DatasetFormatError(self.root, self.missing_reason("cubemap"))

    def fisheye(self, sample_id: str, modality: str) -> np.ndarray:
        if modality != "rgb":
            raise DatasetFormatError(self.root, self.missing_reason(modality))
        return codecs.read_rgb(self.path_of(sample_id, "rgb", "fisheye"))

    def lidar_scan(self, sample_id: str) -> Scan:
        seq, frame = _parse(sample_id)
        return load_scan(self._scan_path(seq, frame))

    def path_of(self, sample_id: str, modality: str, source: str) -> Path:
        seq, frame = _parse(sample_id)
        return self._scan_path(seq, frame) if modality in ("lidar", "depth") else self._image_path(seq, frame)

    # -------------------------------------------------------------------------------- motion compensation
    def T_cam_lidar(self, sample_id: str) -> np.ndarray:
        """Velodyne (at the scan's forward-facing instant) -> camera at its own time stamp.

        The static ``T_camX_velo``, times the vehicle's motion between the scan's reference time and the camera's
        time stamp (``data_2d_raw/<seq>/image_0X/timestamps.txt``; without it the two are taken as simultaneous,
        as the camera is triggered when the Velodyne faces forward).
        """
        seq, frame = _parse(sample_id)
        static = self.calib(sample_id).T_cam_lidar_static
        cam_times = self._timestamps(seq, self._image_path(seq, 0).parent.parent / "timestamps.txt")
        motion = self._motion(seq, frame)
        scan_times = self._scan_times(seq)
        if cam_times is None or scan_times is None or motion is None or motion[1] is None:
            return static
        if frame >= min(len(cam_times), len(scan_times)):
            return static
        D, dt = motion
        s = (scan_times[frame] - cam_times[frame]) / dt  # the camera's time as a fraction of D
        return static @ invert_rigid(fraction_transform(D, s))

    def deskew(self, sample_id: str, points: np.ndarray) -> np.ndarray:
        """Points of the frame's scan at the instant the Velodyne faced forward (see the module docstring).

        Point ``i`` was recorded ``a_i / (2 pi) * T`` before that instant (``a_i`` its azimuth, ``T`` the scan
        period: the median step of ``velodyne_points/timestamps.txt``); it moves by the fraction
        ``(a_i / 2 pi) T / dt`` of the motion ``D`` between the previous scan and this one, ``dt`` apart. With
        ``T = dt`` (no dropped scan) this is the devkit's curl exactly, and so it is without ``timestamps.txt`` (a
        separate download, ``data_3d_timestamps.zip``: logged).
        """
        seq, frame = _parse(sample_id)
        motion = self._motion(seq, frame)
        if motion is None:
            return np.asarray(points, np.float64)
        D, dt = motion
        ratio = 1.0 if dt is None else self._scan_period(seq) / dt
        return curl_points(points, D, scan_fraction(points) * ratio)

    def depth_points(self, sample_id: str, min_range: float = 0.0) -> DepthPoints:
        """The depth target's points in the frame's LiDAR frame: its deskewed scan, and with ``accumulate = N``
        the scans of the ``N`` posed frames either side, each deskewed and moved by
        ``inv(T_world_velo(f)) @ T_world_velo(g)`` (``T_world_velo = pose @ T_pose_velo``, as
        ``accumuLaser/src/accumulation.cpp`` ``AddVelodynePoints``). Returns closer than ``min_range`` to their
        own sensor are dropped first (self-hits)."""
        seq, frame = _parse(sample_id)
        frames, poses = self._poses(seq)
        i = int(np.searchsorted(frames, frame))
        T_pose_velo = self.calib(sample_id).T_body_lidar
        T_world_velo = poses[i] @ T_pose_velo
        clouds = []
        have = self._frames(seq)
        for j in range(max(0, i - self.accumulate), min(len(frames), i + self.accumulate + 1)):
            g = int(frames[j])
            if g != frame and g not in have:
                continue  # a posed frame without its scan
            points = self._curled(seq, g, min_range)
            if g != frame:
                T = invert_rigid(T_world_velo) @ poses[j] @ T_pose_velo
                points = points @ T[:3, :3].T + T[:3, 3]
            clouds.append(points)
        return DepthPoints(np.concatenate(clouds), self.target_occlusion)

    def _curled(self, seq: str, frame: int, min_range: float) -> np.ndarray:
        """A frame's scan without self-hits, curled; the last ``2 accumulate + 1`` are kept (the targets of
        neighbouring frames share them)."""
        key = (seq, frame, float(min_range))
        if key in self._recent:
            self._recent.move_to_end(key)
            return self._recent[key]
        points = load_scan(self._scan_path(seq, frame)).points
        points = self.deskew(f"{seq}/{frame:010d}", points[np.linalg.norm(points, axis=1) >= min_range])
        points.setflags(write=False)  # shared by several targets
        self._recent[key] = points
        while len(self._recent) > 2 * self.accumulate + 1:
            self._recent.popitem(last=False)
        return points

    def _motion(self, seq: str, frame: int) -> tuple[np.ndarray, float | None] | None:
        """``(D, dt)``: the Velodyne's motion from the previous frame into ``frame``, and their time apart
        (``None`` without time stamps). As the devkit's ``CurlParametersFromPoses``: frame 0 uses the next frame's
        motion; a frame whose neighbour has no pose (the vehicle standing) has none."""
        frames, poses = self._poses(seq)
        i = int(np.searchsorted(frames, frame))
        if i >= len(frames) or frames[i] != frame:
            raise DatasetFormatError(self._poses_path(seq), f"no pose for frame {frame}")
        a, b = (frame, frame + 1) if frame == 0 else (frame - 1, frame)
        ia, ib = np.searchsorted(frames, a), np.searchsorted(frames, b)
        if ia >= len(frames) or ib >= len(frames) or frames[ia] != a or frames[ib] != b:
            return None
        T_pose_velo = self.calib("").T_body_lidar
        T_a, T_b = poses[ia] @ T_pose_velo, poses[ib] @ T_pose_velo
        D = invert_rigid(T_b) @ T_a  # Tr_velo_pose^-1 (pose_b^-1 pose_a) Tr_velo_pose
        times = self._scan_times(seq)
        if times is None or b >= len(times):
            return D, None
        dt = float(times[b] - times[a])
        if not dt > 0:
            raise DatasetFormatError(
                self._scan_times_path(seq), f"time stamps of frames {a}, {b} do not increase"
            )
        return D, dt

    def _scan_period(self, seq: str) -> float:
        """The median step of the scans' time stamps (the Velodyne's revolution, 0.1 s)."""
        return float(np.median(np.diff(self._scan_times(seq))))

    def _scan_times(self, seq: str) -> np.ndarray | None:
        path = self._scan_times_path(seq)
        times = self._timestamps(seq, path)
        if times is None and ("warned", seq) not in self._cache:
            self._cache[("warned", seq)] = True
            log.warning(
                "KITTI-360: no %s: the scans are curled as the devkit does (a revolution per frame)", path
            )
        return times

    # ------------------------------------------------------------------------------------------- files
    def _image_path(self, seq: str, frame: int) -> Path:
        return self.root / "data_2d_raw" / seq / self.camera / "data_rgb" / f"{frame:010d}.png"

    def _scan_path(self, seq: str, frame: int) -> Path:
        return self.root / "data_3d_raw" / seq / "velodyne_points" / "data" / f"{frame:010d}.bin"

    def _scan_times_path(self, seq: str) -> Path:
        return self.root / "data_3d_raw" / seq / "velodyne_points" / "timestamps.txt"

    def _poses_path(self, seq: str) -> Path:
        return self.root / "data_poses" / seq / "poses.txt"

    def _poses(self, seq: str) -> tuple[np.ndarray, np.ndarray]:
        return self._cached("poses", seq, lambda: read_poses(self._poses_path(seq)))

    def _timestamps(self, seq: str, path: Path) -> np.ndarray | None:
        return self._cached("times", str(path), lambda: read_timestamps(path) if path.is_file() else None)

    def _cached(self, kind: str, key: str, load):
        if (kind, key) not in self._cache:
            self._cache[(kind, key)] = load()
        return self._cache[(kind, key)]


def _parse(sample_id: str) -> tuple[str, int]:
    seq, _, frame = sample_id.rpartition("/")
    if not seq or not frame.isdigit():
        raise ValueError(f"a KITTI-360 sample id is '<sequence>/<frame:010d>', got {sample_id!r}")
    return seq, int(frame)


__all__ = ["Kitti360Source"]
