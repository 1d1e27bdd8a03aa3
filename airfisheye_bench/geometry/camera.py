"""``incidence_angle``, and ``FisheyeCamera``, the deprecated name of
:func:`~airfisheye_bench.geometry.cameras.ideal_camera`.

``FisheyeCamera`` was once the camera class; since the camera models got their package (``geometry/cameras/``) it
only built a :class:`~airfisheye_bench.geometry.cameras.CameraModel`. It stays, a function that warns
(``DeprecationWarning``) and calls ``ideal_camera`` with the same arguments, so that code, notebooks and configs
written against it keep working; ``FisheyeCamera.from_dict`` is ``camera_from_dict``. Annotate cameras as
``CameraModel``, build the ideal lenses with ``ideal_camera`` and any model with ``camera_from_dict``.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import torch

from airfisheye_bench.geometry._arrays import ArrayLike, as_tensor, back, check_last_dim
from airfisheye_bench.geometry.cameras import CameraModel, camera_from_dict
from airfisheye_bench.geometry.cameras.ideal import LENS_MODELS, ideal_camera


def FisheyeCamera(  # the historical class name
    width: int,
    height: int,
    fov_deg: float = 190.0,
    model: str = "equidistant",
    cx: float | None = None,
    cy: float | None = None,
    focal: float | None = None,
    k: Sequence[float] | None = None,
) -> CameraModel:
    """Deprecated: :func:`~airfisheye_bench.geometry.cameras.ideal_camera`, which takes the same arguments.

    Example:
        >>> import warnings
        >>> with warnings.catch_warnings():
        ...     warnings.simplefilter("ignore", DeprecationWarning)
        ...     cam = FisheyeCamera(512, 512, fov_deg=190.0)
        >>> cam == ideal_camera(512, 512, fov_deg=190.0), type(cam).__name__
        (True, 'Equidistant')
    """
    warnings.warn(
        "FisheyeCamera is deprecated: build the lens with airfisheye_bench.geometry.ideal_camera (same arguments) "
        "and annotate cameras as CameraModel",
        DeprecationWarning,
        stacklevel=2,
    )
    return ideal_camera(width, height, fov_deg, model, cx, cy, focal, k)


FisheyeCamera.from_dict = camera_from_dict  # type: ignore[attr-defined]


def incidence_angle(points: ArrayLike) -> ArrayLike:
    """Angle (radians) between camera-frame points ``[..., 3]`` and the optical axis."""
    p, was_numpy = as_tensor(points, "points")
    check_last_dim(p, 3, "points")
    return back(torch.atan2(torch.hypot(p[..., 0], p[..., 1]), p[..., 2]), was_numpy)


__all__ = ["LENS_MODELS", "FisheyeCamera", "incidence_angle"]
