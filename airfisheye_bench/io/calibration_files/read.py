"""Reading a calibration file: the table of formats (:data:`FORMATS`), a file's format recognised from its contents
(:func:`detect_format`), one camera of it as the camera contract's flat dict (:func:`read_calibration`) or as a
camera (:func:`load_camera`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

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

__all__ = ["FORMATS", "detect_format", "load_camera", "read_calibration"]

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
