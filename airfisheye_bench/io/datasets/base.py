"""What a dataset on disk must offer the datamodules: the :class:`DatasetSource` contract.

Every format the benchmark reads (the AirFisheye layout, and the public fisheye datasets: TartanAir V2,
KITTI-360, WoodScape, AirSim360 / Omni360-X) is one subclass of :class:`DatasetSource`, registered in
:data:`airfisheye_bench.io.datasets.DATASET_FORMATS`. A source turns its dataset's files into the project's
conventions (``docs/design.md``): cube faces in :data:`~airfisheye_bench.geometry.cubemap.FACE_NAMES` order and
orientation, depth as range in metres (0 invalid), raw label ids that ``spec.raw_to_train`` maps to training classes,
LiDAR points in the LiDAR's FLU frame, and a :class:`~airfisheye_bench.io.calib_yaml.Calibration` per frame (the
camera model, ``T_body_cam``, ``T_body_lidar``, the LiDAR spec). The datamodule never looks at file names; the error
messages of a source name the file.

The contract is the class itself: the abstract members every reader defines, and the hooks with a default that a
reader overrides where its dataset differs (``docs/design.md``, "Adding a dataset"). The dataset
(:class:`datamodules.AirFisheyeDataset`) calls them directly, nothing else of a reader:
``tests/io/datasets/test_contract.py`` checks that every member it uses is declared here and that every registered
reader implements the contract.

``data.lidar.preset`` picks the LiDAR for every format (:meth:`DatasetSource.cast_scan`); TartanAir's and Omni360's
``format_options.lidar``, which did it before, is read as that key for one release (:func:`legacy_lidar`).
"""

from __future__ import annotations

import logging
import warnings
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.io.calib_yaml import Calibration
from airfisheye_bench.io.dataset_spec import DatasetSpec
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.scan import Scan

log = logging.getLogger(__name__)

#: The dense maps a dataset may have; a source that does not set ``modalities`` has all three.
DENSE_MODALITIES = ("rgb", "seg", "depth")


