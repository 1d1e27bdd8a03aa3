"""``ideal_camera``: the ideal fisheye lenses, the single-focal Kannala-Brandt lens and the ideal pinhole by the
config's spelling (``data.camera``: ``model``, ``fov_deg``, ``k``), with the image circle inscribed unless ``focal``
is given (the pinhole's ``fov_deg`` is its field of view across the width instead: it has no image circle).

Conventions (docs/design.md): the default principal point is the image centre ``((W-1)/2, (H-1)/2)``; unless
``focal`` is given it is chosen so that the image circle (``theta = fov_deg / 2``) is inscribed in the image:
``r_max = min(W, H) / 2``.

Cameras are annotated as :class:`CameraModel`; the ideal lenses are built with ``ideal_camera``, any model with
``camera_from_dict`` (``FisheyeCamera``, the class these replaced, is gone: ``ideal_camera`` takes its arguments).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.kannala_brandt import KannalaBrandt
from airfisheye_bench.geometry.cameras.radial import RADIAL_MODELS, Pinhole

#: The lens models :func:`ideal_camera` builds (``data.camera.model``).
LENS_MODELS = (*RADIAL_MODELS, KannalaBrandt.model, Pinhole.model)


def ideal_camera(
    width: int,
    height: int,
    fov_deg: float = 190.0,
    model: str = "equidistant",
    cx: float | None = None,
    cy: float | None = None,
    focal: float | None = None,
    k: Sequence[float] | None = None,
) -> CameraModel:
    """A central fisheye camera with a radially symmetric lens model.

    Args:
        width: Image width in pixels.
        height: Image height in pixels.
        fov_deg: Full field of view in degrees; pixels with ``theta > fov_deg / 2`` are outside the image circle.
            ``pinhole``: the field of view across the width (below 180), the whole frame valid.
        model: One of :data:`LENS_MODELS`: ``equidistant`` (default), ``equisolid``, ``stereographic``,
            ``orthographic``, ``kannala_brandt``, ``pinhole``.
        cx: Principal point column; default ``(width - 1) / 2``.
        cy: Principal point row; default ``(height - 1) / 2``.
        focal: Focal length in pixels; default inscribes the image circle in the image (``pinhole``: given, it
            sets ``fov_deg``, ``2 atan(W / (2 focal))``).
        k: Kannala-Brandt coefficients ``(k1, k2, k3, k4)``; only for ``kannala_brandt``.

    Example:
        >>> import numpy as np
        >>> cam = ideal_camera(512, 512)  # 190 deg equidistant, image circle inscribed
        >>> uv, valid = cam.project(np.array([[0.0, 0.0, 5.0], [1.0, 0.0, -0.05]]))
        >>> uv[0].round(3).tolist(), valid.tolist()
        ([255.5, 255.5], [True, True])
        >>> np.allclose(cam.unproject(uv[:1]), [[0.0, 0.0, 1.0]])
        True
        >>> ideal_camera(512, 512, model="kannala_brandt", k=(0.01, 0.0, 0.0, 0.0)).model
        'kannala_brandt'
        >>> ideal_camera(512, 512, fov_deg=90.0, model="pinhole").focal  # a cube face
        256.00000000000006
    """
    if model not in LENS_MODELS:
        raise ValueError(f"model must be one of {LENS_MODELS}, got {model!r}")
    if model == KannalaBrandt.model:
        return KannalaBrandt.from_focal(width, height, fov_deg, cx, cy, focal, k)
    if k is not None and any(float(x) != 0.0 for x in k):
        raise ValueError(
            f"k (distortion coefficients) is only used by the kannala_brandt model, not {model!r}"
        )
    if model == Pinhole.model:
        if focal is not None:
            fov_deg = math.degrees(2.0 * math.atan(width / (2.0 * float(focal))))
        return Pinhole(width, height, fov_deg, cx, cy)
    return RADIAL_MODELS[model](width, height, fov_deg, cx, cy, focal)


__all__ = ["LENS_MODELS", "ideal_camera"]
