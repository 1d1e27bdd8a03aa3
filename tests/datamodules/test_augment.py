"""Fisheye augmentation primitives."""

from __future__ import annotations

import math

import pytest
import torch
import torchvision.transforms.v2.functional as TF

from datamodules.augment import (
    AugmentParams,
    FisheyeAugment,
    apply_color_jitter,
    apply_geometry,
    augment_sample,
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


@pytest.mark.parametrize(
    "params",
    [
        AugmentParams(True, 0.3, (1.15, 0.85, 1.2, 0.04)),
        AugmentParams(False, -0.2, None),
        AugmentParams(True, 0.0, (0.9, 1.1, 0.8, -0.03)),
        AugmentParams(False, 0.0, None),
    ],
    ids=["flip-rotate-jitter", "rotate", "flip-jitter", "identity"],
)
def test_fused_augmentation_matches_the_torch_composition(params: AugmentParams) -> None:
    """``augment_sample`` = ``apply_geometry`` on every map, then ``apply_color_jitter`` and the moved mask."""
    g = torch.Generator().manual_seed(5)
    h, w, cx, cy = 40, 56, 26.0, 19.5  # non-square, principal point off the image centre
    v, u = torch.meshgrid(torch.arange(h), torch.arange(w), indexing="ij")
    valid = (u - cx) ** 2 + (v - cy) ** 2 <= 18.0**2
    rgb = (torch.rand(3, h, w, generator=g) * 255).to(torch.uint8) * valid
    label = torch.randint(0, 13, (h, w), generator=g).where(valid, 255)
    depth = (torch.rand(1, h, w, generator=g) * 80 + 1) * valid
    image, moved, maps = augment_sample(
        rgb, valid, torch.cat([label[None].float(), depth]), [255.0, 0.0], params, cx, cy
    )

    grid_maps = apply_geometry(
        torch.cat([valid[None].float(), label[None].float(), depth]), params, cx, cy, "nearest"
    )
    ref_valid = grid_maps[0] > 0.5
    assert torch.equal(moved, ref_valid)
    assert torch.equal(maps[0], torch.where(ref_valid, grid_maps[1], 255.0))
    assert torch.equal(maps[1], grid_maps[2] * ref_valid)
    ref_rgb = apply_geometry(rgb.float() / 255.0, params, cx, cy, "bilinear")
    # The fused path takes the contrast's mean grey before the warp: here the two means differ by ~6e-6, which
    # moves the colours by ~1e-6.
    ref_image = apply_color_jitter(ref_rgb, params) * ref_valid
    torch.testing.assert_close(image, ref_image, atol=1e-5, rtol=0)


@pytest.mark.parametrize("angle", [0.0, 0.5])
def test_flip_mirrors_about_the_principal_point_not_the_frame_centre(angle: float) -> None:
    """A real calibration's off-centre principal point: the image circle mirrors onto itself.

    Mirroring about the frame's centre (``u -> W - 1 - u``) would move the circle to ``W - 1 - cx`` and the
    rotation that follows would turn about the wrong point.
    """
    h, w, cx, cy = 40, 56, 22.5, 19.5  # cx is 5 px left of the centre column 27.5
    v, u = torch.meshgrid(torch.arange(h), torch.arange(w), indexing="ij")
    valid = (u - cx) ** 2 + (v - cy) ** 2 <= 15.0**2
    column = (u.float() * valid)[None]  # each pixel holds its own column
    params = AugmentParams(True, angle, None)
    moved = apply_geometry(valid[None].float(), params, cx, cy, "nearest")[0] > 0.5
    _, fused_valid, fused = augment_sample(
        torch.zeros(3, h, w, dtype=torch.uint8), valid, column, [0.0], params, cx, cy
    )
    # The circle is symmetric about its centre's column, so mirroring it changes nothing: mirrored-then-rotated
    # equals rotated alone (up to a rounding tie or two on the rim).
    rotated = (
        apply_geometry(valid[None].float(), AugmentParams(False, angle, None), cx, cy, "nearest")[0] > 0.5
    )
    assert (moved ^ rotated).sum() <= 2
    assert torch.equal(fused_valid, moved)
    if angle == 0.0:  # the pixel at column u now shows column 2 cx - u
        expected = torch.where(valid, 2 * cx - u.float(), torch.zeros(()))
        assert torch.equal(fused[0], expected)


def test_flip_about_a_centred_principal_point_is_the_pixel_permutation() -> None:
    x = torch.arange(12.0).view(1, 3, 4)
    params = AugmentParams(True, 0.0, None)
    assert torch.equal(apply_geometry(x, params, cx=1.5, cy=1.0, mode="nearest"), x.flip(-1))
