"""OpenCV FileStorage calibrations (YAML ``%YAML:1.0`` with ``!!opencv-matrix``, or JSON with
``"type_id": "opencv-matrix"``), as OpenCV's calibration samples write them.

Layout (``samples/cpp/tutorial_code/calib3d/camera_calibration/camera_calibration.cpp``, ``saveCameraParams``;
``samples/cpp/calibration.cpp`` writes the same keys without ``fisheye_model``): ``image_width``, ``image_height``,
``camera_matrix`` (3x3 K), ``distortion_coefficients`` (a 1xN or Nx1 matrix), ``fisheye_model`` (0 or 1). Scripts'
spellings are read too (:data:`MATRIX_KEYS`, :data:`DISTORTION_KEYS`; the size as ``imageSize`` / ``image_size``
``[width, height]``, or ``width`` and ``height``), their matrices also as plain lists (nested, or flat row-major);
without an image size the file is refused naming the key.

- ``fisheye_model: 1``, or no ``fisheye_model`` and 4 coefficients: ``cv::fisheye`` (``kannala_brandt``, k1..k4;
  K[0, 1] = alpha * fx, alpha being ``cv::fisheye``'s skew).
- otherwise ``cv::calibrateCamera``'s order k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4[, tauX, tauY]]]]:
  ``pinhole_radtan`` (4, 5 or 8 coefficients, 8 being ``CALIB_RATIONAL_MODEL``'s; of 12 or 14 the thin-prism
  and tilt terms must be zero).

Pixel convention: OpenCV's (pixel centre at integer coordinates), the project's: nothing to convert.

Example:
    >>> from airfisheye_bench.io.calibration_files._fields import parse_structured
    >>> doc = parse_structured('''%YAML:1.0
    ... ---
    ... image_width: 640
    ... image_height: 480
    ... camera_matrix: !!opencv-matrix
    ...    rows: 3
    ...    cols: 3
    ...    dt: d
    ...    data: [ 300., 0., 319.5, 0., 301., 239.5, 0., 0., 1. ]
    ... distortion_coefficients: !!opencv-matrix
    ...    rows: 4
    ...    cols: 1
    ...    dt: d
    ...    data: [ 0.01, -0.002, 1e-05, 0. ]
    ... ''')
    >>> camera, _ = FORMAT.cameras(Fields("c.yaml", doc))["0"](Fields("c.yaml", doc))
    >>> camera["model"], camera["k3"], camera["fy"]
    ('kannala_brandt', 1e-05, 301.0)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from airfisheye_bench.geometry.cameras import KannalaBrandt, PinholeRadtan
from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CameraEntry, Fields

__all__ = ["DISTORTION_KEYS", "FORMAT", "MATRIX_KEYS", "camera_from_matrices"]

_RADTAN_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tauX", "tauY")


def camera_from_matrices(
    fields: Fields,
    width: int,
    height: int,
    K: np.ndarray,
    D: list[float],
    fisheye: bool,
    k_key: str,
    d_key: str,
) -> dict[str, Any]:
    """The camera of a 3x3 ``K`` and coefficients ``D`` (OpenCV's meaning), shared with the ROS reader.

    Args:
        fields: The document (for errors).
        width, height: Image size in pixels.
        K: Camera matrix.
        D: Distortion coefficients.
        fisheye: ``cv::fisheye`` (4 coefficients, ``kannala_brandt``) rather than ``cv::calibrateCamera``'s model.
        k_key, d_key: The keys of ``K`` and ``D`` in the file (named in errors).
    """
    if not (K[0, 0] > 0 and K[1, 1] > 0) or K[1, 0] != 0 or list(K[2]) != [0.0, 0.0, 1.0]:
        raise fields.error(
            k_key, f"expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, got {K.tolist()}"
        )
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if fisheye:
        if len(D) != 4:
            raise fields.error(
                d_key, f"a fisheye (cv::fisheye) calibration has 4 coefficients k1..k4, got {len(D)}"
            )
        return KannalaBrandt.flat_dict(width, height, fx, fy, cx, cy, *D, skew=K[0, 1] / fx)
    if K[0, 1] != 0:
        raise fields.error(
            k_key, "a skewed camera matrix (K[0][1] != 0) is only supported for fisheye calibrations"
        )
    if len(D) not in (4, 5, 8, 12, 14):
        raise fields.error(
            d_key, f"expected 4, 5, 8, 12 or 14 coefficients (k1, k2, p1, p2[, k3, ...]), got {len(D)}"
        )
    extra = {name: v for name, v in zip(_RADTAN_NAMES[8:], D[8:], strict=False) if v != 0}
    if extra:
        raise fields.error(
            d_key,
            f"non-zero {', '.join(extra)}: the thin-prism and tilted models are not supported; supported: k1, k2, "
            "p1, p2, k3[, k4, k5, k6] (pinhole_radtan) or 4 fisheye coefficients (kannala_brandt)",
        )
    # k1, k2, p1, p2, k3, k4, k5, k6: the declaration's order is OpenCV's.
    return PinholeRadtan.flat_dict(width, height, fx, fy, cx, cy, *D[:8])


#: Spellings of the camera matrix and of the coefficients, OpenCV's samples' first: ``calibrateCamera``'s own
#: argument names (``cameraMatrix``, ``distCoeffs``, written by many scripts), ``K`` / ``D`` (``cv::fisheye`` scripts),
#: and the Python tutorial's ``mtx`` / ``dist``.
MATRIX_KEYS = ("camera_matrix", "cameraMatrix", "K", "mtx")
DISTORTION_KEYS = ("distortion_coefficients", "distCoeffs", "dist_coeffs", "D", "dist")
#: Image size keys: a ``[width, height]`` pair (``cv::Size`` as FileStorage writes it), else separate width / height.
SIZE_KEYS = ("imageSize", "image_size")
WIDTH_HEIGHT_KEYS = (("image_width", "image_height"), ("width", "height"))


def _keys(doc: Any) -> tuple[str, str] | None:
    """The (matrix, coefficients) keys of a document, ``None`` when it has no such pair."""
    if not isinstance(doc, dict):
        return None
    k_key = next((k for k in MATRIX_KEYS if k in doc), None)
    d_key = next((d for d in DISTORTION_KEYS if d in doc), None)
    return (k_key, d_key) if k_key and d_key else None


def _detect(text: str, doc: Any) -> bool:
    return _keys(doc) is not None


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    return {"0": _read}


def _matrix(f: Fields, key: str, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """An ``!!opencv-matrix`` (or its JSON form), or plain nested / flat lists as scripts write them."""
    value = f.get(key)
    if isinstance(value, dict):
        return f.opencv_matrix(key, shape)
    if isinstance(value, list) and value and all(isinstance(row, list) for row in value):
        rows = [f.check_numbers(key, row) for row in value]
        if len({len(row) for row in rows}) != 1:
            raise f.error(key, "expected a matrix: rows of one length")
        matrix = np.asarray(rows, np.float64)
    else:
        matrix = np.asarray(f.check_numbers(key, value), np.float64)[None]
    if shape is not None and matrix.shape != shape:
        if matrix.size != shape[0] * shape[1]:
            raise f.error(
                key, f"expected a {shape[0]}x{shape[1]} matrix, got {matrix.shape[0]}x{matrix.shape[1]}"
            )
        matrix = matrix.reshape(shape)  # a flat list, row-major
    return matrix


def _size(f: Fields) -> tuple[int, int]:
    for key in SIZE_KEYS:
        if key in f.data:
            return f.size(key)
    for w_key, h_key in WIDTH_HEIGHT_KEYS:
        if w_key in f.data or h_key in f.data:
            return f.whole(w_key), f.whole(h_key)
    raise f.error(
        "image_width",
        "is missing: the image size is needed (image_width and image_height, or image_size: [width, height])",
    )


def _read(f: Fields) -> tuple[dict[str, Any], dict]:
    k_key, d_key = _keys(f.data)
    width, height = _size(f)
    K = _matrix(f, k_key, (3, 3))
    D = _matrix(f, d_key)
    if 1 not in D.shape:
        raise f.error(d_key, f"expected a 1xN or Nx1 matrix, got {D.shape[0]}x{D.shape[1]}")
    coefficients = D.reshape(-1).tolist()
    flag = f.get("fisheye_model", None)
    if flag is not None and flag not in (0, 1):  # True and False compare equal to 1 and 0
        raise f.error("fisheye_model", f"expected 0 or 1, got {flag!r}")
    fisheye = bool(flag) if flag is not None else len(coefficients) == 4
    return camera_from_matrices(f, width, height, K, coefficients, fisheye, k_key, d_key), {}


FORMAT = CalibrationFormat(
    name="opencv",
    summary="OpenCV FileStorage YAML/JSON (camera_matrix | cameraMatrix | K | mtx, distortion_coefficients | "
    "distCoeffs | dist_coeffs | D | dist, image_width + image_height | imageSize | image_size | width + height; "
    "4 coefficients or fisheye_model: 1 = kannala_brandt, 5 or 8 (rational) = pinhole_radtan)",
    source="OpenCV samples/cpp/calibration.cpp and tutorial_code/calib3d/camera_calibration/camera_calibration.cpp "
    "(saveCameraParams); cv::fisheye and cv::calibrateCamera docs for the coefficient order",
    detect=_detect,
    cameras=_cameras,
)
