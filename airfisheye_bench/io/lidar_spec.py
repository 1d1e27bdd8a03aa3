"""Where a :class:`~airfisheye_bench.geometry.lidar.LidarSpec` comes from: a preset name, a mapping, or a file.

A file is YAML or JSON holding a ``LidarSpec`` mapping (``LidarSpec.to_dict()``, or ``{preset: hdl64e, ...}`` with
changes), or an Ouster sensor's metadata JSON (recognised by its ``beam_altitude_angles``, at the top level or
under ``beam_intrinsics``).

Example:
    >>> load_lidar_spec("vlp16").channels
    16
    >>> load_lidar_spec({"preset": "hdl64e", "points_per_channel": 1024}).points_per_channel
    1024
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_presets import LIDAR_PRESETS, ouster_metadata_table
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.yamlio import read_yaml

SPEC_FILE_SUFFIXES = (".yaml", ".yml", ".json")


def load_lidar_spec(value: LidarSpec | str | Path | dict[str, Any]) -> LidarSpec:
    """A LiDAR spec from a preset name, a mapping, or a YAML / JSON / Ouster metadata file.

    Raises:
        ValueError: An unknown preset or a bad mapping (the message names the key or the presets).
        DatasetFormatError: A file that is missing or does not describe a sensor (naming the file).
    """
    if isinstance(value, LidarSpec):
        return value
    if isinstance(value, dict):
        return LidarSpec.from_dict(value)
    text = str(value)
    if text in LIDAR_PRESETS:
        return LidarSpec.from_preset(text)
    path = Path(text)
    if path.suffix.lower() not in SPEC_FILE_SUFFIXES:
        raise ValueError(
            f"unknown LiDAR preset {text!r}; expected one of {', '.join(sorted(LIDAR_PRESETS))}, or a "
            f"{'/'.join(SPEC_FILE_SUFFIXES)} file describing the sensor"
        )
    return read_lidar_spec_file(path)


def read_lidar_spec_file(path: str | Path) -> LidarSpec:
    """A spec from a YAML / JSON file (a ``LidarSpec`` mapping) or an Ouster metadata JSON."""
    path = Path(path)
    if not path.is_file():
        raise DatasetFormatError(path, "no such LiDAR spec file")
    try:
        data = json.loads(path.read_text()) if path.suffix.lower() == ".json" else read_yaml(path)
    except (OSError, ValueError) as err:
        raise DatasetFormatError(path, f"cannot be parsed ({err})") from None
    if not isinstance(data, dict):
        raise DatasetFormatError(path, "a LiDAR spec file holds a mapping")
    try:
        if "beam_altitude_angles" in data or "beam_intrinsics" in data:
            return LidarSpec(**ouster_metadata_table(data), name=path.stem)
        return LidarSpec.from_dict(data)
    except (TypeError, ValueError) as err:
        raise DatasetFormatError(path, str(err)) from None


__all__ = ["SPEC_FILE_SUFFIXES", "load_lidar_spec", "read_lidar_spec_file"]
