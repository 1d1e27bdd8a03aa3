"""What every calibration reader shares: the parsed document, typed field access whose errors name the file and the
key, the OpenCV-flavoured YAML loader, and the choice of one camera among several.

Example:
    >>> f = Fields("camchain.yaml", {"cam0": {"intrinsics": [1.0, 2.0], "resolution": [640, 480.0]}})
    >>> f.numbers("cam0.intrinsics", 2), f.size("cam0.resolution")
    ([1.0, 2.0], (640, 480))
    >>> f.numbers("cam0.intrinsics", 4)
    Traceback (most recent call last):
    ...
    airfisheye_bench.io.errors.CalibrationFileError: camchain.yaml: key 'cam0.intrinsics': expected 4 numbers, got 2
"""

from __future__ import annotations

import json
import logging
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from airfisheye_bench.io.errors import CalibrationFileError
from airfisheye_bench.io.yamlio import FieldReader

__all__ = [
    "CalibrationFormat",
    "CalibrationRecord",
    "CameraEntry",
    "Fields",
    "parse_structured",
    "quaternion_pose",
    "rigid_both_ways",
    "select_camera",
    "syntax_error",
]

log = logging.getLogger(__name__)

_MISSING = object()
_INDEX = re.compile(r"^(\w[\w\-]*)\[(\d+)\]$")


@dataclass(frozen=True)
class CalibrationRecord:
    """One camera read from a calibration file.

    Attributes:
        path: The file.
        format: The format's name in :data:`~airfisheye_bench.io.calibration_files.FORMATS` (``kalibr``, ...).
        name: The camera's name in the file (``cam0``, a COLMAP camera id, ``image_02``, ``FV``; ``"0"`` when the
            file names none).
        camera: The camera as the flat dict of the camera contract (``{"model": ..., "width": ..., "height": ...,
            <params>}``), in the project's pixel convention (the centre of pixel (row i, col j) at (u=j, v=i)).
        extrinsics: Rigid transforms the file gives for this camera, ``[4, 4]`` float64 by name (``T_a_b`` maps
            points of frame b to frame a): ``T_vehicle_cam`` (WoodScape); ``T_cam_imu`` and ``T_imu_cam`` (Kalibr,
            basalt), ``T_cn_cnm1`` and ``T_cnm1_cn`` (Kalibr): both directions, whichever one the file stores (the
            other is its inverse; which was read is logged).
    """

    path: Path
    format: str
    name: str
    camera: dict[str, Any]
    extrinsics: dict[str, np.ndarray] = field(default_factory=dict)


#: A camera of a file, built on demand: only the chosen camera's keys are checked.
CameraEntry = Callable[["Fields"], tuple[dict[str, Any], dict[str, np.ndarray]]]


@dataclass(frozen=True)
class CalibrationFormat:
    """One file format: how it is recognised from its contents and how its cameras are read.

    Attributes:
        name: Short name (``kalibr``), reported in :class:`CalibrationRecord` and in errors.
        summary: What writes it and the lens models it takes (for docs and for the unknown-format message).
        source: Where its layout and pixel convention were checked (code or documentation of the tool).
        detect: ``(text, document) -> bool``: whether a file is in this format (``document`` is the parsed JSON or
            YAML, ``None`` when the text is neither).
        cameras: ``Fields -> {name: CameraEntry}`` in file order; an entry is only built when chosen.
        document: ``(text, document) -> document`` for text formats: the text's values as a mapping, so that
            errors name a key (default: the parsed document).
    """

    name: str
    summary: str
    source: str
    detect: Callable[[str, Any], bool]
    cameras: Callable[[Fields], dict[str, CameraEntry]]
    document: Callable[[str, Any], Any] | None = None