class DatasetSource(ABC):
    """Read access to one dataset root, in the project's conventions: subclass it for a new format.

    Every reader sets these (class attributes, or in ``__init__``):

    Attributes:
        format: The registry name (``airfisheye``, ``tartanair``, ...), the ``data.format`` that picks it.
        OPTIONS: Its ``data.format_options`` and their defaults: the constructor's keyword arguments after ``root``
            (``configs/data/<format>.yaml`` lists them all).
        root: The dataset root.
        spec: Classes (raw ids and the training classes they map to), the contents present
            (:data:`~airfisheye_bench.io.dataset_spec.KNOWN_CONTENTS`: which of ``cubemap``, ``equirect``,
            ``fisheye``, ``lidar``, ... the dataset has), the ignore index.

    Hooks with a default, set where the dataset differs (the methods below have theirs in their docstrings):

    Attributes:
        modalities: The dense maps its images come with, of ``rgb``, ``seg``, ``depth`` (default all three;
            WoodScape has no depth, KITTI-360 no fisheye labels). Read before a root is opened
            (:func:`unserved_modality`): a task needing a map the class leaves out is refused with
            :meth:`missing_reason`, then a classmethod. A reader may narrow it per root in ``__init__`` (an Omni360
            scene without its depth folder).
        depth_from_points: The depth target is LiDAR points (:meth:`depth_points`, a sparse-ground-truth dataset
            such as KITTI-360), projected at the served camera, instead of a dense depth map (default ``False``).
        parallax_free: The LiDAR sees from the camera's centre (a scan cast from the depth at the camera, as
            Omni360's): nothing it returns is hidden from the camera, so the dataset projects its scans without an
            occlusion correction, whatever ``data.occlusion`` says (default ``False``).
        pano_rotation: ``R_pano_cam0``, ``[3, 3]``: the recorded camera's directions -> the panorama's frame, the
            orientation a ``data.source=equirect`` remap starts from before ``data.gimbal`` turns it (default
            ``None``: the panorama's own axes).
    """

    format: ClassVar[str]
    OPTIONS: ClassVar[dict[str, object]]
    root: Path
    spec: DatasetSpec

    modalities: tuple[str, ...] = DENSE_MODALITIES
    depth_from_points: ClassVar[bool] = False
    parallax_free: ClassVar[bool] = False
    pano_rotation: np.ndarray | None = None

    # ------------------------------------------------------------------------------------ every reader defines
    @property
    @abstractmethod
    def split_names(self) -> list[str]:
        """The splits the source has (``train``, ``val``, ``test``): what ``airfisheye-inspect`` walks."""

    @abstractmethod
    def split(self, name: str) -> list[str]:
        """Sample ids of split ``name``, in a fixed order (empty when the root has none for it).

        Called once when the dataset opens the split; a sample id is the source's own key for a frame.
        """

    @abstractmethod
    def split_rule(self, name: str) -> str:
        """Which samples split ``name`` takes, in words: called only when :meth:`split` is empty, for the
        :class:`~airfisheye_bench.io.errors.EmptySplitError` that refuses it."""

    @abstractmethod
    def calib(self, sample_id: str) -> Calibration:
        """The calibration in force for a sample (camera, extrinsics, LiDAR spec; ``face_size`` for cube faces).

        Called when a split opens (its first sample's: the calibrated camera, the cube-face size) and per frame
        for the LiDAR spec when ``data.lidar.preset`` is null and for the static ``T_cam_lidar`` when
        ``data.motion_compensation`` is false.
        """

    @abstractmethod
    def lidar_scan(self, sample_id: str) -> Scan:
        """The source's own LiDAR scan of a sample (points in the LiDAR's FLU frame, rings where known).

        Called per frame for ``sparse_depth`` when ``data.lidar.preset`` is null (:meth:`cast_scan` otherwise).
        A dataset without a LiDAR (no ``lidar`` in ``spec.contents``: its tasks are refused first) raises
        :class:`~airfisheye_bench.io.errors.DatasetFormatError` with :meth:`missing_reason`.
        """

    @abstractmethod
    def T_cam_lidar(self, sample_id: str) -> np.ndarray:
        """``[4, 4]`` LiDAR -> camera transform of the sample, motion-compensated where the data allows.

        Called per frame that serves LiDAR points (``sparse_depth``, or a :meth:`depth_points` target).
        """

    @abstractmethod
    def path_of(self, sample_id: str, modality: str, source: str) -> Path:
        """The file (or folder) that holds ``modality`` of a sample: a dense map (``rgb``, ``seg``, ``depth``) read
        from ``source`` (``cubemap``, ``equirect``, ``fisheye``), or a file of the scan (``lidar``,
        ``lidar_visible``) where the dataset has one, whatever ``source`` says.

        Called for the dataset's errors about that file, and by ``airfisheye-inspect`` for each dense map.
        """

    @abstractmethod
    def missing_reason(self, content: str) -> str:
        """One sentence on why the dataset has no ``content`` (a content of ``spec.contents``, an image source or a
        dense map): the dataset refuses a task or ``data.source`` with it. A classmethod where ``modalities``
        leaves a map out (asked of the class before a root is read)."""

    # --------------------------------------------------------------------------- hooks with a default
    def fisheye(self, sample_id: str, modality: str) -> np.ndarray:
        """The recorded fisheye image ``[H, W(, 3)]`` of ``modality``: rgb uint8, seg uint8 raw ids, depth float32
        range.

        Called per frame with ``data.source=fisheye``. Default: the dataset has none (``spec.contents`` has no
        ``fisheye``): :class:`~airfisheye_bench.io.errors.DatasetFormatError` with :meth:`missing_reason`.
        """
        raise DatasetFormatError(self.root, self.missing_reason("fisheye"))

    def cubemap(self, sample_id: str, modality: str) -> np.ndarray:
        """Stacked faces ``[5, S, S(, 3)]`` in ``FACE_NAMES`` order: rgb uint8, seg uint8 raw ids, depth float32.

        Called per frame with ``data.source=cubemap`` (``spec.contents`` has ``cubemap``). Default: the dataset
        has none, refused with :meth:`missing_reason`.
        """
        raise DatasetFormatError(self.root, self.missing_reason("cubemap"))

    def equirect(self, sample_id: str, modality: str) -> np.ndarray:
        """An equirectangular panorama ``[H, W(, 3)]`` (``spec.equirect_size``): rgb uint8, seg uint8 raw ids,
        depth float32 range.

        Called per frame with ``data.source=equirect`` (``spec.contents`` has ``equirect``), remapped from
        :attr:`pano_rotation`. Default: the dataset has none, refused with :meth:`missing_reason`.
        """
        raise DatasetFormatError(self.root, self.missing_reason("equirect"))

    def cast_scan(self, sample_id: str, spec: LidarSpec) -> Scan:
        """A scan of the sensor ``spec`` (``data.lidar.preset``) for a sample, as :meth:`lidar_scan` gives one.

        Called per frame instead of :meth:`lidar_scan` when ``data.lidar.preset`` is set. A source that simulates
        its LiDAR from depth (TartanAir's faces, Omni360's panoramas) casts that sensor's beams. Default: a
        recorded LiDAR cannot become another sensor: its scan as recorded (:meth:`lidar_scan`), which ``spec`` then
        describes (its rings, its density subset) in place of the calibration's.
        """
        return self.lidar_scan(sample_id)

    def deskew(self, sample_id: str, points: np.ndarray) -> np.ndarray:
        """The scan's points (``[M, 3]``, any subset of the scan's, in its order) moved to where they were at the
        scan's reference time, the time :meth:`T_cam_lidar` refers to (a spinning LiDAR's raw scan is recorded over
        a revolution).

        Called per frame on the filtered scan with ``data.motion_compensation`` (the default). Default: the points
        as they are (a scan taken at one instant: rendered, or deskewed already).
        """
        return points

    def depth_points(self, sample_id: str, min_range: float = 0.0) -> DepthPoints:
        """The points whose projection at the served camera is the sample's depth target (returns closer than
        ``min_range``, ``data.lidar.min_range``, dropped).

        Called per frame for ``depth`` when :attr:`depth_from_points` is true, never otherwise. Default: none
        (a reader that sets :attr:`depth_from_points` overrides it).
        """
        raise NotImplementedError(f"{type(self).__name__} sets depth_from_points without depth_points")

    def lidar_visible(self, sample_id: str) -> np.ndarray:
        """``bool [N]``: which points of the sample's scan (:meth:`lidar_scan`, in its order) the camera sees, the
        generator's exact visibility.

        Called per frame with ``data.occlusion=oracle``, only when ``spec.contents`` has ``lidar_visible`` (the
        synthetic releases). Default: the dataset has none, refused with :meth:`missing_reason`.
        """
        raise DatasetFormatError(self.root, self.missing_reason("lidar_visible"))


