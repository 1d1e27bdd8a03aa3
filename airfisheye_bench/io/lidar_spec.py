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
import logging
import math
import re
from pathlib import Path
from typing import Any

from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_presets import (
    LIDAR_PRESETS,
    OUSTER_BEAM_ORIGIN_MM,
    OUSTER_GEN1_BEAM_ORIGIN_MM,
    laser_table,
)
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.yamlio import read_yaml

SPEC_FILE_SUFFIXES = (".yaml", ".yml", ".json")

log = logging.getLogger(__name__)


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


def lidar_preset_problem(value: Any, synthetic: bool) -> str | None:
    """``data.lidar.preset``'s one rule (the config check and the datamodule both ask it): a named sensor serves
    any dataset; a spec file describes the LiDAR of a ``data.root`` release only, since the synthetic data is
    generated with a named sensor. ``None``: allowed (a file's contents are checked when it is read, once).

    Example:
        >>> lidar_preset_problem("hdl64e", synthetic=True) is None
        True
        >>> lidar_preset_problem("hdl65e", synthetic=False)  # doctest: +ELLIPSIS
        'expected one of hdl32e, hdl64e, ..., or a LiDAR spec file (YAML, JSON or Ouster metadata)'
    """
    if value in LIDAR_PRESETS:
        return None
    names = ", ".join(sorted(LIDAR_PRESETS))
    if not Path(str(value)).expanduser().is_file():
        return f"expected one of {names}, or a LiDAR spec file (YAML, JSON or Ouster metadata)"
    if synthetic:
        return (
            f"the synthetic data simulates a named sensor only; expected one of {names} (a spec file describes "
            "the LiDAR of a data.root release)"
        )
    return None


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
    if "beam_altitude_angles" in data or "beam_intrinsics" in data:
        return ouster_metadata_spec(data, path)
    try:
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


