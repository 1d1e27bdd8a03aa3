"""Where a :class:`~airfisheye_bench.geometry.lidar.LidarSpec` comes from: a preset name, a mapping, or a file.

A file is YAML or JSON holding a ``LidarSpec`` mapping (``LidarSpec.to_dict()``, or ``{preset: hdl64e, ...}`` with
changes), an Ouster sensor's metadata JSON (recognised by its ``beam_altitude_angles``, at the top level or
under ``beam_intrinsics``), or the ROS Velodyne driver's calibration YAML (recognised by its ``lasers`` list; see
:func:`velodyne_calibration_spec`).

Example:
    >>> load_lidar_spec("vlp16").channels
    16
    >>> load_lidar_spec({"preset": "hdl64e", "points_per_channel": 1024}).points_per_channel
    1024
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_presets import LIDAR_PRESETS, laser_table, ouster_metadata_table
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
    """A spec from a YAML / JSON file (a ``LidarSpec`` mapping), an Ouster metadata JSON or a Velodyne driver's
    calibration YAML."""
    path = Path(path)
    if not path.is_file():
        raise DatasetFormatError(path, "no such LiDAR spec file")
    try:
        data = json.loads(path.read_text()) if path.suffix.lower() == ".json" else read_yaml(path)
    except (OSError, ValueError) as err:
        raise DatasetFormatError(path, f"cannot be parsed ({err})") from None
    if not isinstance(data, dict):
        raise DatasetFormatError(path, "a LiDAR spec file holds a mapping")
    if "lasers" in data:
        return velodyne_calibration_spec(data, path)
    try:
        if "beam_altitude_angles" in data or "beam_intrinsics" in data:
            return LidarSpec(**ouster_metadata_table(data), name=path.stem)
        return LidarSpec.from_dict(data)
    except (TypeError, ValueError) as err:
        raise DatasetFormatError(path, str(err)) from None


# The ROS Velodyne driver's calibration YAML (github:ros-drivers/velodyne, velodyne_pointcloud/params/*.yaml, read by
# src/lib/calibration.cc). Besides the driver's keys a file may give points_per_channel and max_range (the driver
# ignores keys it does not know); without them they come from the Velodyne preset with as many lasers and the
# nearest elevations (a VLP-32C's file is not an HDL-32E's), else 1800 (0.2 deg at 10 Hz) and 200 m.
_VELODYNE_KEYS = ("lasers", "num_lasers", "distance_resolution", "points_per_channel", "max_range")
_VELODYNE_PRESETS = ("vlp16", "hdl32e", "vlp32c", "hdl64e")
# Per laser: the corrections the geometry needs (the driver requires all but horiz_offset_correction), with the
# largest magnitude that is still in the driver's units (radians, metres): a value in degrees or cm is refused.
_VELODYNE_LASER = {
    "vert_correction": math.pi / 2,
    "rot_correction": math.pi,
    "vert_offset_correction": 1.0,
    "horiz_offset_correction": 1.0,
}


def velodyne_calibration_spec(data: dict[str, Any], path: str | Path = "<calibration>") -> LidarSpec:
    """A spec from the ROS Velodyne driver's calibration YAML (VLP16db.yaml, 32db.yaml, 64e_s2.1-sztaki.yaml...).

    Per laser: elevation ``vert_correction`` and azimuth offset ``rot_correction`` (radians), beam origin from
    ``vert_offset_correction`` and ``horiz_offset_correction`` (metres), placed as the driver's
    ``RawData::unpack`` (src/lib/rawdata.cc) places them: with ``a = encoder - rot_correction`` clockwise from
    forward in Velodyne's frame (x right, y forward), ``x = (d cos v - V sin v) sin a - H cos a``, ``y = (d cos v -
    V sin v) cos a + H sin a``, ``z = d sin v + V cos v``, then ``(x, y) -> (y, -x)`` into ROS's. In ours (x
    forward, y left) that is azimuth ``rot_correction - encoder`` (the offset is ``+rot_correction``) and origin
    ``(radial, tangential, vertical) = (-V sin v, H, V cos v)``: the vertical offset is perpendicular to the beam,
    the horizontal one to its left. ``dist_correction`` (a range bias along the beam), the two-point and intensity
    corrections do not move the beams and are not read. Lasers are sorted by elevation (the driver's rings).

    Raises:
        DatasetFormatError: One line naming the file, the key and what is expected.

    Example:
        >>> lasers = [{"laser_id": 0, "vert_correction": -0.1, "rot_correction": 0.0, "vert_offset_correction": 0.0},
        ...           {"laser_id": 1, "vert_correction": 0.1, "rot_correction": 0.0, "vert_offset_correction": 0.0}]
        >>> spec = velodyne_calibration_spec({"lasers": lasers, "num_lasers": 2, "points_per_channel": 900})
        >>> [round(e, 3) for e in spec.elevations_deg], spec.points_per_channel
        ([-5.73, 5.73], 900)
    """
    path = Path(path)

    def refuse(key: str, expected: str) -> DatasetFormatError:
        return DatasetFormatError(path, expected, key=key)

    for key in data:
        if key not in _VELODYNE_KEYS:
            raise refuse(str(key), f"not a Velodyne calibration key; expected {', '.join(_VELODYNE_KEYS)}")
    lasers = data["lasers"]
    if not isinstance(lasers, list) or len(lasers) < 2:
        raise refuse("lasers", "must be a list of at least 2 lasers (laser_id, vert_correction, ...)")
    if data.get("num_lasers", len(lasers)) != len(lasers):
        raise refuse("num_lasers", f"is {data['num_lasers']} but 'lasers' lists {len(lasers)}")
    table: dict[int, dict[str, float]] = {}
    position: dict[int, int] = {}  # laser_id -> its index in the list, for the messages
    for k, laser in enumerate(lasers):
        if not isinstance(laser, dict):
            raise refuse(f"lasers[{k}]", "must be a mapping (laser_id, vert_correction, rot_correction, ...)")
        laser_id = laser.get("laser_id")
        if not isinstance(laser_id, int) or isinstance(laser_id, bool) or not 0 <= laser_id < len(lasers):
            raise refuse(
                f"lasers[{k}].laser_id", f"must be an integer in [0, {len(lasers)}), got {laser_id!r}"
            )
        if laser_id in table:
            raise refuse(f"lasers[{k}].laser_id", f"{laser_id} is listed twice")
        values = {}
        for name, limit in _VELODYNE_LASER.items():
            value = laser.get(name, 0.0 if name == "horiz_offset_correction" else None)
            unit = "radians" if limit > 1.0 else "metres"
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not abs(value) <= limit:
                raise refuse(
                    f"lasers[{k}].{name}",
                    f"must be {unit} within +-{limit:.4g} (the driver's unit), got {value!r}",
                )
            values[name] = float(value)
        table[laser_id], position[laser_id] = values, k
    rows = [table[i] for i in range(len(lasers))]
    elevations = [math.degrees(r["vert_correction"]) for r in rows]
    for i, e in enumerate(elevations):
        if e in elevations[:i]:
            raise refuse(
                f"lasers[{position[i]}].vert_correction",
                "equals another laser's: each ring needs its own elevation",
            )
    azimuths = [math.degrees(r["rot_correction"]) for r in rows]
    origins = [
        (
            -r["vert_offset_correction"] * math.sin(r["vert_correction"]),
            r["horiz_offset_correction"],
            r["vert_offset_correction"] * math.cos(r["vert_correction"]),
        )
        for r in rows
    ]
    table_kwargs = laser_table(
        elevations, azimuths if any(azimuths) else None, origins if any(map(any, origins)) else None
    )
    kwargs = {"points_per_channel": 1800, "max_range": 200.0}
    low, high = min(elevations), max(elevations)
    similar = [LidarSpec.from_preset(name) for name in _VELODYNE_PRESETS]
    similar = [p for p in similar if p.channels == len(rows)]
    if similar:
        nearest = min(similar, key=lambda p: abs(p.vfov_deg[0] - low) + abs(p.vfov_deg[1] - high))
        kwargs = {"points_per_channel": nearest.points_per_channel, "max_range": nearest.max_range}
    kwargs.update({k: data[k] for k in ("points_per_channel", "max_range") if k in data})
    try:
        return LidarSpec(**table_kwargs, hfov_deg=360.0, name=path.stem, **kwargs)
    except ValueError as err:  # points_per_channel / max_range given in the file
        raise DatasetFormatError(path, str(err)) from None


__all__ = ["SPEC_FILE_SUFFIXES", "load_lidar_spec", "read_lidar_spec_file", "velodyne_calibration_spec"]