@dataclass(frozen=True)
class DepthPoints:
    """The points whose projection at the served camera is a sample's depth target (``depth_points``).

    Attributes:
        points: ``float64 [M, 3]`` in the sample's LiDAR frame (the frame ``T_cam_lidar`` maps to the camera).
        occlusion: How the points the camera cannot see are removed: a method of
            :data:`~airfisheye_bench.geometry.occlusion.OCCLUSION_METHODS` that needs no rings (``zbuffer``,
            ``hpr``, ``none``): accumulated points have no ring structure.
        occlusion_options: That method's options (unset ones take their defaults).
    """

    points: np.ndarray
    occlusion: str = "zbuffer"
    occlusion_options: dict = field(default_factory=dict)


def modalities_of(source: DatasetSource | type[DatasetSource]) -> tuple[str, ...]:
    """The dense maps ``source`` (a reader or its class) has: its ``modalities``.

    Example:
        >>> modalities_of(DatasetSource)
        ('rgb', 'seg', 'depth')
    """
    return tuple(source.modalities)


#: Sample key -> the dense map it is read from.
_MAP_OF_KEY = {"label": "seg", "depth": "depth"}


def unserved_modality(source: DatasetSource | type[DatasetSource], keys: Iterable[str]) -> str | None:
    """The first dense map that ``keys`` (sample keys a task needs) are read from and that ``source`` (a source or
    its class) does not have (:func:`modalities_of`), or ``None``; a depth target given as points
    (``depth_from_points``) needs no depth map.

    Asked of the class before a root is read (WoodScape has no depth at all): the class's ``missing_reason`` then
    says why, so a source whose ``modalities`` leave a map out defines it as a classmethod.

    Example:
        >>> class RgbOnly(DatasetSource):
        ...     modalities = ("rgb",)
        >>> unserved_modality(RgbOnly, {"label"}), unserved_modality(RgbOnly, {"sparse_depth"})
        ('seg', None)
    """
    modalities = modalities_of(source)
    for key in sorted(set(keys) & set(_MAP_OF_KEY)):
        modality = _MAP_OF_KEY[key]
        if modality not in modalities and not (modality == "depth" and source.depth_from_points):
            return modality
    return None


