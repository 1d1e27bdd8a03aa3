"""The generator's ray-cast fisheye and its cube-face route both follow a calibrated lens (KITTI-360 image_02, MEI)."""

from __future__ import annotations

import numpy as np

from airfisheye_bench.geometry import CubemapToFisheye, camera_from_dict
from airfisheye_bench.synth.scene import Lighting, Scene
from airfisheye_bench.synth.sensors import remap_fisheye, render_cube_faces, render_fisheye
from tests.helpers.camera_tester import CALIBRATIONS


def test_raycast_and_cubemap_fisheye_agree_through_a_kitti360_lens() -> None:
    cam = camera_from_dict(CALIBRATIONS["kitti360_image_02"]["camera"]).resized(70, 70)
    scene = Scene.generate("suburban", seed=0, size_m=100.0)
    T = np.eye(4)
    T[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]  # looking along the world's x axis, level
    T[2, 3] = 20.0
    _, seg_ray, depth_ray = render_fisheye(scene, Lighting(), T, cam)
    faces = render_cube_faces(scene, Lighting(), T, face_size=96)
    _, seg_cube, depth_cube = remap_fisheye(CubemapToFisheye(cam, 96), *faces)
    valid = cam.valid_mask().numpy()
    assert (
        not valid[0, 0] and valid.mean() > 0.8
    )  # the corners lie outside the MEI model: nothing rendered there
    assert (depth_ray[~valid] == 0).all()
    both = valid & (depth_ray > 0) & (depth_cube > 0)
    assert both.mean() > 0.3  # ground and buildings below the horizon
    # Nearest-texel depth from 96^2 faces vs the exact ray: the same surfaces, up to texel-size edges.
    close = np.abs(depth_cube[both] - depth_ray[both]) <= 0.05 * depth_ray[both]
    assert close.mean() > 0.9
    assert (seg_cube[both] == seg_ray[both]).mean() > 0.9
