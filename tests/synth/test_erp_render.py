"""The generator's panorama (``synth.sensors.render_erp``) against its cube faces of the same pose.

Both are ray-cast from the scene, independently; remapped to one 512^2, 190-deg fisheye (nearest, the depth and
label rule of both sources) they must describe the same surfaces: this checks the ERP convention end to end (a
wrong axis, a mirrored column order or a flipped pole would put other surfaces under the pixels) and the ERP
sampler against the cube sampler, with the fisheye ray-cast through the lens as the yardstick of both.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry import CubemapToFisheye, EquirectToFisheye, ideal_camera
from airfisheye_bench.geometry.transforms import CAM_FROM_FLU, euler_to_matrix
from airfisheye_bench.synth.scene import Lighting, Scene
from airfisheye_bench.synth.sensors import render_cube_faces, render_erp, render_fisheye

pytestmark = pytest.mark.integration

# Sources at the fisheye's resolution: 512 px over 190 deg is 2.7 px/deg; a 256^2 face has 2.8 px/deg at its
# centre, a 512-row panorama 2.8 px/deg.
FACE_SIZE, ERP_HEIGHT, SIZE = 256, 512, 512


@pytest.fixture(scope="module")
def rendered() -> dict[str, np.ndarray]:
    torch.set_num_threads(1)
    scene = Scene.generate("suburban", seed=0, size_m=120.0)
    # A drone 25 m up looking north, its gimbal pitched 30 deg down (docs/design.md, the synthetic rig).
    R_world_body = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, :3] = R_world_body @ euler_to_matrix(0.0, np.radians(30.0), 0.0) @ CAM_FROM_FLU.T
    T[:3, 3] = (0.0, 0.0, 25.0)
    camera = ideal_camera(SIZE, SIZE)
    _, cube_seg, cube_depth = render_cube_faces(scene, Lighting(), T, FACE_SIZE)
    _, erp_seg, erp_depth = render_erp(scene, Lighting(), T, ERP_HEIGHT)
    _, ray_seg, ray_depth = render_fisheye(scene, Lighting(), T, camera)
    cube = CubemapToFisheye(camera, FACE_SIZE)
    erp = EquirectToFisheye(camera, ERP_HEIGHT)
    return {
        "mask": camera.valid_mask().numpy(),
        "cube_depth": cube(cube_depth[:, None], "nearest")[0],
        "cube_seg": cube(cube_seg[:, None], "nearest", fill=255)[0],
        "erp_depth": erp(erp_depth[None], "nearest")[0],
        "erp_seg": erp(erp_seg[None], "nearest", fill=255)[0],
        "ray_depth": ray_depth,
        "ray_seg": ray_seg,
    }


def _agreement(r: dict[str, np.ndarray], a: str, b: str) -> tuple[float, float]:
    """(median relative depth difference where both see a surface, fraction of equal labels) inside the circle."""
    m = r["mask"]
    da, db = r[f"{a}_depth"], r[f"{b}_depth"]
    both = m & (da > 0) & (db > 0)
    rel = np.abs(da[both] - db[both]) / db[both]
    return float(np.median(rel)), float((r[f"{a}_seg"] == r[f"{b}_seg"])[m].mean())


def test_erp_and_cube_fisheyes_agree(rendered: dict[str, np.ndarray]) -> None:
    m = rendered["mask"]
    assert ((rendered["erp_depth"] > 0) == (rendered["cube_depth"] > 0))[m].mean() > 0.99  # the same sky
    assert len(np.unique(rendered["erp_seg"][m])) >= 5  # a street scene, not one surface
    depth, labels = _agreement(rendered, "erp", "cube")
    # Measured 0.17 % and 98.4 %: the two nearest samplings disagree only along edges (a texel's width).
    assert depth < 0.01
    assert labels >= 0.98


def test_both_sources_agree_with_the_fisheye_cast_through_the_lens(rendered: dict[str, np.ndarray]) -> None:
    erp = _agreement(rendered, "erp", "ray")
    cube = _agreement(rendered, "cube", "ray")
    # The panorama is as close to the exact image as the cube faces are (measured: within 0.2 % of each other).
    assert erp[0] < 0.01 and cube[0] < 0.01
    assert erp[1] >= 0.98 and cube[1] >= 0.98
    assert erp[1] >= cube[1] - 0.01