class Fields(FieldReader):
    """Typed access to a parsed calibration document; every error is a
    :class:`~airfisheye_bench.io.errors.CalibrationFileError` naming the file and the dotted key.

    Keys may index lists: ``value0.intrinsics[1].camera_type``.
    """

    def error(self, key: str, message: str) -> CalibrationFileError:
        return CalibrationFileError(self.path, message, key=key)

    def get(self, key: str, default: Any = _MISSING) -> Any:
        node: Any = self.data
        for part in key.split("."):
            match = _INDEX.match(part)
            name, index = (match.group(1), int(match.group(2))) if match else (part, None)
            if not isinstance(node, Mapping) or name not in node:
                if default is not _MISSING:
                    return default
                raise self.error(key, "is missing")
            node = node[name]
            if index is not None:
                if not isinstance(node, list) or index >= len(node):
                    if default is not _MISSING:
                        return default
                    raise self.error(key, f"is missing (the list {name} has {_length(node)} entries)")
                node = node[index]
        return node

    def number(self, key: str, default: Any = _MISSING, positive: bool = False) -> float:
        """A finite number (``positive``: > 0)."""
        return self.float(key, default, positive=positive)

    def numbers(self, key: str, count: int | tuple[int, ...] | None = None) -> list[float]:
        """A list of finite numbers, of ``count`` entries (one of them when a tuple) if given."""
        value = self.get(key)
        return self.check_numbers(key, value, count)

    def check_numbers(self, key: str, value: Any, count: int | tuple[int, ...] | None = None) -> list[float]:
        if not isinstance(value, list) or not all(_is_number(v) for v in value):
            raise self.error(key, f"expected a list of finite numbers, got {_short(value)}")
        counts = (count,) if isinstance(count, int) else count
        if counts is not None and len(value) not in counts:
            wanted = " or ".join(str(c) for c in counts)
            raise self.error(key, f"expected {wanted} numbers, got {len(value)}")
        return [float(v) for v in value]

    def whole(self, key: str, value: Any = _MISSING, minimum: int = 1) -> int:
        """An integer >= ``minimum``; a float with an integral value counts (WoodScape writes ``1280.0``)."""
        value = self.get(key) if value is _MISSING else value
        if _is_number(value) and float(value).is_integer() and value >= minimum:
            return int(value)
        raise self.error(key, f"expected an integer >= {minimum}, got {_short(value)}")

    def size(self, key: str) -> tuple[int, int]:
        """``[width, height]`` in pixels."""
        value = self.get(key)
        if not isinstance(value, list) or len(value) != 2:
            raise self.error(key, f"expected [width, height], got {_short(value)}")
        return self.whole(key, value[0]), self.whole(key, value[1])

    def opencv_matrix(self, key: str, shape: tuple[int, ...] | None = None) -> np.ndarray:
        """A matrix written as ``{rows, cols, data}`` (OpenCV ``!!opencv-matrix``, its JSON form, or ROS's)."""
        node = self.mapping(key)
        rows = self.whole(f"{key}.rows", minimum=0)
        cols = self.whole(f"{key}.cols", minimum=0)
        data = self.check_numbers(f"{key}.data", node.get("data"), rows * cols)
        matrix = np.asarray(data, np.float64).reshape(rows, cols)
        if shape is not None and matrix.shape != shape:
            raise self.error(key, f"expected a {shape[0]}x{shape[1]} matrix, got {rows}x{cols}")
        return matrix


def parse_structured(text: str) -> Any:
    """The document of a JSON or YAML file (OpenCV FileStorage YAML included), or ``None`` if it is neither."""
    return _parse(text)[0]


def syntax_error(text: str) -> str | None:
    """Why ``text`` is neither JSON nor YAML, with the parser's line and column in the file; ``None`` if it parses.

    A text that starts with ``{`` is reported as JSON, anything else as YAML.

    Example:
        >>> syntax_error("cam0: {intrinsics: [1, 2}")
        "invalid YAML at line 1, column 25: expected ',' or ']', but got '}'"
        >>> syntax_error('{"value0": [1, 2}')
        "invalid JSON at line 1, column 17: Expecting ',' delimiter"
        >>> syntax_error("cam0: {}") is None
        True
    """
    return _parse(text)[1]


def _parse(text: str) -> tuple[Any, str | None]:
    """``(document, None)``, or ``(None, what the parser refused and where)``."""
    json_error = None
    if text.lstrip().startswith("{"):
        try:
            return json.loads(text), None
        except json.JSONDecodeError as err:
            json_error = f"invalid JSON at line {err.lineno}, column {err.colno}: {err.msg}"
    try:
        # A topic echo (`rostopic echo -n 1 /camera_info`) ends its messages with `---`: several YAML documents,
        # of which the first is read. _OpenCVLoader is a SafeLoader subclass.
        documents = yaml.load_all(_opencv_yaml_text(text), Loader=_OpenCVLoader)
        return next((d for d in documents if d is not None), None), None
    except yaml.YAMLError as err:
        return None, json_error or _yaml_error(err, dropped=int(text.startswith("%YAML:")))


