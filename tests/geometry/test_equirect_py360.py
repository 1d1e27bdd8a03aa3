"""``EquirectToFisheye`` against py360convert's ``e2c`` and ``e2p`` on the same panorama (a live comparison; extra
``test-ref``).

Conventions, read from py360convert 1.0.4 (``utils.py``): its frame is x right, **y up**, z forward; ``xyz2uv`` gives
``u = atan2(x, z)`` and ``v = atan2(y, hypot(x, z))``, and ``uv2coor`` puts them at pixel
``((u / 2 pi + 0.5) W - 0.5, (-v / pi + 0.5) H - 0.5)`` with pixel centres on integers: exactly our longitude,
latitude and pixel convention (docs/design.md, "Equirectangular panoramas"; our y points down, so their ``y`` is
our ``-y``). Its sampler pads the panorama with the first and last rows rolled by ``W // 2`` (across the pole) and
the columns wrapped: our bilinear taps.

- ``e2c`` faces (``xyzcube``: F R B L U D, texel centres ``linspace(-0.5, 0.5, face_w)`` on a cube of side 1) are
  our faces' axes (``face_rotation``: front, right, left, up, down; back = camera -x, +y, -z), but with the first
  and last texel centres *on* the face's edges: a pinhole of focal ``(S - 1) / 2``, not ``S / 2``.
- ``e2p(u_deg, v_deg, in_rot_deg)`` (``xyzpers``: ``linspace(-tan(fov/2), tan(fov/2), n)``, rows top-down, rotated
  ``d @ Rx(v) @ Ry(-u) @ Ri``) is a pinhole of focal ``(n - 1) / (2 tan(fov / 2))`` centred at ``(n - 1) / 2``,
  turned by ``Ry(u) Rx(v) Rz(in_rot)`` in our axes, which is ``gimbal_rotation(yaw=-u_deg, pitch=-v_deg,
  roll=in_rot_deg)``: their u is positive to the right and v up; our yaw is positive to the left and pitch down.

Tolerances. Both sides interpolate bilinearly on the same grid, so any offset or mirroring would show as a
difference of the order of the image's contrast (the panorama is uniform noise in [0, 1]). py360convert samples with
``cv2.remap`` when OpenCV is installed, with ``CV_16SC2`` maps: coordinates rounded to 1/32 texel (at most 1/64 per
axis) and weights in fixed point, so on noise whose neighbours differ by up to 1 the two agree to 1/64 + 1/64 = 1/32
plus float32 rounding (measured: 0.018 at most, 0.003 on average); with OpenCV hidden it runs
``scipy.ndimage.map_coordinates`` in double precision, and the only difference left is its float32 coordinates
(bound 1e-4; measured 7.5e-6). Nearest labels: equal everywhere.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from airfisheye_bench.geometry import EquirectToFisheye, camera_from_dict
from airfisheye_bench.geometry.cube_depth import six_face_rotation
from airfisheye_bench.geometry.transforms import gimbal_rotation

py360 = pytest.importorskip("py360convert", reason="py360convert (extra test-ref) not installed")
py360_utils = pytest.importorskip("py360convert.utils")

# Not a multiple of 8: with W = 128 the faces' edge texels (45 deg) fall exactly halfway between two panorama
# columns, where nearest may round either way.
H, W = 66, 132
# py360convert's face keys -> our six faces (cube_depth's names; "back" is the face the remap omits).
FACES = {"F": "front", "R": "right", "B": "back", "L": "left", "U": "up", "D": "down"}


@pytest.fixture(params=["cv2", "scipy"])
def backend(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> float:
    """Which sampler py360convert runs, and the tolerance it allows (module docstring)."""
    if request.param == "cv2":
        if py360_utils.cv2 is None:
            pytest.skip("OpenCV not installed: py360convert samples with scipy only")
        return 1 / 32 + 1e-5
    monkeypatch.setattr(py360_utils, "cv2", None)
    for sampler in (py360_utils.EquirecSampler.from_cubemap, py360_utils.EquirecSampler.from_perspective):
        sampler.cache_clear()  # its samplers are cached with the backend they were built with
    return 1e-4


def panorama() -> np.ndarray:
    return np.random.default_rng(0).uniform(0, 1, (H, W)).astype(np.float32)


def pinhole(width: int, height: int, fx: float, fy: float) -> object:
    return camera_from_dict(
        {
            "model": "pinhole_radtan",
            "width": width,
            "height": height,
            "fx": fx,
            "fy": fy,
            "cx": (width - 1) / 2,
            "cy": (height - 1) / 2,
        }
    )


@pytest.mark.parametrize("face_w", [24, 33])
def test_cube_faces_match_e2c(backend: float, face_w: int) -> None:
    erp = panorama()
    theirs = py360.e2c(erp, face_w=face_w, mode="bilinear", cube_format="dict")
    camera = pinhole(face_w, face_w, (face_w - 1) / 2, (face_w - 1) / 2)
    worst = 0.0
    for key, name in FACES.items():
        ours = EquirectToFisheye(camera, (H, W), rotation=six_face_rotation(name))(erp[None])[0]
        worst = max(worst, float(np.abs(ours - theirs[key]).max()))
    assert worst <= backend, f"largest difference {worst:.3g} on the six faces"


@pytest.mark.parametrize(
    ("fov_deg", "u_deg", "v_deg", "in_rot_deg", "out_hw"),
    [
        (90.0, 0.0, 0.0, 0.0, (32, 32)),
        ((100.0, 70.0), 35.0, -20.0, 0.0, (30, 40)),
        (80.0, 180.0, 10.0, 0.0, (32, 32)),  # across the +-180 deg seam
        (60.0, -100.0, 85.0, 25.0, (33, 31)),  # over the up pole, rolled
        (120.0, 10.0, -90.0, -40.0, (32, 32)),  # straight down
    ],
)
def test_perspective_matches_e2p(
    backend: float, fov_deg, u_deg: float, v_deg: float, in_rot_deg: float, out_hw
):
    erp = panorama()
    theirs = py360.e2p(erp, fov_deg, u_deg, v_deg, out_hw, in_rot_deg=in_rot_deg, mode="bilinear")
    h_fov, v_fov = (fov_deg, fov_deg) if isinstance(fov_deg, float) else fov_deg
    h, w = out_hw
    camera = pinhole(
        w,
        h,
        (w - 1) / (2 * math.tan(math.radians(h_fov) / 2)),
        (h - 1) / (2 * math.tan(math.radians(v_fov) / 2)),
    )
    rotation = gimbal_rotation(yaw_deg=-u_deg, pitch_deg=-v_deg, roll_deg=in_rot_deg)
    ours = EquirectToFisheye(camera, (H, W), rotation=rotation)(erp[None])[0]
    assert float(np.abs(ours - theirs).max()) <= backend


def test_nearest_labels_match_e2c(backend: float) -> None:
    labels = np.random.default_rng(1).integers(0, 20, (H, W)).astype(np.uint8)
    face_w = 40
    theirs = py360.e2c(labels, face_w=face_w, mode="nearest", cube_format="dict")
    camera = pinhole(face_w, face_w, (face_w - 1) / 2, (face_w - 1) / 2)
    equal = [
        EquirectToFisheye(camera, (H, W), rotation=six_face_rotation(name))(labels[None], mode="nearest")[0]
        == theirs[key]
        for key, name in FACES.items()
    ]
    # Only a texel centre exactly halfway between two panorama texels may round either way.
    assert np.mean(equal) >= 0.999
