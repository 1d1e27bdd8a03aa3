"""``FisheyeCamera``: the constructor of the ideal fisheye lenses and the single-focal Kannala-Brandt model.

Kept for the call sites written before the camera models got their package (``geometry/cameras/``): it returns a
:class:`~airfisheye_bench.geometry.cameras.CameraModel` of the named model. ``FisheyeCamera.from_dict`` is
``camera_from_dict``, which reads every model (and the old ``{focal, k}`` Kannala-Brandt form).

Conventions (docs/design.md): camera frame x right, y down, z forward; the centre of pixel (row i, col j) is at
``(u=j, v=i)``; the default principal point is the image centre ``((W-1)/2, (H-1)/2)``; unless ``focal`` is given
it is chosen so that the image circle (``theta = FOV/2``) is inscribed in the image: ``r_max = min(W, H) / 2``.
"""

from __future__ import annotations

from typing import Any

import torch

from airfisheye_bench.geometry._arrays import ArrayLike, as_tensor, back, check_last_dim
from airfisheye_bench.geometry.cameras import CameraModel, KannalaBrandt, camera_from_dict
from airfisheye_bench.geometry.cameras.radial import RADIAL_MODELS

#: The lens models :func:`FisheyeCamera` builds (``data.camera.model``).
LENS_MODELS = ("equidistant", "equisolid", "stereographic", "orthographic", "kannala_brandt")


def FisheyeCamera(  # the historical class name; it now builds a CameraModel
    width: int,
    height: int,
    fov_deg: float = 190.0,
    model: str = "equidistant",
    cx: float | None = None,
    cy: float | None = None,
    focal: float | None = None,
    k: tuple[float, float, float, float] | list[float] | None = None,
) -> CameraModel:
    """A central fisheye camera with a radially symmetric lens model.

    Args:
        width: Image width in pixels.
        height: Image height in pixels.
        fov_deg: Full field of view in degrees; pixels with ``theta > fov_deg / 2`` are outside the image circle.
        model: One of ``equidistant`` (default), ``equisolid``, ``stereographic``, ``orthographic``,
            ``kannala_brandt``.
        cx: Principal point column; default ``(width - 1) / 2``.
        cy: Principal point row; default ``(height - 1) / 2``.
        focal: Focal length in pixels; default inscribes the image circle in the image.
        k: Kannala-Brandt coefficients ``(k1, k2, k3, k4)``; only for ``kannala_brandt``.

    Example:
        >>> import numpy as np
        >>> cam = FisheyeCamera(512, 512)  # 190 deg equidistant, image circle inscribed
        >>> uv, valid = cam.project(np.array([[0.0, 0.0, 5.0], [1.0, 0.0, -0.05]]))
        >>> uv[0].round(3).tolist(), valid.tolist()
        ([255.5, 255.5], [True, True])
        >>> np.allclose(cam.unproject(uv[:1]), [[0.0, 0.0, 1.0]])
        True
    """
    if model not in LENS_MODELS:
        raise ValueError(f"model must be one of {LENS_MODELS}, got {model!r}")
    if model == "kannala_brandt":
        return KannalaBrandt.from_focal(width, height, fov_deg, cx, cy, focal, k)
    if k is not None and any(float(x) != 0.0 for x in k):
        raise ValueError(
            f"k (distortion coefficients) is only used by the kannala_brandt model, not {model!r}"
        )
    return RADIAL_MODELS[model](width, height, fov_deg, cx, cy, focal)


def _from_dict(d: dict[str, Any]) -> CameraModel:
    return camera_from_dict(d)


FisheyeCamera.from_dict = _from_dict  # type: ignore[attr-defined]


def incidence_angle(points: ArrayLike) -> ArrayLike:
    """Angle (radians) between camera-frame points ``[..., 3]`` and the optical axis."""
    p, was_numpy = as_tensor(points, "points")
    check_last_dim(p, 3, "points")
    return back(torch.atan2(torch.hypot(p[..., 0], p[..., 1]), p[..., 2]), was_numpy)


__all__ = ["LENS_MODELS", "FisheyeCamera", "incidence_angle"]
