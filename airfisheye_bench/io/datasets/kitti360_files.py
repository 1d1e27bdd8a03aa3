"""The KITTI-360 text files a fisheye + Velodyne sample needs, read as the devkit reads them.

Source: github:autonomousvision/kitti360Scripts, commit 40ee015 (2025-04-27):

- ``calibration/calib_cam_to_pose.txt``: lines ``image_0X: r11 r12 r13 t1 r21 r22 r23 t2 r31 r32 r33 t3``, camera
  X -> GPS/IMU (pose) frame (``kitti360scripts/devkits/commons/loadCalibration.py`` ``loadCalibrationCameraToPose``:
  ``readVariable(fid, 'image_0X', 3, 4)`` plus the row ``0 0 0 1``; every one of image_00..03 must be there).
- ``calibration/calib_cam_to_velo.txt``: 12 numbers, ``image_00`` -> Velodyne (``loadCalibrationRigid``:
  ``np.loadtxt(...).reshape(3, 4)``).
- ``data_poses/<seq>/poses.txt``: per line ``frame`` and the 12 numbers of a 3x4 pose -> world, row-major; only
  the frames with a pose are listed (``kitti360scripts/helpers/project.py`` ``Camera.__init__``; the C++
  ``accumuLaser/src/commons.cpp`` ``LoadPoses``).
- ``timestamps.txt`` (``data_3d_raw/<seq>/velodyne_points/``, ``data_2d_raw/<seq>/image_0X/``): one line per frame,
  ``YYYY-MM-DD HH:MM:SS.nnnnnnnnn`` (``accumuLaser/src/commons.cpp`` ``String2Timestamp``: the fraction is
  nanoseconds, padded to 9 digits).

Every error is a :class:`~airfisheye_bench.io.errors.DatasetFormatError` naming the file and the line.

Example:
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "timestamps.txt"
    >>> _ = path.write_text("2013-05-28 08:46:02.868368754\\n2013-05-28 08:46:02.972\\n")
    >>> t = read_timestamps(path)
    >>> round(float(t[1] - t[0]), 6)  # float64 seconds since 1970: ~0.2 us resolution
    0.103631
"""

from __future__ import annotations

import datetime as dt
import re
from pathlib import Path

import numpy as np

from airfisheye_bench.geometry.transforms import check_rigid
from airfisheye_bench.io.errors import DatasetFormatError

#: The devkit's camera names in ``calib_cam_to_pose.txt`` (perspective 00, 01; fisheye 02, 03).
CAMERAS = ("image_00", "image_01", "image_02", "image_03")
_TIMESTAMP = re.compile(r"^(\d{4})-(\d{1,2})-(\d{1,2})[ _tT](\d{1,2}):(\d{1,2}):(\d{1,2})(?:\.(\d{1,9}))?$")


def _lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise DatasetFormatError(path, "no such file (see docs/design.md, KITTI-360)") from None
    except (OSError, UnicodeDecodeError) as err:
        raise DatasetFormatError(path, f"cannot read it ({err})") from None


def _numbers(path: Path, words: list[str], count: int, where: str) -> np.ndarray:
    if len(words) != count:
        raise DatasetFormatError(path, f"expected {count} numbers, got {len(words)}", key=where)
    try:
        values = np.array([float(w) for w in words], np.float64)
    except ValueError:
        raise DatasetFormatError(path, "a value is not a number", key=where) from None
    if not np.isfinite(values).all():
        raise DatasetFormatError(path, "a value is not finite", key=where)
    return values


def _rigid(path: Path, values: np.ndarray, where: str) -> np.ndarray:
    T = np.vstack([values.reshape(3, 4), [0.0, 0.0, 0.0, 1.0]])
    try:
        check_rigid(T, where)
    except ValueError as err:
        raise DatasetFormatError(path, str(err), key=where) from None
    return T


def read_cam_to_pose(path: str | Path) -> dict[str, np.ndarray]:
    """``calib_cam_to_pose.txt``: ``{image_0X: T_pose_camX [4, 4]}`` for the four cameras."""
    path = Path(path)
    found: dict[str, np.ndarray] = {}
    for number, line in enumerate(_lines(path), start=1):
        name, sep, rest = line.partition(":")
        if sep and name.strip() in CAMERAS and name.strip() not in found:  # the devkit takes the first
            found[name.strip()] = _rigid(
                path, _numbers(path, rest.split(), 12, f"line {number}"), name.strip()
            )
    missing = [c for c in CAMERAS if c not in found]
    if missing:
        raise DatasetFormatError(
            path, f"no line for {', '.join(missing)} (expected 'image_0X: <12 numbers>')"
        )
    return found


def read_rigid(path: str | Path) -> np.ndarray:
    """A 3x4 transform of 12 numbers (``calib_cam_to_velo.txt``), as ``[4, 4]``."""
    path = Path(path)
    words = " ".join(_lines(path)).split()
    return _rigid(path, _numbers(path, words, 12, "values"), "transform")


def read_poses(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``poses.txt``: ``(frames int64 [N], T_world_pose [N, 4, 4])`` in file order (frames increasing)."""
    path = Path(path)
    frames: list[int] = []
    poses: list[np.ndarray] = []
    for number, line in enumerate(_lines(path), start=1):
        words = line.split()
        if not words:
            continue
        values = _numbers(path, words, 13, f"line {number}")
        if values[0] != int(values[0]) or values[0] < 0:
            raise DatasetFormatError(path, f"frame {words[0]!r} is not a frame number", key=f"line {number}")
        if frames and int(values[0]) <= frames[-1]:
            raise DatasetFormatError(path, "frame numbers must increase", key=f"line {number}")
        frames.append(int(values[0]))
        poses.append(_rigid(path, values[1:], f"line {number}"))
    if not frames:
        raise DatasetFormatError(path, "no poses")
    return np.asarray(frames, np.int64), np.stack(poses)


def read_timestamps(path: str | Path) -> np.ndarray:
    """``timestamps.txt``: ``float64 [N]`` seconds (UTC, as the devkit reads them), line ``k`` for frame ``k``."""
    path = Path(path)
    out = []
    for number, line in enumerate(_lines(path), start=1):
        match = _TIMESTAMP.match(line.strip())
        if match is None:
            raise DatasetFormatError(
                path, f"{line.strip()!r} is not 'YYYY-MM-DD HH:MM:SS.nnnnnnnnn'", key=f"line {number}"
            )
        *date, frac = match.groups()
        try:
            whole = dt.datetime(*map(int, date), tzinfo=dt.timezone.utc).timestamp()
        except ValueError as err:
            raise DatasetFormatError(path, str(err), key=f"line {number}") from None
        out.append(whole + (int(frac.ljust(9, "0")) * 1e-9 if frac else 0.0))
    return np.asarray(out, np.float64)


__all__ = ["CAMERAS", "read_cam_to_pose", "read_poses", "read_rigid", "read_timestamps"]
