"""Calibration files as the tools write them, read into cameras of the camera contract.

:func:`read_calibration` recognises a file's format from its contents (never its name), picks one camera
(``camera=`` a name or a 0-based index when the file holds several) and returns its flat camera dict in the
project's pixel convention, with the extrinsics the file gives; :func:`load_camera` turns that into a camera
(:func:`~airfisheye_bench.geometry.cameras.camera_from_dict`); :func:`save_camera` writes the project's own camera file, which
:func:`load_camera` reads back to an equal camera.

:data:`FORMATS` is the one table of formats, tried in order; each reader is a small module of this package with
its source named (``docs/design.md``, "Calibration files").

Example:
    >>> import json, pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "calib.json"
    >>> path.write_text(json.dumps({"value0": {"intrinsics": [{"camera_type": "eucm", "intrinsics": {
    ...     "fx": 191.1, "fy": 191.1, "cx": 254.9, "cy": 256.9, "alpha": 0.63, "beta": 1.04}}],
    ...     "resolution": [[512, 512]]}}))
    178
    >>> record = read_calibration(path)
    >>> record.format, record.camera["model"], record.camera["alpha"]
    ('basalt', 'eucm', 0.63)
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.errors import MissingFileError
from airfisheye_bench.geometry.cameras import CameraModel, camera_from_dict
from airfisheye_bench.io.calibration_files import (
    basalt,
    colmap,
    kalibr,
    kitti360,
    ocamcalib,
    opencv,
    project,
    ros,
    woodscape,
)
from airfisheye_bench.io.calibration_files._fields import (
    CalibrationFormat,
    CalibrationRecord,
    Fields,
    parse_structured,
    select_camera,
    syntax_error,
)
from airfisheye_bench.io.errors import CalibrationFileError
from airfisheye_bench.io.yamlio import to_plain

__all__ = [
    "FORMATS",
    "CalibrationFileError",
    "CalibrationFormat",
    "CalibrationRecord",
    "camera_label",
    "camera_mismatch",
    "detect_format",
    "load_camera",
    "read_calibration",
    "save_camera",
]

#: The formats, in the order they are tried: text formats first, then the structured ones from the most specific
#: signature to the least (a ROS file also has OpenCV's camera_matrix; the project's dict is checked first).
FORMATS: tuple[CalibrationFormat, ...] = (
    ocamcalib.FORMAT,
    colmap.FORMAT,
    project.FORMAT,
    basalt.FORMAT,
    kalibr.FORMAT,
    kitti360.FORMAT,
    woodscape.FORMAT,
    ros.FORMAT,
    opencv.FORMAT,
)


def detect_format(path: str | Path) -> tuple[CalibrationFormat, Any]:
    """The format of a file and its document (a mapping), recognised from the contents.

    Raises:
        MissingFileError: no such file.
        CalibrationFileError: not a format of :data:`FORMATS` (one line naming them; their layouts are in
            ``docs/design.md``, "Calibration files"), or, for a file that is neither JSON nor YAML and no text
            format, the parser's error with its line and column.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise MissingFileError(f"{path}: no such calibration file") from None
    except (OSError, UnicodeDecodeError) as err:
        raise CalibrationFileError(path, f"cannot be read as text ({type(err).__name__}: {err})") from None
    doc = parse_structured(text)
    for fmt in FORMATS:
        if fmt.detect(text, doc):
            return fmt, (fmt.document(text, doc) if fmt.document is not None else doc)
    if doc is None and (error := syntax_error(text)) is not None:
        # A YAML or JSON file with a typo: the parser's line and column say more than "no format matched".
        raise CalibrationFileError(path, error)
    # One line: the formats' layouts are docs/design.md's table ("Calibration files"), not this message.
    names = ", ".join(fmt.name for fmt in FORMATS)
    raise CalibrationFileError(
        path,
        f"not a calibration file of a known format ({names}; their keys: docs/design.md, Calibration files)",
    )


def read_calibration(
    path: str | Path, camera: str | int | None = None, option: str = "camera"
) -> CalibrationRecord:
    """Read one camera of a calibration file as the camera contract's flat dict.

    Args:
        path: The file, in any format of :data:`FORMATS`.
        camera: Which camera of a file that holds several: its name in the file (``cam1``, a COLMAP camera id) or
            its 0-based index. May be left out when the file holds one camera.
        option: The name of ``camera`` in messages (``data.camera.camera`` for a training config).

    Returns:
        The :class:`CalibrationRecord` (format, camera name, flat camera dict, extrinsics).

    Raises:
        MissingFileError: no such file.
        CalibrationFileError: (a ``ValueError``) unknown format, unsupported model, missing key, wrong value, or
            several cameras and no ``camera``; the message names the file, the key and what is supported.
    """
    path = Path(path)
    fmt, doc = detect_format(path)
    fields = Fields(path, doc)
    cameras = fmt.cameras(fields)
    name = select_camera(path, cameras, camera, option)
    camera_dict, extrinsics = cameras[name](fields)
    return CalibrationRecord(path=path, format=fmt.name, name=name, camera=camera_dict, extrinsics=extrinsics)


