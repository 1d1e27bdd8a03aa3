"""Fisheye augmentation primitives."""

from __future__ import annotations

import math

import torch
import torchvision.transforms.v2.functional as TF

from datamodules.augment import (
    AugmentParams,
    FisheyeAugment,
    apply_color_jitter,
    apply_geometry,
    rotation_affine,
)


def test_brightness_contrast_saturation_match_torchvision() -> None:
    # In-gamut colours: torchvision clamps after every step, the fused transform once at the end.
    img = torch.rand(3, 32, 40, generator=torch.Generator().manual_seed(0)) * 0.3 + 0.35
    for b, c, s in [(1.2, 1.0, 1.0), (1.0, 0.7, 1.0), (1.0, 1.0, 1.4), (0.9, 1.1, 0.8)]:
        ours = apply_color_jitter(img, AugmentParams(False, 0.0, (b, c, s, 0.0)))
        ref = TF.adjust_saturation(TF.adjust_contrast(TF.adjust_brightness(img, b), c), s)
        torch.testing.assert_close(ours, ref, atol=1e-4, rtol=0)


def test_hue_rotation_keeps_luma_and_turns_chroma() -> None:
    img = torch.rand(3, 16, 16, generator=torch.Generator().manual_seed(1)) * 0.2 + 0.4  # stays in gamut
    out = apply_color_jitter(img, AugmentParams(False, 0.0, (1.0, 1.0, 1.0, 0.25)))
    luma = torch.tensor([0.299, 0.587, 0.114])
    torch.testing.assert_close(luma @ out.reshape(3, -1), luma @ img.reshape(3, -1), atol=1e-5, rtol=0)
    assert (out - img).abs().mean() > 0.01
    full_turn = apply_color_jitter(img, AugmentParams(False, 0.0, (1.0, 1.0, 1.0, 0.5)))
    half_back = apply_color_jitter(full_turn, AugmentParams(False, 0.0, (1.0, 1.0, 1.0, -0.5)))
    torch.testing.assert_close(half_back, img, atol=1e-5, rtol=0)


def test_rotation_grid_matches_the_pixel_formula() -> None:
    """The normalised affine reproduces src = c + R(-a)(dst - c) in pixels, also off-centre and non-square."""
    h, w, cx, cy, a = 30, 50, 21.0, 13.5, 0.7
    grid = torch.nn.functional.affine_grid(
        rotation_affine(a, cx, cy, h, w)[None], [1, 1, h, w], align_corners=True
    )[0]
    src_u = (grid[..., 0] + 1) * (w - 1) / 2
    src_v = (grid[..., 1] + 1) * (h - 1) / 2
    v, u = torch.meshgrid(
        torch.arange(h, dtype=torch.float32), torch.arange(w, dtype=torch.float32), indexing="ij"
    )
    exp_u = cx + math.cos(a) * (u - cx) + math.sin(a) * (v - cy)
    exp_v = cy - math.sin(a) * (u - cx) + math.cos(a) * (v - cy)
    torch.testing.assert_close(src_u, exp_u, atol=1e-3, rtol=0)
    torch.testing.assert_close(src_v, exp_v, atol=1e-3, rtol=0)


def test_nearest_geometry_copies_values() -> None:
    labels = torch.randint(0, 13, (1, 33, 33), dtype=torch.int64)
    out = apply_geometry(labels, AugmentParams(True, 0.4, None), 16.0, 16.0, "nearest")
    assert out.dtype == torch.int64 and set(out.unique().tolist()) <= set(labels.unique().tolist()) | {0}


def test_sampling_is_seeded() -> None:
    aug = FisheyeAugment(hflip=0.5, rotate_deg=20.0)
    draws = [aug.sample(torch.Generator().manual_seed(3)) for _ in range(2)]
    assert draws[0] == draws[1]
    assert abs(draws[0].angle_rad) <= math.radians(20.0)