def check_options(format_name: str, given: dict, allowed: dict[str, object]) -> dict:
    """``data.format_options`` of a source: unknown keys refused, unset ones from ``allowed``'s defaults.

    Example:
        >>> check_options("kitti360", {"camera": "image_03"}, {"camera": "image_02", "accumulate": 0})
        {'camera': 'image_03', 'accumulate': 0}
    """
    unknown = sorted(set(given) - set(allowed))
    if unknown:
        raise ConfigError(
            f"data.format_options: unknown keys {unknown} for data.format={format_name}; expected some of "
            f"{sorted(allowed)}"
        )
    return {key: default if given.get(key) is None else given[key] for key, default in allowed.items()}


#: The option TartanAir and Omni360 picked their LiDAR with before ``data.lidar.preset`` did it for every format:
#: read as that key for one release (:func:`legacy_lidar`), then gone.
LEGACY_LIDAR_OPTION = "lidar"
#: ``format_options.lidar``'s name for the dataset's own LiDAR (TartanAir's recorded scans): ``data.lidar.preset``
#: null.
OWN_LIDAR = "dataset"


def legacy_lidar(value: str | None) -> str | None:
    """The deprecated ``format_options.lidar`` as the ``data.lidar.preset`` it stands for (``dataset``, the
    dataset's own LiDAR: ``None``), said with a :class:`DeprecationWarning` and a log line that name the new key.
    ``None`` (not given): ``None``, nothing said.

    A reader that took the option takes its own sensor from it for one more release, so a run that sets it serves
    what it served before; :func:`lidar_option_conflict` refuses it beside a different ``data.lidar.preset``.

    Example:
        >>> import warnings
        >>> with warnings.catch_warnings(record=True) as caught:
        ...     warnings.simplefilter("always")
        ...     legacy_lidar("hdl64e"), legacy_lidar("dataset"), legacy_lidar(None)
        ('hdl64e', None, None)
        >>> print(caught[0].message)
        data.format_options.lidar=hdl64e is deprecated and goes in the next release: data.lidar.preset picks the LiDAR of every format; use data.lidar.preset=hdl64e
    """
    if value is None:
        return None
    preset = None if value == OWN_LIDAR else str(value)
    use = "null (the dataset's own, the default)" if preset is None else preset
    message = (
        f"data.format_options.{LEGACY_LIDAR_OPTION}={value} is deprecated and goes in the next release: "
        f"data.lidar.preset picks the LiDAR of every format; use data.lidar.preset={use}"
    )
    log.warning("%s", message)
    warnings.warn(message, DeprecationWarning, stacklevel=3)
    return preset


def lidar_option_conflict(
    format_options: Mapping[str, Any] | None, preset: Any, key: str = "data.format_options"
) -> str | None:
    """Why the deprecated ``<key>.lidar`` and ``data.lidar.preset`` cannot both stand (they name different LiDARs;
    ``dataset`` is a null preset), or ``None``. Nothing is warned here: the reader that reads the option warns.

    Example:
        >>> lidar_option_conflict({"lidar": "hdl64e"}, "vlp16")  # doctest: +ELLIPSIS
        "data.format_options.lidar='hdl64e' and data.lidar.preset='vlp16' name different LiDARs: ..."
        >>> lidar_option_conflict({"lidar": "vlp16"}, "vlp16") is None, lidar_option_conflict({"lidar": "dataset"}, None)
        (True, None)
    """
    value = (format_options or {}).get(LEGACY_LIDAR_OPTION)
    if value is None or preset is None:
        return None
    if (None if value == OWN_LIDAR else str(value)) == str(preset):
        return None
    return (
        f"{key}.{LEGACY_LIDAR_OPTION}={value!r} and data.lidar.preset={preset!r} name different LiDARs: "
        f"{key}.{LEGACY_LIDAR_OPTION} is deprecated: set it to null and give data.lidar.preset alone"
    )


__all__ = [
    "DENSE_MODALITIES",
    "LEGACY_LIDAR_OPTION",
    "OWN_LIDAR",
    "DatasetSource",
    "DepthPoints",
    "check_options",
    "legacy_lidar",
    "lidar_option_conflict",
    "modalities_of",
    "unserved_modality",
]
