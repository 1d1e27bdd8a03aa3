"""Calibration files as the tools write them, read into cameras of the camera contract.

:func:`read_calibration` recognises a file's format from its contents (never its name), picks one camera
(``camera=`` a name or a 0-based index when the file holds several) and returns its flat camera dict in the
project's pixel convention, with the extrinsics the file gives; :func:`load_camera` turns that into a camera
(:func:`~airfisheye_bench.geometry.cameras.camera_from_dict`); :func:`save_camera` writes the project's own camera file, which
:func:`load_camera` reads back to an equal camera.

:data:`FORMATS` is the one table of formats, tried in order; each reader is a small module of this package with
its source named (``docs/design.md``, "Calibration files").

Modules: :mod:`~.read` (the table of formats, detection, reading), each format's reader (:mod:`~.basalt`,
:mod:`~.colmap`, ... ; the project's own file, read and written: :mod:`~.project`), :mod:`~.compare` (a camera's
short name, what differs between two). The public names are re-exported here.

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

from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CalibrationRecord
from airfisheye_bench.io.calibration_files.compare import camera_label, camera_mismatch
from airfisheye_bench.io.calibration_files.project import save_camera
from airfisheye_bench.io.calibration_files.read import FORMATS, detect_format, load_camera, read_calibration
from airfisheye_bench.io.errors import CalibrationFileError

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
