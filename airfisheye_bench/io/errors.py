"""The error types raised for malformed dataset files."""

from __future__ import annotations

from pathlib import Path

from airfisheye_bench.errors import UserError


class DatasetFormatError(UserError, ValueError):
    """A dataset file is missing, unreadable or does not follow the layout.

    The message always names the file and, where it applies, the offending key (``classes.raw[3].color``) or
    line, so a user can fix a hand-written ``dataset.yaml`` or a broken download without reading code.

    Attributes:
        path: The offending file.
        key: Dotted key or ``line N`` inside the file, or ``None``.
        message: What is wrong, without the location.

    Example:
        >>> err = DatasetFormatError("/data/dataset.yaml", "must be a mapping", key="splits")
        >>> str(err)
        "/data/dataset.yaml: key 'splits': must be a mapping"
    """

    def __init__(self, path: str | Path, message: str, key: str | None = None) -> None:
        self.path = Path(path)
        self.key = key
        self.message = message
        where = f"{self.path}: key '{key}': " if key is not None else f"{self.path}: "
        super().__init__(where + message)

    def __reduce__(self):
        # Pickle by the constructor's arguments (the default re-calls __init__ with the formatted message only),
        # so the error crosses process boundaries intact (worker pools, DataLoader workers).
        return type(self), (self.path, self.message, self.key)


class CalibrationFileError(DatasetFormatError):
    """A calibration file (OpenCV, ROS, Kalibr, basalt, COLMAP, KITTI-360, WoodScape, OCamCalib or the project's own)
    cannot be read as a camera: an unknown layout, an unsupported lens model, a missing key or a wrong value.

    The message names the file, the key (dotted, ``cam1.distortion_model``) and what is supported.

    Example:
        >>> err = CalibrationFileError("camchain.yaml", "ds + radtan is not supported; supported: ds + none",
        ...                            key="cam0.distortion_model")
        >>> isinstance(err, ValueError), str(err)
        (True, "camchain.yaml: key 'cam0.distortion_model': ds + radtan is not supported; supported: ds + none")
    """


class EmptySplitError(DatasetFormatError):
    """A split of a dataset holds no sample; the message names the root, the split and the samples it takes.

    Example:
        >>> err = EmptySplitError("/data/ws", "split 'val' is empty: expected images of the devkit's list")
        >>> isinstance(err, ValueError), str(err)
        (True, "/data/ws: split 'val' is empty: expected images of the devkit's list")
    """
