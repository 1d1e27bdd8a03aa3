"""The ideal radially symmetric lenses: ``r(theta)`` with one focal length, the fisheyes and the pinhole
(docs/design.md).

================  ==========================  =========================
model             r(theta)                    largest FOV it represents
================  ==========================  =========================
equidistant       f theta                     360 deg
equisolid         2 f sin(theta / 2)          360 deg
stereographic     2 f tan(theta / 2)          < 360 deg
orthographic      f sin(theta)                180 deg
pinhole           f tan(theta)                < 180 deg
================  ==========================  =========================

The default principal point is the image centre ``((W-1)/2, (H-1)/2)``; the default focal length of the fisheye
lenses inscribes the image circle (``theta = fov_deg / 2``) in the image: ``r_max = min(W, H) / 2``. The pinhole
(:class:`Pinhole`, the perspective lens of a model trained on ordinary images) has no image circle: its ``fov_deg``
is the field of view across the image's width, ``f = (W / 2) / tan(fov_deg / 2)``, and its whole frame is valid.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import torch

from airfisheye_bench.geometry.cameras.base import CameraModel, ray_at_incidence
from airfisheye_bench.geometry.cameras.params import (
    Param,
    field_of_view,
    interval,
    number,
    optional,
    positive,
)


class RadialCamera(CameraModel):
    """A central lens mapping the incidence angle ``theta`` to the image radius ``f r(theta)``.

    Args:
        width: Image width in pixels.
        height: Image height in pixels.
        fov_deg: Full field of view in degrees (the image circle).
        cx: Principal point column; default ``(width - 1) / 2``.
        cy: Principal point row; default ``(height - 1) / 2``.
        focal: Focal length in pixels; default inscribes the image circle in the image.

    Example:
        >>> import numpy as np
        >>> cam = Equidistant(512, 512)  # 190 deg, image circle inscribed
        >>> uv, valid = cam.project(np.array([[0.0, 0.0, 5.0], [1.0, 0.0, -0.05]]))
        >>> uv[0].round(3).tolist(), valid.tolist()
        ([255.5, 255.5], [True, True])
    """

    # fov_deg is the image circle here, never None; the others default from it and the image size (_setup).
    declaration = (
        Param("fov_deg", 190.0, check=field_of_view),
        Param("cx", None, check=optional(number), scale="cx"),
        Param("cy", None, check=optional(number), scale="cy"),
        Param("focal", None, check=optional(positive), scale="fx"),
    )
    #: Largest half-FOV the model represents (radians) and whether it is excluded.
    max_model_theta: ClassVar[float] = math.pi
    open_limit: ClassVar[bool] = False

    fov_deg: float

    def _setup(self) -> None:
        limit = math.degrees(2 * self.max_model_theta)
        if self.fov_deg > limit or (self.open_limit and self.fov_deg >= limit):
            raise ValueError(
                f"fov_deg={self.fov_deg} cannot be represented by the {self.model} model (maximum {limit:g} deg"
                f"{', exclusive' if self.open_limit else ''})"
            )
        if self.cx is None:
            self.cx = (self.width - 1) / 2.0
        if self.cy is None:
            self.cy = (self.height - 1) / 2.0
        if self.focal is None:
            self.focal = (min(self.width, self.height) / 2.0) / self.radius(self.max_theta)

    # r(theta) / f and its inverse, for floats and float64 tensors
    @staticmethod
    def radius(theta: Any) -> Any:
        raise NotImplementedError

    @staticmethod
    def _theta_of(rho: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError

    def _project(self, x, y, z):
        rho_xy = torch.hypot(x, y)
        theta = torch.atan2(rho_xy, z)
        r = self.focal * self.radius(theta)
        # rho_xy is 0 only on the optical axis, where x = y = 0: the clamped division maps it to the centre.
        rho_c = rho_xy.clamp_min(1e-300)
        in_region = theta < self.max_model_theta if self.open_limit else theta <= self.max_model_theta + 1e-12
        return self.cx + r * (x / rho_c), self.cy + r * (y / rho_c), in_region

    def _unproject(self, u, v):
        dx, dy = u - self.cx, v - self.cy
        r = torch.hypot(dx, dy)
        theta = self._theta_of(r / self.focal)
        theta = torch.where(theta <= self.max_model_theta, theta, torch.nan)  # past pi a radius wraps round
        return ray_at_incidence(theta, dx, dy, r)


class Equidistant(RadialCamera):
    """``r = f theta`` (see :class:`RadialCamera`)."""

    model = "equidistant"

    @staticmethod
    def radius(theta):
        return theta

    @staticmethod
    def _theta_of(rho):
        return rho


class Equisolid(RadialCamera):
    """``r = 2 f sin(theta / 2)`` (see :class:`RadialCamera`)."""

    model = "equisolid"

    @staticmethod
    def radius(theta):
        return 2.0 * (torch.sin(theta / 2.0) if isinstance(theta, torch.Tensor) else math.sin(theta / 2.0))

    @staticmethod
    def _theta_of(rho):
        return torch.where(rho <= 2.0, 2.0 * torch.asin((rho / 2.0).clamp(max=1.0)), torch.nan)


class Stereographic(RadialCamera):
    """``r = 2 f tan(theta / 2)`` (see :class:`RadialCamera`)."""

    model = "stereographic"
    open_limit = True

    @staticmethod
    def radius(theta):
        return 2.0 * (torch.tan(theta / 2.0) if isinstance(theta, torch.Tensor) else math.tan(theta / 2.0))

    @staticmethod
    def _theta_of(rho):
        return 2.0 * torch.atan(rho / 2.0)


class Orthographic(RadialCamera):
    """``r = f sin(theta)`` (see :class:`RadialCamera`)."""

    model = "orthographic"
    max_model_theta = math.pi / 2

    @staticmethod
    def radius(theta):
        return torch.sin(theta) if isinstance(theta, torch.Tensor) else math.sin(theta)

    @staticmethod
    def _theta_of(rho):
        return torch.where(rho <= 1.0, torch.asin(rho.clamp(max=1.0)), torch.nan)


RADIAL_MODELS: dict[str, type[RadialCamera]] = {
    cls.model: cls for cls in (Equidistant, Equisolid, Stereographic, Orthographic)
}


class Pinhole(CameraModel):
    """The ideal perspective lens, ``r = f tan(theta)``: a pinhole without distortion, as the views a model
    trained on ordinary (perspective) images takes.

    Its ``fov_deg`` is not an image circle: it is the full field of view across the image's width, which sets the
    focal length ``f = (W / 2) / tan(fov_deg / 2)`` (the same in x and y), and every pixel of the frame is valid
    (the corners see further than ``fov_deg / 2``). The valid region is the half-space in front of the camera. At
    ``fov_deg = 90`` on an ``S x S`` image with the default principal point it is a cube face (focal ``S / 2``).

    Args:
        width: Image width in pixels.
        height: Image height in pixels.
        fov_deg: Full field of view across the width, in degrees, in ``(0, 180)``.
        cx: Principal point column; default ``(width - 1) / 2``.
        cy: Principal point row; default ``(height - 1) / 2``.

    Example:
        >>> import numpy as np
        >>> cam = Pinhole(64, 64, fov_deg=90.0)
        >>> cam.focal, cam.valid_mask().all().item()
        (32.00000000000001, True)
        >>> uv, valid = cam.project(np.array([[1.0, 0.0, 1.0], [0.0, 0.0, -1.0]]))
        >>> uv[0].round(6).tolist(), valid.tolist()
        ([63.5, 31.5], [True, False])
        >>> round(cam.coverage_deg, 1)  # the corner pixels' centres: what the incidence-angle rings must reach
        108.6
    """

    model = "pinhole"
    declaration = (
        Param("fov_deg", 90.0, check=interval(0.0, 180.0, open_lo=True, open_hi=True)),
        Param("cx", None, check=optional(number), scale="cx"),
        Param("cy", None, check=optional(number), scale="cy"),
    )
    fov_limits_region = False

    fov_deg: float
    #: Focal length in pixels (derived from ``fov_deg`` and the width).
    focal: float

    def _setup(self) -> None:
        if self.cx is None:
            self.cx = (self.width - 1) / 2.0
        if self.cy is None:
            self.cy = (self.height - 1) / 2.0
        self.focal = (self.width / 2.0) / math.tan(math.radians(self.fov_deg) / 2.0)

    def _project(self, x, y, z):
        return self.cx + self.focal * (x / z), self.cy + self.focal * (y / z), z > 0

    def _unproject(self, u, v):
        mx, my = (u - self.cx) / self.focal, (v - self.cy) / self.focal
        return mx, my, torch.ones_like(mx)

    def perturbed(
        self, focal: float = 1.0, shift: tuple[float, float] = (0.0, 0.0), distortion: Sequence[float] = ()
    ) -> Pinhole:
        """The same lens zoomed by ``focal`` (its field of view narrowed to keep ``f`` times the focal length)
        with its principal point shifted by ``shift``; it has no distortion coefficients."""
        half = math.atan(math.tan(math.radians(self.fov_deg) / 2.0) / focal)
        return Pinhole(
            self.width, self.height, math.degrees(2.0 * half), self.cx + shift[0], self.cy + shift[1]
        )


__all__ = [
    "RADIAL_MODELS",
    "Equidistant",
    "Equisolid",
    "Orthographic",
    "Pinhole",
    "RadialCamera",
    "Stereographic",
]