def _yaml_error(err: yaml.YAMLError, dropped: int) -> str:
    """PyYAML's problem and where, as one line; ``dropped``: lines :func:`_opencv_yaml_text` left out before it."""
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    mark = getattr(err, "problem_mark", None)
    where = f" at line {mark.line + 1 + dropped}, column {mark.column + 1}" if mark is not None else ""
    return f"invalid YAML{where}: {problem}"


class _OpenCVLoader(yaml.SafeLoader):
    """PyYAML's safe loader that also reads what OpenCV's FileStorage writes (``!!opencv-matrix`` mappings) and
    exponent-only floats (``1e-05``) as numbers, which YAML 1.1 would read as strings."""


_OpenCVLoader.add_constructor(
    "tag:yaml.org,2002:opencv-matrix", lambda loader, node: loader.construct_mapping(node, deep=True)
)
_OpenCVLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)[eE][-+]?\d+$"), list("-+0123456789.")
)


def _opencv_yaml_text(text: str) -> str:
    # OpenCV writes the directive `%YAML:1.0`, which no YAML parser accepts; the KITTI-360 devkit
    # (kitti360scripts/helpers/project.py, readYAMLFile) drops that line and puts a space after a `key:` that lacks
    # one. The same here, the space only after a key at the start of a line.
    lines = text.splitlines()
    if lines and lines[0].startswith("%YAML:"):
        lines = lines[1:]
    return "\n".join(re.sub(r"^(\s*[A-Za-z_][\w\-]*):(?=[^\s:/])", r"\1: ", line) for line in lines) + "\n"


def select_camera(
    path: Path, cameras: Mapping[str, CameraEntry], camera: str | int | None, option: str = "camera"
) -> str:
    """The name of the camera to read: the only one, or the one ``camera`` names (by name, else by 0-based index).

    ``option`` is how the caller's user spells the choice (``data.camera.camera`` in a training config).

    Raises:
        CalibrationFileError: several cameras and no ``camera``, or a ``camera`` the file does not hold; the
            message lists the names.
    """
    names = list(cameras)
    listed = ", ".join(names)
    if not names:
        raise CalibrationFileError(path, "holds no camera")
    if camera is None:
        if len(names) == 1:
            return names[0]
        raise CalibrationFileError(
            path,
            f"holds {len(names)} cameras ({listed}); choose one with {option}=<name or 0-based index>",
            key="camera",
        )
    text = str(camera).strip()
    if text in cameras:
        return text
    numeric_names = all(n.lstrip("-").isdigit() for n in names)
    if text.isdigit() and not numeric_names and int(text) < len(names):
        return names[int(text)]
    raise CalibrationFileError(
        path,
        f"camera={camera!r} is not in the file; it holds {listed} (a name or a 0-based index)",
        key="camera",
    )


def quaternion_pose(qxyzw: list[float], translation: list[float]) -> np.ndarray:
    """``[4, 4]`` rigid transform from a unit quaternion ``(x, y, z, w)`` (Hamilton, scalar last: Eigen's and
    scipy's ``from_quat`` order) and a translation.

    Example:
        >>> quaternion_pose([0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)], [1.0, 2.0, 3.0]).round(6)[0] + 0.0
        array([ 0., -1.,  0.,  1.])
    """
    x, y, z, w = (float(v) for v in qxyzw)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    pose = np.eye(4)
    pose[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    pose[:3, 3] = [float(v) for v in translation]
    return pose


def rigid_both_ways(f: Fields, key: str, T: np.ndarray, a: str, b: str) -> dict[str, np.ndarray]:
    """``{"T_a_b": T, "T_b_a": T^-1}`` from the file's ``T_a_b`` at ``key``, so that a reader finds either direction
    whichever one the file stores; logs which was read. ``T`` must be rigid (its inverse uses ``R^T``)."""
    R = T[:3, :3]
    rigid = np.allclose(R.T @ R, np.eye(3), atol=1e-4) and abs(np.linalg.det(R) - 1.0) < 1e-4
    if not rigid or not np.array_equal(T[3], [0.0, 0.0, 0.0, 1.0]):
        raise f.error(key, "expected a rigid 4x4 transform [[R, t], [0, 0, 0, 1]] with R a rotation")
    inverse = np.eye(4)
    inverse[:3, :3] = R.T
    inverse[:3, 3] = -R.T @ T[:3, 3]
    log.info("%s: extrinsics T_%s_%s read from key %r; T_%s_%s is its inverse", f.path, a, b, key, b, a)
    return {f"T_{a}_{b}": T, f"T_{b}_{a}": inverse}


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _length(node: Any) -> int:
    return len(node) if isinstance(node, list) else 0


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
