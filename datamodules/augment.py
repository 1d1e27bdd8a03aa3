"""Fisheye-aware augmentation that keeps image, labels, depth and sparse LiDAR depth consistent.

- Horizontal flip: mirrors the image about the vertical line through the principal point (``u -> 2 cx - u``), which
  for a radially symmetric lens is the camera seen in a mirror, wherever its principal point lies. A centred
  principal point (``cx = (W - 1) / 2``) makes it the pixel permutation ``u -> W - 1 - u``; an off-centre one
  (a real calibration) moves the image circle onto itself, not onto the frame's mirror image, so the rotation
  about ``(cx, cy)`` that follows turns about the right point. LiDAR points are mirrored as points
  (``lidar_depth_map(mirror=True)``), so no sparse point is moved by resampling.
- Rotation about the optical axis: rotating the camera frame by ``angle`` about z moves every pixel by ``angle``
  about the principal point (the lens is radially symmetric), so dense maps are rotated in the image
  (bilinear for RGB, nearest for labels and depth) and LiDAR points are rotated *before* projection, so no sparse
  point is lost or smeared by resampling. Positive angles turn x (right) towards y (down).
- Colour jitter (paper: "random color jitter"): brightness, contrast, saturation and hue on the RGB image only, as
  one affine colour transform (hue as a rotation about the grey axis in YIQ); pixels outside the image circle stay
  black.

:func:`augment_sample` does all three in one fused CPU pass (what ``AirFisheyeDataset`` uses);
:func:`apply_geometry` and :func:`apply_color_jitter` are the device-agnostic torch versions it is tested against.

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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from datamodules import augment_kernel


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


def augment_sample(
    rgb: torch.Tensor,
    valid: torch.Tensor,
    maps: torch.Tensor,
    fills: Sequence[float],
    params: AugmentParams,
    cx: float,
    cy: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """A sample's whole augmentation in one fused CPU pass: flip, rotation and colour jitter.

    The same as :func:`apply_geometry` on every map followed by :func:`apply_color_jitter` and masking, except
    that the contrast's mean grey is taken before the rotation (the image circle turns into itself, so only the
    interpolation differs).

    Args:
        rgb: ``uint8 [3, H, W]`` image.
        valid: ``bool [H, W]`` pixels that carry data.
        maps: ``float32 [D, H, W]`` maps that are copied, never blended (labels, depth); ``D`` may be 0.
        fills: Value of each map where the moved ``valid`` is False (255 for labels, 0 for depth).
        params: The sample's draw.
        cx, cy: Principal point.

    Returns:
        ``(image, valid, maps)``: ``float32 [3, H, W]`` in ``[0, 1]`` (0 outside ``valid``), the moved mask and
        the moved maps.

    Example:
        >>> rgb = torch.full((3, 4, 4), 200, dtype=torch.uint8)
        >>> valid = torch.ones(4, 4, dtype=torch.bool)
        >>> image, moved, maps = augment_sample(
        ...     rgb, valid, torch.zeros(0, 4, 4), [], AugmentParams(True, 0.0, None), 1.5, 1.5
        ... )
        >>> round(float(image[0, 0, 0]), 4), bool(moved.all()), tuple(maps.shape)
        (0.7843, True, (0, 4, 4))
    """
    h, w = valid.shape
    if rgb.shape != (3, h, w) or rgb.dtype != torch.uint8:
        raise ValueError(f"rgb must be uint8 [3, {h}, {w}], got {rgb.dtype} {tuple(rgb.shape)}")
    if maps.ndim != 3 or maps.shape[1:] != (h, w) or len(fills) != maps.shape[0]:
        raise ValueError(
            f"maps must be [D, {h}, {w}] with D fill values, got {tuple(maps.shape)}, {len(fills)}"
        )
    colour, offset = torch.eye(3), torch.zeros(3)
    if params.jitter is not None:
        mean_rgb = rgb.reshape(3, -1).sum(1, dtype=torch.float64) / (255.0 * h * w)
        colour, offset = jitter_affine(params.jitter, float(LUMA.double() @ mean_rgb))
    colour = colour / 255.0  # the kernel reads 0-255 values
    image = torch.empty(3, h, w)
    moved = torch.empty(h, w, dtype=torch.bool)
    moved_maps = torch.empty(maps.shape)
    augment_kernel.warp_and_colour(
        rgb.contiguous().numpy(),
        valid.contiguous().numpy(),
        maps.to(torch.float32).contiguous().numpy(),
        np.asarray(fills, dtype=np.float32),
        bool(params.flip),
        math.cos(params.angle_rad),
        math.sin(params.angle_rad),
        float(cx),
        float(cy),
        colour.to(torch.float32).numpy(),
        offset.to(torch.float32).numpy(),
        image.numpy(),
        moved.numpy(),
        moved_maps.numpy(),
    )
    return image, moved, moved_maps


def apply_geometry(
    x: torch.Tensor, params: AugmentParams, cx: float, cy: float, mode: str, grid: torch.Tensor | None = None
) -> torch.Tensor:
    """Mirror (``u -> 2 cx - u``) and rotate a dense ``[C, H, W]`` map about the principal point ``(cx, cy)``.

    ``mode`` is ``bilinear`` (images) or ``nearest`` (labels, depth, masks; values are copied, never blended).
    Stack maps that share a mode into one call, and pass the same ``grid`` (:func:`rotation_grid`) to every call of
    one sample. Pixels rotated in from outside the image get 0 (callers re-apply the image-circle mask).
    """
    w = x.shape[-1]
    if params.flip and cx == (w - 1) / 2.0:  # centred: the mirror is a pixel permutation
        x = x.flip(-1)
        flip = False
    else:
        flip = params.flip
    if params.angle_rad == 0.0 and not flip:
        return x
    if grid is None:
        grid = rotation_grid(params.angle_rad, cx, cy, *x.shape[-2:], flip=flip)
    dtype = x.dtype
    out = F.grid_sample(x[None].to(torch.float32), grid, mode=mode, padding_mode="zeros", align_corners=True)[
        0
    ]
    if dtype.is_floating_point:
        return out.to(dtype)
    return out.round_().to(dtype)


def rotation_grid(angle_rad: float, cx: float, cy: float, h: int, w: int, flip: bool = False) -> torch.Tensor:
    """``[1, H, W, 2]`` sampling grid of the rotation (what ``F.affine_grid`` gives, built separably: faster).

    With ``flip``, the rotated position is then mirrored about the principal point's column (``u -> 2 cx - u``):
    the grid of "mirror, then rotate" (the output reads the mirrored input).
    """
    theta = rotation_affine(angle_rad, cx, cy, h, w, flip)
    xs = torch.linspace(-1.0, 1.0, w)
    ys = torch.linspace(-1.0, 1.0, h)
    gx = theta[0, 0] * xs[None, :] + (theta[0, 1] * ys + theta[0, 2])[:, None]
    gy = theta[1, 0] * xs[None, :] + (theta[1, 1] * ys + theta[1, 2])[:, None]
    return torch.stack([gx, gy], -1)[None]


def rotation_affine(
    angle_rad: float, cx: float, cy: float, h: int, w: int, flip: bool = False
) -> torch.Tensor:
    """``[2, 3]`` affine map (``align_corners=True`` normalised coordinates) of the inverse rotation.

    The output pixel at offset ``d`` from the principal point reads the input at ``R(-angle) d`` (then mirrored
    about the principal point's column if ``flip``); written in normalised coordinates ``x = 2u / (W-1) - 1`` so
    that ``F.affine_grid`` builds the sampling grid in one call.
    """
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    sx, sy = (w - 1) / 2.0, (h - 1) / 2.0  # pixels per normalised unit
    # Pixel-space map: src = p0 + R(-a) (dst - p0), with p0 = (cx, cy); conjugate by the normalisation.
    a = torch.tensor([[c, s * sy / sx], [-s * sx / sy, c]], dtype=torch.float64)
    p0 = torch.tensor([cx / sx - 1.0, cy / sy - 1.0], dtype=torch.float64)
    b = p0 - a @ p0
    if flip:  # x -> 2 p0_x - x, after the rotation
        a, b = a * torch.tensor([[-1.0], [1.0]], dtype=torch.float64), b.clone()
        b[0] = 2.0 * p0[0] - b[0]
    return torch.cat([a, b[:, None]], 1).to(torch.float32)


def rotation_about_optical_axis(angle_rad: float) -> torch.Tensor:
    """``[4, 4]`` float64 transform rotating camera-frame points by ``angle`` about z (x towards y)."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    T = torch.eye(4, dtype=torch.float64)
    T[:2, :2] = torch.tensor([[c, -s], [s, c]], dtype=torch.float64)
    return T


# ITU-R BT.601 luma, as torchvision's rgb_to_grayscale.
LUMA = torch.tensor([0.299, 0.587, 0.114])
_RGB_TO_YIQ = torch.tensor([[0.299, 0.587, 0.114], [0.596, -0.274, -0.322], [0.211, -0.523, 0.312]])


def color_matrix(saturation: float, hue: float) -> torch.Tensor:
    """``[3, 3]`` linear map of a saturation change followed by a hue rotation (``hue`` in turns, +-0.5).

    Saturation blends each pixel with its grey value (as torchvision); the hue shift rotates chroma about the grey
    axis in YIQ space, a linear stand-in for HSV hue rotation that costs one matrix product instead of a colour
    space round trip.
    """
    grey = torch.outer(torch.ones(3), LUMA)
    sat = saturation * torch.eye(3) + (1.0 - saturation) * grey
    c, s = math.cos(2 * math.pi * hue), math.sin(2 * math.pi * hue)
    rot = torch.tensor([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    hue_m = torch.linalg.inv(_RGB_TO_YIQ) @ rot @ _RGB_TO_YIQ
    return hue_m @ sat


def apply_color_jitter(image: torch.Tensor, params: AugmentParams) -> torch.Tensor:
    """Colour-jitter a float ``[3, H, W]`` image in ``[0, 1]``: brightness, contrast, saturation, hue, in that order.

    All four are affine in the colour, so they compose into one ``3 x 3`` matrix and an offset applied in a single
    pass (clamped once at the end rather than after every step).
    """
    if params.jitter is None:
        return image
    mean_grey = float((LUMA.to(image.dtype) @ image.reshape(3, -1)).mean())
    matrix, offset = jitter_affine(params.jitter, mean_grey)
    out = matrix.to(image.dtype) @ image.reshape(3, -1)
    out += offset.to(image.dtype)[:, None]
    return out.clamp_(0.0, 1.0).reshape(image.shape)


def jitter_affine(
    jitter: tuple[float, float, float, float], mean_grey: float
) -> tuple[torch.Tensor, torch.Tensor]:
    """The colour jitter ``(brightness, contrast, saturation, hue)`` as ``x -> matrix @ x + offset``.

    ``mean_grey`` is the image's mean luma (colours in ``[0, 1]``) before the jitter, which contrast blends towards.
    Returns ``float32 [3, 3]`` and ``[3]``.
    """
    brightness, contrast, saturation, hue = jitter
    m = color_matrix(saturation, hue)
    # contrast(brightness(x)) = c * b * x + (1 - c) * b * mean_grey; saturation and hue then apply m.
    offset = m @ torch.full((3,), (1.0 - contrast) * brightness * mean_grey)
    return m * (contrast * brightness), offset
