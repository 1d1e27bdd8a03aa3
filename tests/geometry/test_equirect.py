"""Equirectangular panorama -> camera remap, checked against the documented convention written out here."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry import camera_from_dict, ideal_camera
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.equirect import (
    EquirectToFisheye,
    direction_to_erp,
    direction_to_lonlat,
    erp_rays,
    lonlat_to_direction,
    range_to_z_depth,
    z_depth_to_range,
)
from airfisheye_bench.geometry.remap_table import TABLES, _apply_torch, clear_table_cache
from airfisheye_bench.geometry.serving import serve_camera
from airfisheye_bench.geometry.transforms import gimbal_rotation

CALIBRATIONS = Path(__file__).parent / "golden" / "calibrations.json"


def direction_panorama(h: int, w: int) -> torch.Tensor:
    """``[3, H, W]`` float64: each texel holds its own viewing direction, from the docs/design.md formulas."""
    lon = 2 * np.pi * (np.arange(w) + 0.5) / w - np.pi
    lat = np.pi / 2 - np.pi * (np.arange(h) + 0.5) / h
    lon, lat = np.meshgrid(lon, lat)
    d = np.stack([np.cos(lat) * np.sin(lon), -np.sin(lat), np.cos(lat) * np.cos(lon)])
    return torch.from_numpy(d)


def angular_error(image: torch.Tensor, expected: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    d = image.permute(1, 2, 0)[mask].double()
    d = d / d.norm(dim=-1, keepdim=True)
    return torch.acos((d * expected[mask]).sum(-1).clamp(-1, 1))


def expected_directions(camera: CameraModel, rotation: np.ndarray | None) -> torch.Tensor:
    rays = camera.ray_grid(torch.float64)
    return rays if rotation is None else rays @ torch.from_numpy(rotation).T


def test_convention_of_the_docstring() -> None:
    h, w = 4, 8
    torch.testing.assert_close(erp_rays(h, w, torch.float64), direction_panorama(h, w).permute(1, 2, 0))
    # Ahead, right, behind, left, up, down.
    d = torch.tensor(
        [[0, 0, 1], [1, 0, 0], [0, 0, -1], [-1, 0, 0], [0, -1, 0], [0, 1, 0]], dtype=torch.float64
    )
    u, v = direction_to_erp(d, h, w)
    assert u[:2].tolist() == [3.5, 5.5] and u[3] == 1.5 and u[2] in (-0.5, 7.5)
    assert v.tolist()[:4] == [1.5] * 4 and v[4] == -0.5 and v[5] == 3.5
    lon, lat = direction_to_lonlat(lonlat_to_direction(torch.tensor([0.3, -2.0]), torch.tensor([-1.2, 0.4])))
    torch.testing.assert_close(lon, torch.tensor([0.3, -2.0]))
    torch.testing.assert_close(lat, torch.tensor([-1.2, 0.4]))


def _golden(name: str, size: int) -> CameraModel:
    return serve_camera(
        camera_from_dict(json.loads(CALIBRATIONS.read_text())["cameras"][name]["camera"]), size
    ).camera


@pytest.mark.parametrize(
    ("camera", "angles"),
    [
        (ideal_camera(96, 96), (0.0, 0.0, 0.0)),
        (ideal_camera(96, 96), (180.0, 0.0, 0.0)),  # looks across the +-180 deg seam
        (ideal_camera(96, 96), (0.0, 90.0, 0.0)),  # the down pole in the middle of the image
        (ideal_camera(80, 64, fov_deg=230.0, model="equisolid"), (37.0, -90.0, 12.0)),  # up pole, rolled
        (ideal_camera(64, 64, fov_deg=360.0, model="equidistant"), (10.0, 20.0, 30.0)),  # the whole sphere
        (
            camera_from_dict(
                {
                    "model": "pinhole_radtan",
                    "width": 64,
                    "height": 48,
                    "fx": 30.0,
                    "fy": 30.0,
                    "cx": 31.5,
                    "cy": 23.5,
                }
            ),
            (-170.0, 45.0, 0.0),
        ),
        ("tumvi512_cam0_ds", (60.0, 30.0, 0.0)),
        ("kitti360_image_02", (0.0, -45.0, 0.0)),
        ("woodscape_front", (-90.0, 10.0, 5.0)),
        ("ocam_kodak_sp360", (0.0, 80.0, 0.0)),
    ],
    ids=lambda x: x if isinstance(x, str) else None,
)
def test_remapped_directions_match_the_rotated_rays(camera: CameraModel | str, angles: tuple) -> None:
    """Every output pixel sees the direction its ray has in the panorama: any lens, any orientation, seam, poles."""
    if isinstance(camera, str):
        camera = _golden(camera, 72)
    h, w = 48, 96
    rotation = gimbal_rotation(*angles)
    remap = EquirectToFisheye(camera, (h, w), rotation=rotation)
    torch.testing.assert_close(remap.valid_mask, camera.valid_mask())  # the sphere has no gap
    pano = direction_panorama(h, w)
    expected = expected_directions(camera, rotation)
    mask = remap.valid_mask
    texel = math.pi / h
    nearest = remap(pano, mode="nearest")
    assert torch.isfinite(nearest).all()
    assert (
        angular_error(nearest, expected, mask).max() <= math.sqrt(0.5) * texel + 1e-9
    )  # half a texel diagonal
    # Bilinear interpolation of unit vectors is nearly exact, across the seam and over the poles too.
    bilinear = remap(pano, mode="bilinear")
    assert torch.isfinite(bilinear).all()
    assert angular_error(bilinear, expected, mask).max() <= 0.1 * texel


def test_nearest_takes_the_texel_containing_the_ray() -> None:
    h, w = 30, 60
    camera = ideal_camera(64, 64)
    rotation = gimbal_rotation(170.0, 75.0, 0.0)  # the seam and the down pole in view
    index = torch.arange(h * w, dtype=torch.int64).view(1, h, w)
    got = EquirectToFisheye(camera, (h, w), rotation=rotation)(index, mode="nearest", fill=-1)[0]
    mask = camera.valid_mask()
    assert (got[~mask] == -1).all()
    row, col = got[mask] // w, got[mask] % w
    d = expected_directions(camera, rotation)[mask].numpy()
    lon = np.arctan2(d[:, 0], d[:, 2])
    lat = np.arctan2(-d[:, 1], np.hypot(d[:, 0], d[:, 2]))
    lon_lo = -np.pi + 2 * np.pi * col.numpy() / w
    dlon = (lon - lon_lo) % (2 * np.pi)  # within the texel's longitude span, wrapping at +-180 deg
    assert ((dlon <= 2 * np.pi / w + 1e-12) | (dlon >= 2 * np.pi - 1e-12)).all()
    lat_hi = np.pi / 2 - np.pi * row.numpy() / h
    assert ((lat <= lat_hi + 1e-12) & (lat >= lat_hi - np.pi / h - 1e-12)).all()


def test_bilinear_taps_wrap_and_cross_the_pole() -> None:
    h, w = 8, 16
    camera = ideal_camera(32, 32)
    up = EquirectToFisheye(camera, (h, w), rotation=gimbal_rotation(pitch_deg=-90.0)).table("bilinear")
    back = EquirectToFisheye(camera, (h, w), rotation=gimbal_rotation(yaw_deg=180.0)).table("bilinear")
    torch.testing.assert_close(up.weight.sum(1), torch.ones(len(up.pixels)))
    assert (up.index >= 0).all() and (up.index < h * w).all() and (back.index < h * w).all()
    # The pixel at the image centre looks straight up: its four taps all lie on the first row.
    centre = (up.pixels == 16 * 32 + 16).nonzero().item()
    assert (up.index[centre] // w == 0).all()
    # Looking back, some pixels blend the last and the first column.
    cols = back.index.long() % w
    assert ((cols == 0) & (cols.roll(1, dims=1) == w - 1)).any(dim=1).any()


def test_values_dtypes_batches_and_layouts() -> None:
    h, w = 16, 32
    remap = EquirectToFisheye(ideal_camera(24, 24), h, supersample=1)  # one int: width = 2 * height
    assert (remap.erp_height, remap.erp_width) == (16, 32)
    rng = np.random.default_rng(0)
    hwc = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    planar = torch.from_numpy(np.ascontiguousarray(hwc.transpose(2, 0, 1)))
    interleaved = torch.from_numpy(hwc).permute(2, 0, 1)  # channels-last memory, no copy
    a, b = remap(planar), remap(interleaved)
    torch.testing.assert_close(a, b, atol=1, rtol=0)  # fastmath may round a last bit the other way
    assert a.dtype == torch.uint8
    ref = _apply_torch(planar.reshape(1, 3, -1), remap.table("bilinear"))[0]
    torch.testing.assert_close(a.reshape(3, -1)[:, remap.table("bilinear").pixels], ref, atol=1, rtol=0)
    batch = torch.stack([planar, planar.flip(0)])
    torch.testing.assert_close(remap(batch)[1], remap(planar.flip(0)))
    labels = rng.integers(0, 13, (1, h, w), dtype=np.uint8)
    out = remap(labels, mode="nearest", fill=255)
    assert isinstance(out, np.ndarray) and out.shape == (1, 24, 24)
    assert set(np.unique(out[0][~remap.valid_mask.numpy()])) == {255}
    assert set(np.unique(out[0][remap.valid_mask.numpy()])) <= set(np.unique(labels))


def test_supersampling_averages_within_the_pixel() -> None:
    h, w = 64, 128
    camera = ideal_camera(16, 16)
    pano = direction_panorama(h, w)
    remap = EquirectToFisheye(camera, (h, w), rotation=gimbal_rotation(180.0, 30.0), supersample=3)
    lut = remap.table("bilinear")
    assert lut.index.shape[1] == 36
    torch.testing.assert_close(lut.weight.sum(1), torch.ones(len(lut.pixels)))
    err = angular_error(remap(pano), expected_directions(camera, remap.rotation), remap.valid_mask)
    assert (
        err.max() < math.radians(190.0) / 16 / 2
    )  # the average of a pixel's sub-rays stays within the pixel


def test_tables_are_cached_per_size_camera_rotation_and_on_disk(tmp_path: Path) -> None:
    clear_table_cache()
    camera = ideal_camera(16, 16)
    a = EquirectToFisheye(camera, 8, rotation=gimbal_rotation(10.0, 20.0), cache_dir=tmp_path)
    lut = a.table("bilinear")
    assert EquirectToFisheye(camera, 8, rotation=gimbal_rotation(10.0, 20.0)).table("bilinear") is lut
    assert EquirectToFisheye(camera, 8, rotation=gimbal_rotation(10.0, 21.0)).table("bilinear") is not lut
    assert EquirectToFisheye(camera, (8, 20)).table("bilinear") is not EquirectToFisheye(camera, 8).table(
        "bilinear"
    )
    assert EquirectToFisheye(camera, 8, rotation=np.eye(3)).table("nearest") is EquirectToFisheye(
        camera, 8
    ).table("nearest")
    assert len(list(tmp_path.glob("erp-lut-*.npz"))) == 1
    clear_table_cache()
    assert len(TABLES) == 0
    again = a.table("bilinear")  # from the disk cache
    torch.testing.assert_close(again.index, lut.index)
    torch.testing.assert_close(again.weight, lut.weight)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"erp_size": 1}, "erp_size"),
        ({"erp_size": (8, 0)}, "erp_size"),
        ({"erp_size": "big"}, "erp_size"),
        ({"erp_size": 8, "rotation": np.ones((3, 3))}, "rotation"),
        ({"erp_size": 8, "rotation": np.diag([1.0, 1.0, -1.0])}, "rotation"),
        ({"erp_size": 8, "rotation": np.eye(4)}, "rotation"),
        ({"erp_size": 8, "supersample": 0}, "supersample"),
    ],
)
def test_bad_arguments_are_named(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        EquirectToFisheye(ideal_camera(16, 16), **kwargs)


def test_bad_panorama_shape_and_mode_are_named() -> None:
    remap = EquirectToFisheye(ideal_camera(16, 16), 8)
    with pytest.raises(ValueError, match=r"erp must have shape \[C, 8, 16\]"):
        remap(torch.zeros(8, 16))
    with pytest.raises(ValueError, match="mode"):
        remap(torch.zeros(1, 8, 16), mode="cubic")
    with pytest.raises(ValueError, match="CameraModel"):
        EquirectToFisheye("fisheye", 8)  # type: ignore[arg-type]


def test_range_and_z_depth_convert_both_ways() -> None:
    camera = ideal_camera(32, 32)
    rays = camera.ray_grid(torch.float64)
    rng = torch.from_numpy(np.random.default_rng(1).uniform(1, 50, (2, 32, 32)))
    z = range_to_z_depth(rng, rays)
    front = torch.nan_to_num(rays[..., 2], 0.0) > 0
    torch.testing.assert_close(z[:, front], (rng * rays[..., 2])[:, front])
    assert (z[:, ~front] == 0).all()  # beyond 90 deg (and outside the image) a fisheye has no planar depth
    torch.testing.assert_close(z_depth_to_range(z, rays)[:, front], rng[:, front])
    assert (z_depth_to_range(torch.zeros(32, 32), rays) == 0).all()
    with pytest.raises(ValueError, match="rays"):
        range_to_z_depth(rng, rays[:8])
