"""Serving a calibrated camera at another image size: one rule for every camera model (docs/design.md, "Calibration
files", serving size).

The served image is ``size x size``. The intrinsics scale with the image about the pixel *corner* (as
``CameraModel.resized``: a pixel-centre coordinate ``c`` becomes ``(c + 0.5) s - 0.5``, focal lengths and every other
pixel length scale by ``s``). A square calibration is simply resized (``s = size / width``). A non-square one is never
stretched; ``fit`` decides:

- ``pad`` (default): ``s = size / max(W, H)``: the whole calibrated frame fits, centred; the bands beyond it are
  outside the sensor (:meth:`ServedCamera.frame_mask` is False there, and the data marks them invalid).
- ``crop``: ``s = size / min(W, H)``: the frame fills the square, centred; the ends of its longer side are cut.

Either way the principal point moves by the centring offset ``((size - W s) / 2, (size - H s) / 2)`` (positive: a
pad, negative: a crop), a sub-pixel amount included. :meth:`ServedCamera.describe` says what was done, for the log.

Example:
    >>> from airfisheye_bench.geometry.cameras import camera_from_dict
    >>> woodscape = camera_from_dict({"model": "radial_poly", "width": 1280, "height": 966, "k1": 339.749,
    ...     "k2": -31.988, "k3": 48.275, "k4": -7.201, "cx": 643.442, "cy": 479.407, "aspect_ratio": 1.0})
    >>> served = serve_camera(woodscape, 512)
    >>> served.camera.width, served.camera.height, served.scale, [round(o, 9) for o in served.offset]
    (512, 512, 0.4, [0.0, 62.8])
    >>> served.describe()
    'radial_poly 1280x966 served at 512x512: intrinsics scaled by 0.4 about the pixel corner, padded by 62.8 px above and below (data.camera.fit=pad; the padding is outside the sensor)'
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from airfisheye_bench.geometry.cameras import CameraModel

__all__ = ["FITS", "ServedCamera", "serve_camera"]

#: How a non-square calibration becomes a square served image.
FITS = ("pad", "crop")


@dataclass(frozen=True)
class ServedCamera:
    """A calibrated camera as served, and how it maps onto the calibrated sensor.

    Attributes:
        camera: The served camera.
        source: The calibrated camera.
        scale: ``s``: served pixels per calibrated pixel.
        offset: ``(x, y)`` pixels added to the scaled pixel-centre coordinates (positive: padding, negative: crop).
        fit: ``pad`` or ``crop`` for a non-square calibration, ``None`` when the aspect was kept.
    """

    camera: CameraModel
    source: CameraModel
    scale: float
    offset: tuple[float, float]
    fit: str | None

    def to_source(self, uv: torch.Tensor) -> torch.Tensor:
        """Served pixel coordinates ``[..., 2]`` -> calibrated-sensor pixel coordinates (float64)."""
        off = torch.tensor(self.offset, dtype=torch.float64)
        return (uv.to(torch.float64) + 0.5 - off) / self.scale - 0.5

    def frame_mask(self) -> torch.Tensor:
        """``[H, W]`` bool: the served pixel's centre lies on the calibrated sensor (False in the padding)."""
        uv = self.to_source(self.camera.pixel_grid())
        u, v = uv[..., 0], uv[..., 1]
        w, h = self.source.width, self.source.height
        return (u >= -0.5) & (u <= w - 0.5) & (v >= -0.5) & (v <= h - 0.5)

    def describe(self) -> str:
        """One line for the log: sizes, scale, and the pad or crop."""
        src, cam = self.source, self.camera
        head = f"{src.model} {src.width}x{src.height} served at {cam.width}x{cam.height}"
        if self.fit is None:
            return f"{head}: intrinsics scaled by {self.scale:.6g} about the pixel corner"
        axis = ("left and right", "above and below")[int(self.offset[0] == 0)]
        amount = max(abs(self.offset[0]), abs(self.offset[1]))
        done = "padded" if self.fit == "pad" else "cropped"
        what = "the padding is outside the sensor" if self.fit == "pad" else "the cut ends are not served"
        return (
            f"{head}: intrinsics scaled by {self.scale:.6g} about the pixel corner, {done} by {amount:.6g} px {axis} "
            f"(data.camera.fit={self.fit}; {what})"
        )


def serve_camera(camera: CameraModel, size: int | None, fit: str = "pad") -> ServedCamera:
    """``camera`` served as a ``size x size`` image (``None``: at its own size), by the rule of the module docstring.

    Raises:
        ValueError: ``fit`` is not one of :data:`FITS`, or ``size < 1``.
    """
    if fit not in FITS:
        raise ValueError(f"fit must be one of {', '.join(FITS)}, got {fit!r}")
    w, h = camera.width, camera.height
    if size is None or (size == w and w == h):
        return ServedCamera(camera, camera, 1.0, (0.0, 0.0), None)
    if size < 1:
        raise ValueError(f"size must be >= 1, got {size}")
    if w == h:
        return ServedCamera(camera.resized(size, size), camera, size / w, (0.0, 0.0), None)
    scale = size / (max(w, h) if fit == "pad" else min(w, h))
    offset = ((size - w * scale) / 2.0, (size - h * scale) / 2.0)
    # The model's own scaling rule (pixel lengths by s, centres about the corner), then the centring shift.
    params = {**camera._param_dict(), **camera._scaled_params(scale, scale)}
    params["cx"] += offset[0]
    params["cy"] += offset[1]
    return ServedCamera(type(camera)(size, size, **params), camera, scale, offset, fit)
