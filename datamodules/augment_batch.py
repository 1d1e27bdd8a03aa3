"""The training augmentation of a whole batch, on whatever device the batch is on.

With ``data.remap_on=device`` the cube faces become fisheye images only after the batch reached the model's device,
so the augmentation that follows the remap (flip, rotation, colour jitter) runs there too. :func:`augment_batch`
does what :func:`datamodules.augment.augment_sample` (the fused CPU kernel ``augment_kernel.warp_and_colour``) does to
each sample, in the same order and arithmetic: source coordinates in float64, nearest copies of the valid mask,
labels and depth (round half to even), bilinear RGB with zero padding in float32, then the colour transform,
clamped, and zero outside the moved mask. The colour jitter's mean grey is taken from the remapped image before
the rotation, as the kernel does.

The worker draws each sample's augmentation and sends it as :func:`pack_params`'s ``float64 [15]`` row (the draw
stays where it was: ``(seed, epoch, index)`` decides it).

Example:
    >>> import torch
    >>> from datamodules.augment import AugmentParams
    >>> rgb = torch.arange(12, dtype=torch.uint8).view(1, 1, 2, 6).expand(1, 3, 2, 6)
    >>> valid = torch.ones(2, 6, dtype=torch.bool)
    >>> packed = pack_params(AugmentParams(True, 0.0, None))[None]
    >>> image, moved, _ = augment_batch(rgb, valid, torch.zeros(1, 0, 2, 6), [], packed, 2.5, 0.5)
    >>> (image[0, 0] * 255).round().int().tolist()
    [[5, 4, 3, 2, 1, 0], [11, 10, 9, 8, 7, 6]]
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from datamodules.augment import LUMA, AugmentParams, color_matrix

#: Columns of a packed draw: flip, cos and sin of the angle, the colour matrix (row-major, for 0-1 colours) and the
#: colour offset per unit of the image's mean grey.
PACKED_SIZE = 15


def pack_params(params: AugmentParams) -> torch.Tensor:
    """One sample's draw as ``float64 [PACKED_SIZE]`` (the cosine and sine as ``math`` gives them, as the kernel).

    The jitter's colour matrix is :func:`~datamodules.augment.jitter_affine`'s; its offset is
    ``m @ (1 - contrast) * brightness`` here, multiplied by the mean grey once the image exists.
    """
    out = torch.zeros(PACKED_SIZE, dtype=torch.float64)
    out[0] = float(params.flip)
    out[1], out[2] = math.cos(params.angle_rad), math.sin(params.angle_rad)
    if params.jitter is None:
        colour, per_grey = torch.eye(3), torch.zeros(3)
    else:
        brightness, contrast, saturation, hue = params.jitter
        m = color_matrix(saturation, hue)
        colour = m * (contrast * brightness)
        per_grey = m @ torch.full((3,), (1.0 - contrast) * brightness)
    out[3:12] = colour.reshape(9).double()
    out[12:15] = per_grey.double()
    return out


def augment_batch(
    rgb: torch.Tensor,
    valid: torch.Tensor,
    maps: torch.Tensor,
    fills: Sequence[float],
    packed: torch.Tensor,
    cx: float,
    cy: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Flip, rotate and colour-jitter a batch: :func:`~datamodules.augment.augment_sample` for every sample.

    Args:
        rgb: ``uint8 [B, 3, H, W]`` images.
        valid: ``bool [H, W]`` pixels that carry data (the same for every sample).
        maps: ``float32 [B, D, H, W]`` maps copied, never blended (labels, depth); ``D`` may be 0.
        fills: Value of each map where the moved mask is False.
        packed: ``[B, PACKED_SIZE]`` draws (:func:`pack_params`).
        cx, cy: Principal point.

    Returns:
        ``float32 [B, 3, H, W]`` images in ``[0, 1]``, ``bool [B, H, W]`` moved masks, ``float32 [B, D, H, W]``
        moved maps.
    """
    b, _, h, w = rgb.shape
    device = rgb.device
    p = packed.to(device=device, dtype=torch.float64)
    flip, cos_a, sin_a = p[:, 0, None, None] > 0.5, p[:, 1, None, None], p[:, 2, None, None]
    dy = torch.arange(h, dtype=torch.float64, device=device).view(1, h, 1) - cy
    dx = torch.arange(w, dtype=torch.float64, device=device).view(1, 1, w) - cx
    # The kernel's expressions, term for term: the output pixel at d from (cx, cy) reads the input at R(-a) d.
    us = (cx + sin_a * dy) + cos_a * dx
    vs = (cy + cos_a * dy) - sin_a * dx
    us = torch.where(flip, 2.0 * cx - us, us)

    # Nearest: the moved mask and the maps (torch.round is round half to even, as np.rint).
    jn, i_n = us.round(), vs.round()
    inside = (jn >= 0) & (jn < w) & (i_n >= 0) & (i_n < h)
    nearest = (i_n.clamp(0, h - 1).long() * w + jn.clamp(0, w - 1).long()).view(b, h * w)
    moved = inside & valid.reshape(-1)[nearest].view(b, h, w)
    depth = maps.shape[1]
    moved_maps = maps.reshape(b, depth, h * w).gather(2, nearest[:, None].expand(b, depth, h * w))
    fill = torch.tensor(list(fills), dtype=maps.dtype, device=device).view(1, depth, 1, 1)
    moved_maps = torch.where(moved[:, None], moved_maps.view(b, depth, h, w), fill)

    # Bilinear RGB: four taps, those off the image read 0 (grid_sample's zero padding).
    x0f, y0f = us.floor(), vs.floor()
    fx, fy = (us - x0f).float(), (vs - y0f).float()
    x0, y0 = x0f.long(), y0f.long()
    src = rgb.reshape(b, 3, h * w)
    acc = torch.zeros(b, 3, h * w, device=device)
    for ox, oy, weight in (
        (0, 0, (1 - fx) * (1 - fy)),
        (1, 0, fx * (1 - fy)),
        (0, 1, (1 - fx) * fy),
        (1, 1, fx * fy),
    ):
        x, y = x0 + ox, y0 + oy
        on_image = (x >= 0) & (x < w) & (y >= 0) & (y < h)
        index = (y.clamp(0, h - 1) * w + x.clamp(0, w - 1)).view(b, 1, h * w).expand(b, 3, h * w)
        acc += src.gather(2, index).float() * (weight * on_image).view(b, 1, h * w)

    # Colour: written out per channel, so no matrix product (which may run in TF32 on a GPU) rounds it.
    colour = p[:, 3:12].float().view(b, 3, 3) / 255.0
    mean_rgb = rgb.reshape(b, 3, -1).sum(2, dtype=torch.float64) / (255.0 * h * w)
    grey = (mean_rgb * LUMA.to(device=device, dtype=torch.float64)).sum(1)
    offset = p[:, 12:15].float() * grey.float()[:, None]
    image = torch.stack(
        [
            colour[:, c, 0, None] * acc[:, 0]
            + colour[:, c, 1, None] * acc[:, 1]
            + colour[:, c, 2, None] * acc[:, 2]
            + offset[:, c, None]
            for c in range(3)
        ],
        1,
    ).clamp_(0.0, 1.0)
    image = image.view(b, 3, h, w) * moved[:, None]
    return image, moved, moved_maps


__all__ = ["PACKED_SIZE", "augment_batch", "pack_params"]
