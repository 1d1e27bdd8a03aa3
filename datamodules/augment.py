"""Fisheye-aware augmentation that keeps image, labels, depth and sparse LiDAR depth consistent.

- Horizontal flip: mirrors the image about the vertical line through the principal point (``u -> W - 1 - u``), which
  for a radially symmetric lens with a centred principal point is the camera seen in a mirror. Sparse depth maps are
  flipped as images (a pixel permutation, exact).
- Rotation about the optical axis: rotating the camera frame by ``angle`` about z moves every pixel by ``angle``
  about the principal point (the lens is radially symmetric), so dense maps are rotated in the image
  (bilinear for RGB, nearest for labels and depth) and LiDAR points are rotated *before* projection, so no sparse
  point is lost or smeared by resampling. Positive angles turn x (right) towards y (down).
- Colour jitter (paper: "random color jitter"): brightness, contrast, saturation and hue on the RGB image only,
  pixels outside the image circle are kept black.

Example:
    >>> import torch
    >>> aug = FisheyeAugment(hflip=1.0, rotate_deg=0.0, color_jitter=None)
    >>> params = aug.sample(torch.Generator().manual_seed(0))
    >>> img = torch.arange(6.0).view(1, 2, 3)
    >>> apply_geometry(img, params, cx=1.0, cy=0.5, mode="nearest")[0, 0].tolist()
    [2.0, 1.0, 0.0]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F
import torchvision.transforms.v2.functional as TF


@dataclass(frozen=True)
class AugmentParams:
    """One sample's random draw."""

    flip: bool
    angle_rad: float
    jitter: tuple[float, float, float, float] | None  # brightness, contrast, saturation factors and hue shift


@dataclass(frozen=True)
class FisheyeAugment:
    """Random augmentation settings (defaults: the paper's flip and colour jitter, no rotation).

    Args:
        hflip: Probability of a horizontal flip.
        rotate_deg: Maximum absolute rotation about the optical axis, degrees (uniform in ``[-r, r]``).
        color_jitter: ``(brightness, contrast, saturation, hue)`` ranges as in torchvision's ``ColorJitter``,
            or ``None`` for none.
    """

    hflip: float = 0.5
    rotate_deg: float = 0.0
    color_jitter: tuple[float, float, float, float] | None = (0.2, 0.2, 0.2, 0.05)

    def __post_init__(self) -> None:
        if not 0.0 <= self.hflip <= 1.0:
            raise ValueError(f"hflip must be a probability in [0, 1], got {self.hflip}")
        if not (math.isfinite(self.rotate_deg) and 0.0 <= self.rotate_deg <= 180.0):
            raise ValueError(f"rotate_deg must be in [0, 180], got {self.rotate_deg}")
        if self.color_jitter is not None and (
            len(self.color_jitter) != 4 or any(v < 0 for v in self.color_jitter) or self.color_jitter[3] > 0.5
        ):
            raise ValueError(
                "color_jitter must be (brightness, contrast, saturation, hue) with non-negative values and"
                f" hue <= 0.5, got {self.color_jitter}"
            )

    def sample(self, generator: torch.Generator | None = None) -> AugmentParams:
        """Draw the parameters for one sample."""
        u = torch.rand(6, generator=generator, dtype=torch.float64).tolist()
        flip = u[0] < self.hflip
        angle = math.radians(self.rotate_deg) * (2.0 * u[1] - 1.0)
        jitter = None
        if self.color_jitter is not None:
            b, c, s, h = self.color_jitter
            jitter = (
                1.0 + b * (2 * u[2] - 1),
                1.0 + c * (2 * u[3] - 1),
                1.0 + s * (2 * u[4] - 1),
                h * (2 * u[5] - 1),
            )
        return AugmentParams(flip, angle, jitter)


def apply_geometry(x: torch.Tensor, params: AugmentParams, cx: float, cy: float, mode: str) -> torch.Tensor:
    """Flip and rotate a dense ``[C, H, W]`` map about the principal point ``(cx, cy)``.

    ``mode`` is ``bilinear`` (images) or ``nearest`` (labels, depth, masks; values are copied, never blended).
    Pixels rotated in from outside the image get 0 (callers re-apply the image-circle mask).
    """
    if params.flip:
        x = x.flip(-1)
    if params.angle_rad == 0.0:
        return x
    h, w = x.shape[-2:]
    # Inverse mapping: the output pixel at offset d from the principal point reads the input at R(-angle) d.
    v, u = torch.meshgrid(
        torch.arange(h, dtype=torch.float64), torch.arange(w, dtype=torch.float64), indexing="ij"
    )
    du, dv = u - cx, v - cy
    c, s = math.cos(params.angle_rad), math.sin(params.angle_rad)
    src_u = cx + c * du + s * dv
    src_v = cy - s * du + c * dv
    grid = torch.stack([2 * src_u / (w - 1) - 1, 2 * src_v / (h - 1) - 1], -1).to(torch.float32)[None]
    dtype = x.dtype
    out = F.grid_sample(x[None].to(torch.float32), grid, mode=mode, padding_mode="zeros", align_corners=True)[
        0
    ]
    if dtype.is_floating_point:
        return out.to(dtype)
    return out.round_().to(dtype)


def rotation_about_optical_axis(angle_rad: float) -> torch.Tensor:
    """``[4, 4]`` float64 transform rotating camera-frame points by ``angle`` about z (x towards y)."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    T = torch.eye(4, dtype=torch.float64)
    T[:2, :2] = torch.tensor([[c, -s], [s, c]], dtype=torch.float64)
    return T


def apply_color_jitter(image: torch.Tensor, params: AugmentParams) -> torch.Tensor:
    """Colour-jitter a ``uint8 [3, H, W]`` image (brightness, contrast, saturation, hue in that order)."""
    if params.jitter is None:
        return image
    brightness, contrast, saturation, hue = params.jitter
    image = TF.adjust_brightness(image, brightness)
    image = TF.adjust_contrast(image, contrast)
    image = TF.adjust_saturation(image, saturation)
    return TF.adjust_hue(image, hue)
