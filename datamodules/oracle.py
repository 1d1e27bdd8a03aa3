"""The ``oracle`` sparse input: the generator's exact visibility of every served LiDAR point.

A synthetic release records, per point of a scan, whether the camera centre sees it (``lidar_visible``, an exact
ray cast; see ``sensors.visibility``). The oracle keeps exactly those points: the sparse input no occlusion
method can beat, served beside them as ``data.occlusion=oracle`` (:data:`~airfisheye_bench.geometry.occlusion.ORACLE`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.io import DatasetFormatError, DatasetSource


def require_visibility(reader: DatasetSource, root: str | Path) -> None:
    """Refuse the oracle on a release without visibility ground truth, in one line.

    Raises:
        ConfigError: naming ``data.occlusion``, the dataset and the inputs it can serve instead.
    """
    if not reader.spec.has("lidar_visible"):
        raise ConfigError(
            f"data.occlusion=oracle needs the generator's per-point visibility (lidar_visible), which {root} "
            "does not have (only synthetic releases do); use ordering, zbuffer, hpr or none"
        )


def oracle_visible(reader: DatasetSource, sample_id: str, keep: np.ndarray) -> np.ndarray:
    """``bool [M]``: which of the served points of a frame the camera sees.

    Args:
        reader: The release (with ``lidar_visible``).
        sample_id: The frame.
        keep: ``bool [N]`` the points of the scan that survive the filtering of
            :meth:`~datamodules.AirFisheyeDataset.lidar_points` (``M = keep.sum()``): the visibility is indexed
            with the same mask, so the flags stay with their points.

    Raises:
        DatasetFormatError: the visibility file does not hold one flag per point of the scan.

    Example:
        >>> reader = DatasetReader("/data/synthetic")                     # doctest: +SKIP
        >>> oracle_visible(reader, "town/traj00/000000", keep).dtype      # doctest: +SKIP
        dtype('bool')
    """
    visible = np.asarray(reader.lidar_visible(sample_id), dtype=bool)
    if visible.shape != keep.shape:
        raise DatasetFormatError(
            reader.path_of(sample_id, "lidar_visible", "fisheye"),  # a scan's file: any image source
            f"{len(visible)} visibility flags for a scan of {len(keep)} points",
        )
    return visible[keep]


__all__ = ["oracle_visible", "require_visibility"]
