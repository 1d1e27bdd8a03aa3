"""Cubemap -> fisheye remap, checked against geometry it does not compute itself."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry import (
    FACE_NAMES,
    CameraModel,
    CubemapToFisheye,
    face_rays,
    face_rotation,
    ideal_camera,
)
from airfisheye_bench.geometry.cubemap import clear_table_cache, direction_to_face
from airfisheye_bench.geometry.remap_table import _apply_torch
from airfisheye_bench.geometry.transforms import gimbal_rotation


def direction_faces(face_size: int) -> torch.Tensor:
    """Faces whose texels hold their own viewing direction (camera frame): ``[5, 3, S, S]``.

    Built from the docs/design.md axis table directly, not from ``face_rays``.
    """
    axes = {  # face: (x axis, y axis, z axis) in the camera frame
        "front": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
        "left": ((0, 0, 1), (0, 1, 0), (-1, 0, 0)),
        "right": ((0, 0, -1), (0, 1, 0), (1, 0, 0)),
        "up": ((1, 0, 0), (0, 0, 1), (0, -1, 0)),
        "down": ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
    }
    s = face_size
    t = (np.arange(s) - (s - 1) / 2) / (s / 2)  # tan of the angle from the face axis at each texel centre
    ty, tx = np.meshgrid(t, t, indexing="ij")
    faces = []
    for name in FACE_NAMES:
        ax, ay, az = (np.array(a, dtype=np.float64) for a in axes[name])
        d = tx[..., None] * ax + ty[..., None] * ay + az
        faces.append(d / np.linalg.norm(d, axis=-1, keepdims=True))
    return torch.from_numpy(np.stack(faces)).permute(0, 3, 1, 2).contiguous()


def angular_error(image: torch.Tensor, camera: CameraModel, mask: torch.Tensor) -> torch.Tensor:
    d = image.permute(1, 2, 0)[mask].double()
    d = d / d.norm(dim=-1, keepdim=True)
    ref = camera.ray_grid(torch.float64)[mask]
    return torch.acos((d * ref).sum(-1).clamp(-1, 1))


def test_face_rotations_match_design_table() -> None:
    looks = {"front": (0, 0, 1), "left": (-1, 0, 0), "right": (1, 0, 0), "up": (0, -1, 0), "down": (0, 1, 0)}
    for name in FACE_NAMES:
        R = face_rotation(name)
        np.testing.assert_array_equal(R[:, 2], looks[name])
        assert np.isclose(np.linalg.det(R), 1.0)
    torch.testing.assert_close(face_rays(6, torch.float64), direction_faces(6).permute(0, 2, 3, 1))


@pytest.mark.parametrize(
    "camera",
    [
        ideal_camera(96, 96),
        ideal_camera(80, 64, fov_deg=230.0, model="equisolid"),
        ideal_camera(96, 96, model="kannala_brandt", k=(0.05, -0.01, 0.002, -0.0003)),
        ideal_camera(64, 64, fov_deg=180.0, model="orthographic"),
    ],
    ids=["equidistant190", "equisolid230", "kb190", "ortho180"],
)
@pytest.mark.parametrize("face_size", [24, 48])
def test_remapped_directions_match_unproject(camera: CameraModel, face_size: int) -> None:
    """Each output pixel must see the direction the camera model assigns to it."""
    remap = CubemapToFisheye(camera, face_size)
    faces = direction_faces(face_size)
    mask = remap.valid_mask
    torch.testing.assert_close(
        mask, camera.valid_mask()
    )  # FOV <= 250 deg: every ray in the circle hits a face
    texel = 2.0 / face_size  # angular size of one texel at a face centre (the largest)
    nearest_err = angular_error(remap(faces, mode="nearest"), camera, mask)
    assert nearest_err.max() <= math.sqrt(0.5) * texel  # at most half a texel diagonal
    # Bilinear interpolation of unit vectors is nearly exact, including across face borders (no seams).
    bilinear_err = angular_error(remap(faces, mode="bilinear"), camera, mask)
    assert bilinear_err.max() <= 0.25 * texel


def test_supersampling_averages_the_subpixel_footprint() -> None:
    camera = ideal_camera(48, 48)
    face_size = 96
    faces = direction_faces(face_size)
    plain = CubemapToFisheye(camera, face_size)(faces)
    smooth = CubemapToFisheye(camera, face_size, supersample=3)(faces)
    mask = camera.valid_mask()
    # The mean of directions over a pixel's footprint still points at the pixel centre's ray.
    assert angular_error(smooth, camera, mask).max() <= 2.0 / face_size
    # Antialiasing: on a checkerboard finer than the output, supersampling reduces aliasing (variance).
    s = face_size
    checker = ((torch.arange(s)[:, None] + torch.arange(s)[None]) % 2).float().expand(5, 1, s, s)
    aliased = CubemapToFisheye(camera, face_size)(checker)[0][mask]
    filtered = CubemapToFisheye(camera, face_size, supersample=4)(checker)[0][mask]
    assert filtered.std() < 0.5 * aliased.std()
    assert abs(filtered.mean().item() - 0.5) < 0.05
    assert plain.shape == smooth.shape


def test_nearest_copies_values_and_fills_outside() -> None:
    camera = ideal_camera(64, 64)
    remap = CubemapToFisheye(camera, 16)
    labels = torch.arange(5, dtype=torch.uint8).view(5, 1, 1, 1).expand(5, 1, 16, 16).contiguous()
    out = remap(labels, mode="nearest", fill=255)
    assert out.dtype == torch.uint8 and out.shape == (1, 64, 64)
    mask = remap.valid_mask
    assert (out[0][~mask] == 255).all()
    assert set(out[0][mask].unique().tolist()) == {0, 1, 2, 3, 4}
    # The centre pixel looks straight ahead (front face); the top row centre looks up.
    assert out[0, 32, 32] == FACE_NAMES.index("front")
    assert out[0, 1, 32] == FACE_NAMES.index("up")
    assert out[0, 32, 62] == FACE_NAMES.index("right")


def test_bilinear_is_seamless_on_a_constant_image() -> None:
    remap = CubemapToFisheye(ideal_camera(128, 128), 20)
    out = remap(torch.full((5, 3, 20, 20), 200, dtype=torch.uint8))
    mask = remap.valid_mask
    assert (out[:, mask] == 200).all()
    assert (out[:, ~mask] == 0).all()


def test_nearest_is_an_exact_copy_for_any_dtype() -> None:
    remap = CubemapToFisheye(ideal_camera(32, 32), 8)
    lut = remap.table("nearest")
    for dtype in (torch.float64, torch.int64, torch.int32, torch.float32):
        faces = (torch.rand(5, 2, 8, 8, dtype=torch.float64) * 2**40 + 1e-7).to(dtype)
        out = remap(faces, mode="nearest").reshape(2, -1)[:, lut.pixels]
        ref = _apply_torch(faces.transpose(0, 1).reshape(1, 2, -1), lut)[0]
        assert out.dtype == dtype
        assert torch.equal(out, ref)
        assert set(out.flatten().tolist()) <= set(faces.flatten().tolist())


def test_batched_and_numpy_inputs() -> None:
    remap = CubemapToFisheye(ideal_camera(40, 40), 12)
    batch = torch.rand(3, 5, 2, 12, 12)
    out = remap(batch)
    assert out.shape == (3, 2, 40, 40)
    torch.testing.assert_close(out[1], remap(batch[1]))
    out_np = remap(batch.numpy(), mode="nearest")
    assert isinstance(out_np, np.ndarray) and out_np.shape == (3, 2, 40, 40)


def test_device_agnostic_path_agrees_with_the_cpu_kernel() -> None:
    remap = CubemapToFisheye(ideal_camera(64, 64, fov_deg=250.0), 16, supersample=2)
    faces = torch.randint(0, 256, (5, 3, 16, 16), dtype=torch.uint8)
    lut = remap.table("bilinear")
    reference = _apply_torch(faces.transpose(0, 1).reshape(1, 3, -1), lut)
    channels_last = (
        faces.permute(0, 2, 3, 1).contiguous().permute(0, 3, 1, 2)
    )  # same values, interleaved memory
    for layout in (faces, channels_last):
        kernel = remap(layout).reshape(1, 3, -1)[..., lut.pixels]
        assert (kernel.int() - reference.int()).abs().max() <= 1  # float rounding order only


def test_fov_beyond_the_five_faces_leaves_the_back_empty() -> None:
    camera = ideal_camera(64, 64, fov_deg=300.0)
    remap = CubemapToFisheye(camera, 16)
    mask = remap.valid_mask
    assert mask.sum() < camera.valid_mask().sum()  # part of the circle looks into the missing back face
    face, _, _ = direction_to_face(camera.ray_grid(torch.float64)[camera.valid_mask() & ~mask], 16)
    assert (face == -1).all()


def test_tables_are_cached_in_memory_and_on_disk(tmp_path) -> None:
    camera = ideal_camera(32, 32)
    a = CubemapToFisheye(camera, 8, cache_dir=tmp_path)
    b = CubemapToFisheye(ideal_camera(32, 32), 8)
    assert a.table("bilinear") is b.table("bilinear")
    assert len(list(tmp_path.glob("cubemap-lut-*.npz"))) == 1
    clear_table_cache()
    loaded = CubemapToFisheye(camera, 8, cache_dir=tmp_path).table("bilinear")  # read back from disk
    clear_table_cache()
    built = CubemapToFisheye(camera, 8).table("bilinear")  # built afresh
    assert loaded is not built
    torch.testing.assert_close(loaded.pixels, built.pixels)
    torch.testing.assert_close(loaded.index, built.index)
    torch.testing.assert_close(loaded.weight, built.weight)


def test_bad_inputs() -> None:
    remap = CubemapToFisheye(ideal_camera(32, 32), 8)
    with pytest.raises(ValueError, match=r"faces must have shape \[5, C, 8, 8\]"):
        remap(torch.zeros(6, 3, 8, 8))
    with pytest.raises(ValueError, match=r"faces must have shape"):
        remap(torch.zeros(5, 3, 8, 9))
    with pytest.raises(ValueError, match="mode"):
        remap(torch.zeros(5, 3, 8, 8), mode="bicubic")
    with pytest.raises(ValueError, match="face_size"):
        CubemapToFisheye(ideal_camera(32, 32), 1)
    with pytest.raises(ValueError, match="supersample"):
        CubemapToFisheye(ideal_camera(32, 32), 8, supersample=0)
    with pytest.raises(ValueError, match="ideal_camera"):
        CubemapToFisheye("cam", 8)


@pytest.mark.parametrize("angles", [(0.0, 45.0, 0.0), (30.0, 20.0, 10.0), (-20.0, -30.0, 0.0)])
def test_rotated_camera_sees_the_rotated_rays(angles: tuple[float, float, float]) -> None:
    """A virtual gimbal: with ``rotation = R_cube_cam`` each pixel sees its ray turned into the cube's frame."""
    camera, face_size = ideal_camera(64, 64, fov_deg=150.0), 32
    rotation = gimbal_rotation(*angles)
    remap = CubemapToFisheye(camera, face_size, rotation=rotation)
    assert remap.table("bilinear") is not CubemapToFisheye(camera, face_size).table("bilinear")
    mask = remap.valid_mask
    expected = camera.ray_grid(torch.float64) @ torch.from_numpy(rotation).T
    d = remap(direction_faces(face_size)).permute(1, 2, 0)[mask]
    err = torch.acos((d / d.norm(dim=-1, keepdim=True) * expected[mask]).sum(-1).clamp(-1, 1))
    assert err.max() <= 0.25 * 2.0 / face_size
    # A camera tilted 45 deg down with a 150 deg field of view stays off the missing back face.
    assert int(mask.sum()) == int(camera.valid_mask().sum())
