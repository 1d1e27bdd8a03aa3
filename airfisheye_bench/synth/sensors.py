"""Per-frame sensor simulation: cube faces, the pre-rendered fisheye, the LiDAR scan and its true visibility.

All rays are cast in the world frame by :class:`~airfisheye_bench.synth.scene.Scene`; this module only builds
them from the sensor poses and packs the results:

* **Cube faces** — ``geometry.cubemap.face_rays`` (five 90-deg pinholes in the camera frame) rotated by
  ``R_world_cam`` at the camera timestamp: RGB, raw ids and range (0 = sky).
* **Fisheye** — either ray-cast directly through the lens (``FisheyeCamera.ray_grid``: exact, the yardstick for
  the cubemap remap) or remapped from the faces with ``CubemapToFisheye`` (like the real release). Pixels outside
  the image circle are ``rgb = 0``, ``seg = 255`` (ignore), ``depth = 0``.
* **LiDAR** — ``LidarSpec.beam_directions`` from the LiDAR pose at the LiDAR timestamp; beams with no return
  within ``max_range`` are dropped. Points are stored in the LiDAR frame in beam order (channel-major).
* **Visibility** — for every LiDAR point, whether the straight segment from the *camera centre at t_cam* to the
  point (the world position where the beam hit at t_lidar) is unobstructed: an exact ray cast
  (``Scene.segment_visible``), independent of the lens field of view. Consumers AND it with
  ``FisheyeCamera.project`` validity to get "seen by the camera".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from airfisheye_bench.geometry import CubemapToFisheye, FisheyeCamera, face_rays
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.synth.classes import IGNORE_ID

#: Tolerance of the visibility test at the point's own surface: max(abs, rel * distance), in metres.
VISIBILITY_ABS_EPS = 0.02
VISIBILITY_REL_EPS = 1e-3

VISIBILITY_DEFINITION = (
    "lidar_visible/<frame>.npy[i] is True iff the straight segment from the camera centre at t_cam to LiDAR point i "
    "(its world position, hit at t_lidar) is unobstructed by scene geometry (exact ray cast; the last "
    f"max({VISIBILITY_ABS_EPS * 100:g} cm, {VISIBILITY_REL_EPS * 100:g}% of the distance) before the point, i.e. its "
    "own surface, is not tested). It ignores the lens field of view: AND it with FisheyeCamera.project(...) validity "
    "(points transformed with the motion-compensated T_cam_lidar) to get 'seen in the image'."
)


@dataclass
class FrameData:
    """Everything recorded for one frame (numpy, ready to encode).

    Attributes:
        cube_rgb: ``uint8 [5, S, S, 3]`` in ``FACE_NAMES`` order (``None`` without cube faces).
        cube_seg: ``uint8 [5, S, S]`` raw ids.
        cube_depth: ``float32 [5, S, S]`` range in metres, 0 = sky.
        fisheye_rgb: ``uint8 [H, W, 3]`` (``None`` without a fisheye image).
        fisheye_seg: ``uint8 [H, W]`` raw ids, 255 outside the image circle.
        fisheye_depth: ``float32 [H, W]`` range, 0 = sky / outside.
        lidar: ``float32 [N, 4]``: x, y, z (LiDAR frame), raw id.
        lidar_visible: ``bool [N]`` ground-truth visibility from the camera centre.
    """

    cube_rgb: np.ndarray | None
    cube_seg: np.ndarray | None
    cube_depth: np.ndarray | None
    fisheye_rgb: np.ndarray | None
    fisheye_seg: np.ndarray | None
    fisheye_depth: np.ndarray | None
    lidar: np.ndarray
    lidar_visible: np.ndarray


def to_uint8(rgb: torch.Tensor) -> torch.Tensor:
    """Display values in [0, 1] -> ``uint8`` (round half up after clamping; deterministic)."""
    return torch.floor(rgb.clamp(0.0, 1.0) * 255.0 + 0.5).to(torch.uint8)


def _rotate(R: np.ndarray, dirs: torch.Tensor) -> torch.Tensor:
    """``R [3, 3] @ d`` for directions ``[..., 3]`` in float64, returned as float32."""
    Rt = torch.as_tensor(R, dtype=torch.float64, device=dirs.device)
    return (dirs.to(torch.float64) @ Rt.T).to(torch.float32)


def _cast_camera(scene, lighting, T_world_cam: np.ndarray, dirs_cam: torch.Tensor, max_dist: float):
    """Render camera-frame directions ``[N, 3]`` from the camera pose -> (rgb uint8, raw uint8, range float32)."""
    dirs = _rotate(T_world_cam[:3, :3], dirs_cam)
    origin = torch.as_tensor(T_world_cam[:3, 3], dtype=torch.float32, device=dirs.device)
    rgb, raw, dist = scene.render(
        origin.expand_as(dirs).contiguous(), dirs.contiguous(), lighting, max_dist=max_dist
    )
    depth = torch.where(torch.isfinite(dist), dist, torch.zeros_like(dist))
    return to_uint8(rgb), raw, depth


def render_cube_faces(scene, lighting, T_world_cam: np.ndarray, face_size: int, max_dist: float = 1000.0):
    """Render the five faces: ``(rgb uint8 [5,S,S,3], seg uint8 [5,S,S], depth float32 [5,S,S])`` (numpy).

    Example:
        >>> from airfisheye_bench.synth.scene import Scene, Lighting
        >>> scene = Scene.generate("suburban", seed=0, size_m=100.0)
        >>> T = np.eye(4); T[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]; T[2, 3] = 20.0  # looking north-ish
        >>> rgb, seg, depth = render_cube_faces(scene, Lighting(), T, face_size=8)
        >>> rgb.shape, seg.dtype, bool((depth[4] > 0).all())  # the down face sees the ground everywhere
        ((5, 8, 8, 3), dtype('uint8'), True)
    """
    rays = face_rays(face_size, dtype=torch.float64, device=scene.device).reshape(-1, 3)
    rgb, raw, depth = _cast_camera(scene, lighting, T_world_cam, rays, max_dist)
    s = face_size
    return (
        rgb.reshape(5, s, s, 3).cpu().numpy(),
        raw.reshape(5, s, s).cpu().numpy(),
        depth.reshape(5, s, s).cpu().numpy(),
    )


def render_fisheye(scene, lighting, T_world_cam: np.ndarray, camera: FisheyeCamera, max_dist: float = 1000.0):
    """Ray-cast the fisheye image directly through the lens model: ``(rgb [H,W,3], seg [H,W], depth [H,W])``."""
    valid = camera.valid_mask().reshape(-1).to(scene.device)
    rays = camera.ray_grid(dtype=torch.float64, device=scene.device).reshape(-1, 3)[valid]
    rgb_v, raw_v, depth_v = _cast_camera(scene, lighting, T_world_cam, rays, max_dist)
    n = camera.height * camera.width
    rgb = torch.zeros(n, 3, dtype=torch.uint8, device=scene.device)
    seg = torch.full((n,), IGNORE_ID, dtype=torch.uint8, device=scene.device)
    depth = torch.zeros(n, dtype=torch.float32, device=scene.device)
    rgb[valid], seg[valid], depth[valid] = rgb_v, raw_v, depth_v
    h, w = camera.height, camera.width
    return (
        rgb.reshape(h, w, 3).cpu().numpy(),
        seg.reshape(h, w).cpu().numpy(),
        depth.reshape(h, w).cpu().numpy(),
    )


def remap_fisheye(
    remapper: CubemapToFisheye, cube_rgb: np.ndarray, cube_seg: np.ndarray, cube_depth: np.ndarray
):
    """Build the fisheye image from the cube faces (bilinear RGB, nearest labels and depth)."""
    rgb = remapper.remap(np.ascontiguousarray(cube_rgb.transpose(0, 3, 1, 2)), mode="bilinear", fill=0)
    seg = remapper.remap(cube_seg[:, None], mode="nearest", fill=IGNORE_ID)[0]
    depth = remapper.remap(cube_depth[:, None], mode="nearest", fill=0.0)[0]
    rgb = np.ascontiguousarray(rgb.transpose(1, 2, 0))
    return rgb, seg.astype(np.uint8), depth.astype(np.float32)


def scan_lidar(scene, T_world_lidar: np.ndarray, spec: LidarSpec) -> tuple[np.ndarray, torch.Tensor]:
    """Simulate one LiDAR scan from ``T_world_lidar``.

    Returns:
        ``points [N, 4]`` float32 (x, y, z in the LiDAR frame, raw id; only beams with a return within
        ``max_range``, in channel-major beam order) and their world positions ``[N, 3]`` (float32 tensor).
    """
    beams = spec.beam_directions(dtype=torch.float64, device=scene.device).reshape(-1, 3)
    dirs = _rotate(T_world_lidar[:3, :3], beams)
    origin = torch.as_tensor(T_world_lidar[:3, 3], dtype=torch.float32, device=scene.device).expand_as(dirs)
    hits = scene.raycast(origin.contiguous(), dirs.contiguous(), max_dist=spec.max_range)
    keep = torch.isfinite(hits.dist) & (hits.dist <= spec.max_range)
    dist = hits.dist[keep]
    local = beams[keep].to(torch.float32) * dist[:, None]
    world = origin[keep] + dirs[keep] * dist[:, None]
    points = torch.cat([local, hits.raw_id[keep].to(torch.float32)[:, None]], dim=1)
    return points.cpu().numpy(), world


def lidar_visibility(scene, camera_centre: np.ndarray, points_world: torch.Tensor) -> np.ndarray:
    """Ground-truth visibility of world points from the camera centre (see :data:`VISIBILITY_DEFINITION`)."""
    if points_world.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    origin = torch.as_tensor(camera_centre, dtype=torch.float32, device=points_world.device).expand_as(
        points_world
    )
    visible = scene.segment_visible(
        origin.contiguous(), points_world.contiguous(), rel_eps=VISIBILITY_REL_EPS, abs_eps=VISIBILITY_ABS_EPS
    )
    return visible.cpu().numpy().astype(bool)


def render_frame(
    scene,
    lighting,
    T_world_cam: np.ndarray,
    T_world_lidar: np.ndarray,
    *,
    face_size: int,
    lidar: LidarSpec,
    camera: FisheyeCamera | None = None,
    fisheye_source: str = "raycast",
    max_dist: float = 1000.0,
    remapper: CubemapToFisheye | None = None,
) -> FrameData:
    """Record one frame: cube faces (if ``face_size > 0``), fisheye (per ``fisheye_source``), LiDAR + visibility.

    Args:
        scene: The scene.
        lighting: Lighting of the trajectory.
        T_world_cam: Camera pose at the camera timestamp (float64 ``[4, 4]``).
        T_world_lidar: LiDAR pose at the LiDAR timestamp.
        face_size: Cube-face size (0: none).
        lidar: LiDAR specification.
        camera: Fisheye camera (``None``: no fisheye image).
        fisheye_source: ``raycast``, ``remap`` or ``none``.
        max_dist: Farthest camera ray distance.
        remapper: Cached ``CubemapToFisheye(camera, face_size)`` for ``remap`` (built if ``None``).
    """
    cube = (None, None, None)
    if face_size > 0:
        cube = render_cube_faces(scene, lighting, T_world_cam, face_size, max_dist)
    fish = (None, None, None)
    if camera is not None and fisheye_source == "raycast":
        fish = render_fisheye(scene, lighting, T_world_cam, camera, max_dist)
    elif camera is not None and fisheye_source == "remap":
        if cube[0] is None:
            raise ValueError("fisheye_source='remap' needs face_size > 0")
        fish = remap_fisheye(remapper or CubemapToFisheye(camera, face_size), *cube)
    elif fisheye_source not in ("none", "raycast", "remap"):
        raise ValueError(f"fisheye_source must be 'raycast', 'remap' or 'none', got {fisheye_source!r}")
    points, world = scan_lidar(scene, T_world_lidar, lidar)
    visible = lidar_visibility(scene, T_world_cam[:3, 3], world)
    return FrameData(*cube, *fish, lidar=points, lidar_visible=visible)