# ------------------------------------------------------------------ Ouster metadata JSON
def ouster_metadata_spec(meta: dict[str, Any], path: str | Path = "<metadata>") -> LidarSpec:
    """A spec from an Ouster sensor's metadata JSON (already parsed), read as the Ouster SDK reads it
    (github:ouster-lidar/ouster-sdk ``ouster_core/src/metadata.cpp``, ``sensor_info.cpp``, ``xyzlut.cpp``).

    Both layouts are read: the legacy flat one (``beam_altitude_angles``, ``beam_azimuth_angles``,
    ``lidar_origin_to_beam_origin_mm``, ``data_format``, ``lidar_mode`` such as ``"1024x10"``, ``prod_line``) and
    the nested one of firmware 2.x / the SDK (``beam_intrinsics``, ``lidar_data_format``, ``config_params``,
    ``sensor_info``). As in the SDK:

    * the beams are ``pixels_per_column``, else the product line's (``"OS-1-16-A0"``: 16). Firmware 1.13 lists a
      16- or 32-beam sensor's angles at its 64 positions with ``(0, 0)`` for the beams it does not fire: those
      placeholders are dropped (the SDK refuses such a file);
    * without ``lidar_origin_to_beam_origin_mm`` (firmware 1.14 and older) the beams start at the product line's
      default distance from the axis (OS-0 27.67, OS-1 15.806, OS-2 13.762 mm, else 12.163), logged;
    * column ``m`` of ``columns_per_frame`` W fires at encoder angle ``2 pi m / W`` clockwise, turned by
      ``lidar_to_sensor_transform`` (by default 180 deg: the sensor frame, x forward, which the SDK's xyz and the
      ROS driver's ``os_sensor`` use); a beam's azimuth is that minus its ``beam_azimuth_angles``, so the offsets
      here are their negatives. A ``column_window`` ``[first, last]`` (it may wrap) narrows the field of view to
      its ``(last - first) % W + 1`` columns, centred where they point (``azimuth_center_deg``).

    Raises:
        DatasetFormatError: One line naming the file, the key and what is wrong.

    Example:
        >>> meta = {"beam_altitude_angles": [2.0, -2.0], "beam_azimuth_angles": [1.0, -1.0],
        ...         "lidar_origin_to_beam_origin_mm": 15.806, "lidar_mode": "512x10"}
        >>> spec = ouster_metadata_spec(meta)
        >>> spec.elevations_deg, spec.azimuth_offsets_deg, spec.points_per_channel, spec.hfov_deg
        ((-2.0, 2.0), (1.0, -1.0), 512, 360.0)
    """
    path = Path(path)
    nested = "beam_intrinsics" in meta

    def refuse(key: str, message: str) -> DatasetFormatError:
        return DatasetFormatError(path, message, key=key)

    def pick(nested_key: str, flat_key: str) -> tuple[str, Any]:
        # The SDK's convert_legacy_to_nonlegacy moves a flat key to its nested place; read either, and name a missing
        # one as the file's layout would.
        for key in (nested_key, flat_key):
            value: Any = meta
            for part in key.split("."):
                value = value.get(part) if isinstance(value, dict) else None
            if value is not None:
                return key, value
        return (nested_key if nested else flat_key), None

    def angles(*keys: str) -> tuple[str, list[float] | None]:
        key, value = pick(*keys)
        if value is not None and (
            not isinstance(value, list)
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        ):
            raise refuse(key, "must be a list of angles in degrees, one per beam")
        return key, None if value is None else [float(v) for v in value]

    alt_key, altitudes = angles("beam_intrinsics.beam_altitude_angles", "beam_altitude_angles")
    az_key, azimuths = angles("beam_intrinsics.beam_azimuth_angles", "beam_azimuth_angles")
    if altitudes is None:
        raise refuse(alt_key, "is missing: one altitude per beam is needed")
    if azimuths is not None and len(azimuths) != len(altitudes):
        raise refuse(
            alt_key, f"has {len(altitudes)} angles but {az_key} has {len(azimuths)}: one per beam each"
        )
    azimuths = azimuths or [0.0] * len(altitudes)

    # How many beams fire: pixels_per_column, else the count in prod_line (the SDK's ProductInfo regex).
    line_key, prod_line = pick("sensor_info.prod_line", "prod_line")
    ppc_key, beams = pick("lidar_data_format.pixels_per_column", "data_format.pixels_per_column")
    source = f"{ppc_key}={beams}"
    if beams is None and isinstance(prod_line, str):
        match = re.match(r"\w+-(?:\d+|DOME)?(?:-MAX)?-(\d+)", prod_line)
        beams, source = (int(match[1]), f"{line_key} {prod_line!r}") if match else (None, "")
    placeholders = [
        i for i, (a, z) in enumerate(zip(altitudes, azimuths, strict=True)) if a == 0.0 and z == 0.0
    ]
    if isinstance(beams, int) and len(altitudes) != beams:
        if len(altitudes) < beams:
            raise refuse(
                alt_key, f"has {len(altitudes)} angles for the {beams} beams of {source}: one per beam"
            )
        if len(altitudes) - len(placeholders) != beams:
            raise refuse(
                alt_key,
                f"has {len(altitudes)} angles, {len(placeholders)} of them (0, 0) placeholders, for the {beams} "
                f"beams of {source}: cannot tell which beams fire",
            )
        skip = set(placeholders)
        altitudes = [a for i, a in enumerate(altitudes) if i not in skip]
        azimuths = [a for i, a in enumerate(azimuths) if i not in skip]
    duplicate = next((a for i, a in enumerate(altitudes) if a in altitudes[:i]), None)
    if duplicate is not None:
        raise refuse(alt_key, f"lists altitude {duplicate:g} twice: each beam needs its own (how many fire?)")

    origin_key, origin_mm = pick(
        "beam_intrinsics.lidar_origin_to_beam_origin_mm", "lidar_origin_to_beam_origin_mm"
    )
    if origin_mm is None:
        # Firmware 1.14 and older wrote none: the SDK takes its product line's default, not the axis.
        prefix = next((p for p in OUSTER_BEAM_ORIGIN_MM if str(prod_line).startswith(p)), None)
        origin_mm = OUSTER_BEAM_ORIGIN_MM[prefix] if prefix else OUSTER_GEN1_BEAM_ORIGIN_MM
        log.info(
            "%s: no %s; the beams start %g mm from the axis, the Ouster SDK's default for %s",
            path,
            origin_key,
            origin_mm,
            f"{prefix}* sensors" if prefix else "a product line it does not know",
        )
    elif isinstance(origin_mm, bool) or not isinstance(origin_mm, (int, float)) or not 0 <= origin_mm < 1000:
        raise refuse(origin_key, f"must be millimetres in [0, 1000), got {origin_mm!r}")

    # Columns per turn: columns_per_frame, else the first number of lidar_mode ("1024x10").
    cols_key, columns = pick("lidar_data_format.columns_per_frame", "data_format.columns_per_frame")
    if columns is None:
        cols_key, mode = pick("config_params.lidar_mode", "lidar_mode")
        match = re.fullmatch(r"(\d+)x\d+", mode) if isinstance(mode, str) else None
        if mode is not None and not match:
            raise refuse(cols_key, f"must be columns x rate such as '1024x10', got {mode!r}")
        columns = int(match[1]) if match else None
    if columns is None:
        raise refuse(cols_key, "is missing, and so is columns_per_frame: how many columns make a turn?")
    if isinstance(columns, bool) or not isinstance(columns, int) or columns < 1:
        raise refuse(cols_key, f"must be a positive integer, got {columns!r}")

    window_key, window = pick("lidar_data_format.column_window", "data_format.column_window")
    kwargs: dict[str, Any] = {"points_per_channel": columns, "hfov_deg": 360.0}
    if window is not None:
        if not (
            isinstance(window, list)
            and len(window) == 2
            and all(isinstance(c, int) and not isinstance(c, bool) and 0 <= c < columns for c in window)
        ):
            raise refuse(window_key, f"must be [first, last] columns in [0, {columns - 1}], got {window!r}")
        first, last = window
        count = (last - first) % columns + 1  # the SDK's window length; last < first wraps through column 0
        if count < columns:
            t_key, t = pick("lidar_intrinsics.lidar_to_sensor_transform", "lidar_to_sensor_transform")
            if t is not None and not (
                isinstance(t, list) and len(t) == 16 and all(isinstance(v, (int, float)) for v in t)
            ):
                raise refuse(t_key, "must be 16 numbers (a 4 x 4 matrix, row-major)")
            yaw = math.atan2(t[4], t[0]) if t is not None else math.pi  # the SDK's default: 180 deg about z
            # xyzlut: column m points at encoder 2 pi - 2 pi m / W in the lidar frame, then lidar_to_sensor turns it.
            centre = math.degrees(yaw - 2.0 * math.pi * (first + (count - 1) / 2.0) / columns)
            centre = round((centre + 180.0) % 360.0 - 180.0, 9)  # a window centred ahead gives 0, not 1e-14
            kwargs = {
                "points_per_channel": count,
                "hfov_deg": 360.0 * count / columns,
                "azimuth_center_deg": centre,
            }
            if abs(centre) + kwargs["hfov_deg"] / 2.0 > 180.0 + 1e-9:
                raise refuse(
                    window_key,
                    f"{window} points at {centre:.1f} +- {kwargs['hfov_deg'] / 2.0:.1f} deg, across +-180 deg "
                    "(behind the sensor): a LidarSpec's field of view may not cross it",
                )
    try:
        return LidarSpec(
            **laser_table(
                altitudes, [-a for a in azimuths], [(origin_mm / 1000.0, 0.0, 0.0)] * len(altitudes)
            ),
            **kwargs,
            name=path.stem,
        )
    except ValueError as err:
        raise DatasetFormatError(path, str(err)) from None


__all__ = [
    "SPEC_FILE_SUFFIXES",
    "load_lidar_spec",
    "ouster_metadata_spec",
    "read_lidar_spec_file",
    "velodyne_calibration_spec",
]
