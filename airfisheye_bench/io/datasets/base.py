"""What a dataset on disk must offer the datamodules: the :class:`DatasetSource` protocol.

Every format the benchmark reads (the AirFisheye layout, and the public fisheye datasets: TartanAir V2,
KITTI-360, WoodScape) is one class of this shape, registered in :data:`airfisheye_bench.io.datasets.DATASET_FORMATS`.
A source turns its dataset's files into the project's conventions (``docs/design.md``): cube faces in
:data:`~airfisheye_bench.geometry.cubemap.FACE_NAMES` order and orientation, depth as range in metres (0 invalid),
raw label ids that ``spec.raw_to_train`` maps to training classes, LiDAR points in the LiDAR's FLU frame, and a
:class:`~airfisheye_bench.io.calib_yaml.Calibration` per frame (the camera model, ``T_body_cam``, ``T_body_lidar``, the
LiDAR spec). The datamodule never looks at file names; the error messages of a source name the file.

Optional members (looked up with ``getattr``; a source without them is served as before):

- ``modalities``: the fisheye image modalities the source has (``rgb``, ``seg``, ``depth``; default all three). A
  task whose target needs a missing one is refused with ``missing_reason(<modality>)`` before any root is read
  (:func:`unserved_modality`), so a source that leaves one out defines ``missing_reason`` as a classmethod.
- ``deskew(sample_id, points) -> points``: the scan's points (``[M, 3]``, any subset of ``lidar_scan``'s, in its
  order) moved to where they were at the scan's reference time, the time ``T_cam_lidar`` refers to (a spinning
  LiDAR's raw scan is recorded over a revolution). Applied with ``data.motion_compensation``.
- ``depth_points(sample_id, min_range) -> DepthPoints``: the depth target is LiDAR points (a sparse-ground-truth
  dataset such as KITTI-360), projected at the served camera by the datamodule instead of a dense depth image.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.io.calib_yaml import Calibration
from airfisheye_bench.io.dataset_spec import DatasetSpec
from airfisheye_bench.io.scan import Scan


@runtime_checkable
class DatasetSource(Protocol):
    """Read access to one dataset root, in the project's conventions.

    Attributes:
        format: The registry name (``airfisheye``, ``tartanair``, ...).
        OPTIONS: The source's ``data.format_options`` and their defaults (the constructor's keyword arguments).
        root: The dataset root.
        spec: Classes (raw ids and the training classes they map to), the contents present
            (:data:`~airfisheye_bench.io.dataset_spec.KNOWN_CONTENTS`), the ignore index.
        modalities: The dense maps its images come with, of ``rgb``, ``seg``, ``depth`` (WoodScape has no depth,
            KITTI-360 no fisheye labels); a task needing another is refused with :meth:`missing_reason`. Read it
            with :func:`modalities_of` (a source that leaves it out has all three).
    """

    format: ClassVar[str]
    OPTIONS: ClassVar[dict[str, object]]
    modalities: ClassVar[tuple[str, ...]]
    root: Path
    spec: DatasetSpec

    @property
    def split_names(self) -> list[str]: ...

    def split(self, name: str) -> list[str]:
        """Sample ids of split ``name``, in a fixed order (empty when the root has none for it)."""

    def split_rule(self, name: str) -> str:
        """Which samples split ``name`` takes, in words: named by the refusal of an empty split."""

    def calib(self, sample_id: str) -> Calibration:
        """The calibration in force for a sample (camera, extrinsics, LiDAR spec; ``face_size`` for cube faces)."""

    def cubemap(self, sample_id: str, modality: str) -> np.ndarray:
        """Stacked faces ``[5, S, S(, 3)]`` in ``FACE_NAMES`` order: rgb uint8, seg uint8 raw ids, depth float32."""

    def fisheye(self, sample_id: str, modality: str) -> np.ndarray:
        """The recorded fisheye image ``[H, W(, 3)]`` of ``modality`` (rgb, seg raw ids, depth range)."""

    def lidar_scan(self, sample_id: str) -> Scan:
        """The LiDAR scan of a sample (points in the LiDAR frame, rings where the file records them)."""

    def T_cam_lidar(self, sample_id: str) -> np.ndarray:
        """``[4, 4]`` LiDAR -> camera transform of the sample, motion-compensated where the data allows."""

    def path_of(self, sample_id: str, modality: str, source: str) -> Path:
        """The file (or folder) that holds ``modality`` of a sample, for error messages."""

    def missing_reason(self, content: str) -> str:
        """One sentence on why the dataset has no ``content`` (asked only when ``spec.has(content)`` is false)."""


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


#: The dense maps a dataset may have; a source without ``modalities`` has all three.
DENSE_MODALITIES = ("rgb", "seg", "depth")


def modalities_of(source: object) -> tuple[str, ...]:
    """The dense maps ``source`` has (its ``modalities``; all of :data:`DENSE_MODALITIES` when it does not say).

    Example:
        >>> modalities_of(object())
        ('rgb', 'seg', 'depth')
    """
    return tuple(getattr(source, "modalities", DENSE_MODALITIES))


#: Sample key -> the dense map it is read from.
_MAP_OF_KEY = {"label": "seg", "depth": "depth"}


def unserved_modality(source: object, keys: Iterable[str]) -> str | None:
    """The first dense map that ``keys`` (sample keys a task needs) are read from and that ``source`` (a source or
    its class) does not have (:func:`modalities_of`), or ``None``; a depth target given as points
    (``depth_points``) needs no depth map.

    Asked of the class before a root is read (WoodScape has no depth at all): the class's ``missing_reason`` then
    says why, so a source whose ``modalities`` leave a map out defines it as a classmethod.

    Example:
        >>> class RgbOnly:
        ...     modalities = ("rgb",)
        >>> unserved_modality(RgbOnly, {"label"}), unserved_modality(RgbOnly, {"sparse_depth"})
        ('seg', None)
    """
    modalities = modalities_of(source)
    from_points = callable(getattr(source, "depth_points", None))
    for key in sorted(set(keys) & set(_MAP_OF_KEY)):
        modality = _MAP_OF_KEY[key]
        if modality not in modalities and not (modality == "depth" and from_points):
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


__all__ = [
    "DENSE_MODALITIES",
    "DatasetSource",
    "DepthPoints",
    "check_options",
    "modalities_of",
    "unserved_modality",
]