def load_camera(path: str | Path, camera: str | int | None = None, option: str = "camera") -> CameraModel:
    """The camera of a calibration file (any format of :data:`FORMATS`), in the project's pixel convention.

    Args:
        path: The file.
        camera: Which camera of a file that holds several: its name (``cam1``, a COLMAP camera id) or its 0-based
            index.
        option: The name of ``camera`` in messages.

    Raises:
        MissingFileError: no such file.
        CalibrationFileError: (a ``ValueError``) unknown format, unsupported model, missing key, a wrong value
            (also one the camera model itself refuses, e.g. a non-monotonic polynomial), or several cameras and
            no ``camera``; the message names the file, the key and what is supported.

    Example:
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "image_02.yaml"
        >>> _ = path.write_text("%YAML:1.0\\n---\\nmodel_type: MEI\\ncamera_name: image_02\\nimage_width: 1400\\n"
        ...     "image_height: 1400\\nmirror_parameters:\\n   xi: 2.2134047507854890e+00\\ndistortion_parameters:\\n"
        ...     "   k1: 1.6798235660113681e-02\\n   k2: 1.6548773243373522e+00\\n   p1: 4.2223943394772046e-04\\n"
        ...     "   p2: 4.2462134260997584e-04\\nprojection_parameters:\\n   gamma1: 1.3363220825849971e+03\\n"
        ...     "   gamma2: 1.3357883350012958e+03\\n   u0: 7.1694323510126321e+02\\n   v0: 7.0576498308221585e+02\\n")
        >>> camera = load_camera(path)
        >>> camera.model, camera.width, round(camera.xi, 4)
        ('unified', 1400, 2.2134)
    """
    record = read_calibration(path, camera, option)
    key = "camera" if record.format == "airfisheye" else record.name
    try:
        return camera_from_dict(record.camera)
    except (TypeError, ValueError) as err:
        raise CalibrationFileError(
            record.path, f"not a valid {record.camera.get('model')} camera ({err})", key=key
        ) from None


def save_camera(camera: Any, path: str | Path) -> Path:
    """Write ``camera`` (anything with ``to_dict()``, or its flat dict) as the project's camera file.

    YAML (``.json``: JSON) with the flat dict at the top level, floats written so that they read back exactly;
    written to a temporary name, then renamed. :func:`load_camera` reads it back to an equal camera.

    Returns:
        The path written.
    """
    path = Path(path)
    data = camera.to_dict() if hasattr(camera, "to_dict") else dict(camera)
    if path.suffix.lower() == ".json":
        text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    else:
        header = "# Camera (airfisheye-bench camera dict; docs/design.md, Fisheye camera).\n"
        # Block style, one parameter a line; PyYAML writes floats as repr, which reads back to the same float.
        text = header + yaml.safe_dump(to_plain(data), sort_keys=False, default_flow_style=False, width=120)
    atomic_write_text(path, text)
    return path


def camera_label(camera: Any) -> str:
    """A short name of a camera (its ``to_dict()`` or the dict): ``<model> <W>x<H>``, for tables and messages.

    Example:
        >>> camera_label({"model": "unified", "width": 1400, "height": 1400, "xi": 2.2})
        'unified 1400x1400'
        >>> camera_label({"width": 64, "height": 48})  # the first calib.yaml files: equidistant
        'equidistant 64x48'
    """
    d = camera.to_dict() if hasattr(camera, "to_dict") else dict(camera)
    return f"{d.get('model', 'equidistant')} {d.get('width', '?')}x{d.get('height', '?')}"


def camera_mismatch(expected: Any, served: Any) -> str | None:
    """``None`` when two cameras (objects or dicts) are the same, else one line naming both and what differs.

    Example:
        >>> a = {"model": "eucm", "width": 64, "height": 64, "fx": 24.0, "fy": 24.0, "cx": 31.5, "cy": 31.5,
        ...      "alpha": 0.6, "beta": 1.0}
        >>> camera_mismatch(a, dict(a)) is None
        True
        >>> camera_mismatch(a, {**a, "alpha": 0.5, "cx": 30.0})
        'eucm 64x64 (alpha=0.6, cx=31.5) and eucm 64x64 (alpha=0.5, cx=30.0) differ in alpha, cx'
    """
    a = expected.to_dict() if hasattr(expected, "to_dict") else dict(expected)
    b = served.to_dict() if hasattr(served, "to_dict") else dict(served)
    keys = sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))
    if not keys:
        return None
    shown = [k for k in keys if k not in ("model", "width", "height")][:4]

    def describe(d: dict) -> str:
        values = ", ".join(f"{k}={d.get(k)!r}" for k in shown)
        return camera_label(d) + (f" ({values})" if values else "")

    return f"{describe(a)} and {describe(b)} differ in {', '.join(keys)}"
