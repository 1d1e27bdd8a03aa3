"""Per-frame sensor simulation: cube faces, the pre-rendered fisheye, the LiDAR scan and its true visibility.

All rays are cast in the world frame by :class:`~airfisheye_bench.synth.scene.Scene`; this module only builds
them from the sensor poses and packs the results:

* **Cube faces** — ``geometry.cubemap.face_rays`` (five 90-deg pinholes in the camera frame) rotated by
  ``R_world_cam`` at the camera timestamp: RGB, raw ids and range (0 = sky).
* **Panorama** — :func:`render_erp`: an equirectangular panorama of the camera pose (``geometry.equirect.erp_rays``
  in the camera frame), cast directly, not resampled from the faces: the reference an ERP source is checked against.
* **Fisheye** — either ray-cast directly through the lens (``CameraModel.ray_grid``: exact, the yardstick for
  the cubemap remap) or remapped from the faces with ``CubemapToFisheye`` (like the real release). Pixels outside
  the image circle are ``rgb = 0``, ``seg = 255`` (ignore), ``depth = 0``.
* **LiDAR** — ``LidarSpec.beam_directions`` from the LiDAR pose at the LiDAR timestamp, each from its laser's
  origin (``LidarSpec.beam_origins``: off the centre for a preset such as ``hdl64e``); beams with no return
  within ``max_range`` are dropped. Points are stored in the LiDAR frame in beam order (channel-major). A
  :class:`ScanModel` makes the scan look like a real spinning sensor's: a per-frame azimuth phase (the firing
  grid slides by a fraction of a column from frame to frame), per-beam angular jitter and random dropped
  returns. The ideal model (the default) casts exactly ``LidarSpec.beam_directions``.
* **Visibility** — for every LiDAR point, whether the straight segment from the *camera centre at t_cam* to the
  point (the world position where the beam hit at t_lidar) is unobstructed: an exact ray cast
  (``Scene.segment_visible``), independent of the lens field of view. Consumers AND it with
  ``CameraModel.project`` validity to get "seen by the camera".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from airfisheye_bench.geometry import CameraModel, CubemapToFisheye, face_rays, portable
from airfisheye_bench.geometry.equirect import erp_rays
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.synth.classes import IGNORE_ID

#: Tolerance of the visibility test at the point's own surface: max(abs, rel * distance), in metres.
VISIBILITY_ABS_EPS = 0.02
VISIBILITY_REL_EPS = 1e-3

# Written into every dataset.yaml, so its text is part of the datasets' content identity (tests/io/test_content.py):
# it keeps the camera's old name, FisheyeCamera (today any CameraModel), rather than change every dataset's identity.
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
        lidar_beam: ``int32 [N]`` beam each point was fired by, ``channel * N_PC + column`` (its true cell of
            ``I_LiDAR``).
        lidar_phase: Azimuth phase of the scan in radians (see :meth:`ScanModel.frame_phase`).
    """

    cube_rgb: np.ndarray | None
    cube_seg: np.ndarray | None
    cube_depth: np.ndarray | None
    fisheye_rgb: np.ndarray | None
    fisheye_seg: np.ndarray | None
    fisheye_depth: np.ndarray | None
    lidar: np.ndarray
    lidar_visible: np.ndarray
    lidar_beam: np.ndarray
    lidar_phase: float = 0.0


def to_uint8(rgb: torch.Tensor) -> torch.Tensor:
    """Display values in [0, 1] -> ``uint8`` (round half up after clamping; deterministic)."""
    return torch.floor(rgb.clamp(0.0, 1.0) * 255.0 + 0.5).to(torch.uint8)


SCAN_PHASES = ("fixed", "random", "spin")


@dataclass(frozen=True)
class ScanModel:
    """How the beams of a spinning LiDAR deviate, frame by frame, from the ideal grid of ``LidarSpec``.

    ``LidarSpec`` puts beam ``(i, j)`` at the centre of cell ``(i, j)``. A real spinning sensor (and a
    simulator's, which steps its azimuth by rotation rate x tick) fires at azimuths ``column_azimuths + phase``
    with a phase that changes every frame, its beams scatter a little about their nominal directions, and some
    returns are lost. Angles below are in cells: horizontal resolution ``HFOV / N_PC`` for azimuth, vertical
    resolution ``VFOV / (N_C - 1)`` for elevation.

    Attributes:
        phase: ``fixed`` (phase 0: the ideal grid), ``random`` (uniform in ``[-1/2, 1/2)`` cell per frame) or
            ``spin`` (a sensor turning at ``rotation_hz`` that fires on a fixed angular grid: phase
            ``2 pi rotation_hz t_lidar`` wrapped into ``[-1/2, 1/2)`` cell).
        rotation_hz: Rotation rate of ``spin``.
        jitter_cells: Standard deviations ``(azimuth, elevation)`` of the Gaussian per-beam, per-frame jitter.
        dropout: Probability that a beam gives no return (independently per beam and frame).

    Example:
        >>> from airfisheye_bench.geometry.lidar import LidarSpec
        >>> spec = LidarSpec(channels=4, points_per_channel=8)
        >>> scan = ScanModel(phase="random", jitter_cells=(0.1, 0.1), dropout=0.25)
        >>> rng = np.random.default_rng(0)
        >>> phase = scan.frame_phase(spec, t_lidar=0.0, rng=rng)
        >>> abs(phase) <= spec.horizontal_resolution / 2
        True
        >>> dirs, beam = scan.beams(spec, phase, rng)
        >>> dirs.shape[0] == len(beam) < 32, bool(torch.allclose(dirs.norm(dim=1), torch.ones(len(beam), dtype=dirs.dtype)))
        (True, True)
    """

    phase: str = "fixed"
    rotation_hz: float = 10.0
    jitter_cells: tuple[float, float] = (0.0, 0.0)
    dropout: float = 0.0

    def __post_init__(self) -> None:
        if self.phase not in SCAN_PHASES:
            raise ValueError(f"lidar_phase must be one of {SCAN_PHASES}, got {self.phase!r}")
        if not self.rotation_hz > 0:
            raise ValueError(f"lidar_rotation_hz must be positive, got {self.rotation_hz!r}")
        if len(self.jitter_cells) != 2 or min(self.jitter_cells) < 0:
            raise ValueError(
                f"lidar_jitter_cells must be two standard deviations (azimuth, elevation) >= 0, got {self.jitter_cells!r}"
            )
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"lidar_dropout must be a probability in [0, 1), got {self.dropout!r}")

    @property
    def ideal(self) -> bool:
        """Whether the beams are exactly ``LidarSpec.beam_directions`` (no phase, jitter or dropout)."""
        return self.phase == "fixed" and tuple(self.jitter_cells) == (0.0, 0.0) and self.dropout == 0.0

    def frame_phase(self, spec: LidarSpec, t_lidar: float, rng: np.random.Generator) -> float:
        """The azimuth phase (radians) of the frame scanned at ``t_lidar``; ``random`` draws first from ``rng``."""
        h = spec.horizontal_resolution
        if self.phase == "random":
            return float((rng.random() - 0.5) * h)
        if self.phase == "spin":
            angle = 2.0 * np.pi * self.rotation_hz * float(t_lidar)
            return float((angle + 0.5 * h) % h - 0.5 * h)
        return 0.0

    def beams(
        self,
        spec: LidarSpec,
        phase: float,
        rng: np.random.Generator,
        device: torch.device | str | None = None,
    ) -> tuple[torch.Tensor, np.ndarray]:
        """Unit directions ``float64 [M, 3]`` (LiDAR frame) of the beams fired this frame, and their beam index.

        The beam index is ``channel * N_PC + column`` of the nominal beam, in ascending order; dropped beams are
        left out. Draws the azimuth jitter, the elevation jitter and the dropout from ``rng``, in that order.
        """
        if self.ideal:
            dirs = spec.beam_directions(dtype=torch.float64, device=device).reshape(-1, 3)
            return dirs, np.arange(dirs.shape[0], dtype=np.int64)
        n = spec.channels * spec.points_per_channel
        el = np.repeat(spec.channel_elevations(), spec.points_per_channel)
        az = np.tile(spec.column_azimuths(), spec.channels) + phase
        az += np.repeat(spec.channel_azimuth_offsets(), spec.points_per_channel)
        sigma_az, sigma_el = self.jitter_cells
        if sigma_az > 0:
            az = az + rng.normal(0.0, sigma_az * spec.horizontal_resolution, n)
        if sigma_el > 0:
            el = el + rng.normal(0.0, sigma_el * spec.vertical_resolution, n)
        beam = np.arange(n, dtype=np.int64)
        if self.dropout > 0:
            keep = rng.random(n) >= self.dropout
            az, el, beam = az[keep], el[keep], beam[keep]
        cos_el = portable.cos(el)  # the C library's, not numpy's CPU-dependent vector kernels: see portable
        dirs = np.stack([cos_el * portable.cos(az), cos_el * portable.sin(az), portable.sin(el)], axis=-1)
        return torch.from_numpy(dirs).to(device=device), beam


def _rotate(R: np.ndarray, dirs: torch.Tensor) -> torch.Tensor:
    """``R [3, 3] @ d`` for directions ``[..., 3]`` in float64, returned as float32.

    Written as three products and two sums in a fixed order, not a matrix product: a BLAS kernel's summation order
    and fused multiply-adds depend on the CPU (MKL's AVX-512 and AVX2 paths differ in the last bit), and one bit in
    float64 can round the float32 result the other way, so the generated data would depend on the machine.
    """
    d = dirs.to(torch.float64)
    Rt = torch.as_tensor(R, dtype=torch.float64, device=dirs.device).T  # row j: how d's axis j moves
    return (d[..., 0:1] * Rt[0] + d[..., 1:2] * Rt[1] + d[..., 2:3] * Rt[2]).to(torch.float32)


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


def render_fisheye(scene, lighting, T_world_cam: np.ndarray, camera: CameraModel, max_dist: float = 1000.0):
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


def render_erp(
    scene, lighting, T_world_cam: np.ndarray, height: int, width: int | None = None, max_dist: float = 1000.0
):
    """Ray-cast an equirectangular panorama centred on the camera: ``(rgb uint8 [H,W,3], seg uint8 [H,W],
    depth float32 [H,W])``, depth the range (0 = sky).

    The panorama's frame is the camera frame of ``T_world_cam`` (the cube faces' frame): longitude 0 on the equator
    is the optical axis, the top row looks along camera ``-y`` (docs/design.md, "Equirectangular panoramas"). Cast
    directly from the scene, independent of the cube faces of the same pose.

    Example:
        >>> from airfisheye_bench.synth.scene import Scene, Lighting
        >>> scene = Scene.generate("suburban", seed=0, size_m=100.0)
        >>> T = np.eye(4); T[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]; T[2, 3] = 20.0  # level, looking north
        >>> rgb, seg, depth = render_erp(scene, Lighting(), T, height=8)
        >>> rgb.shape, bool((depth[-1] > 0).all()), bool((depth[0] == 0).all())  # ground below, sky above
        ((8, 16, 3), True, True)
    """
    width = 2 * height if width is None else width
    rays = erp_rays(height, width, dtype=torch.float64, device=scene.device).reshape(-1, 3)
    rgb, raw, depth = _cast_camera(scene, lighting, T_world_cam, rays, max_dist)
    return (
        rgb.reshape(height, width, 3).cpu().numpy(),
        raw.reshape(height, width).cpu().numpy(),
        depth.reshape(height, width).cpu().numpy(),
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


def scan_lidar(
    scene,
    T_world_lidar: np.ndarray,
    spec: LidarSpec,
    scan: ScanModel | None = None,
    phase: float = 0.0,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, torch.Tensor, np.ndarray]:
    """Simulate one LiDAR scan from ``T_world_lidar``.

    Args:
        scene: The scene.
        T_world_lidar: LiDAR pose at the LiDAR timestamp.
        spec: LiDAR specification.
        scan: Deviations from the ideal beam grid (``None``: ideal).
        phase: This frame's azimuth phase (:meth:`ScanModel.frame_phase`).
        rng: Source of the frame's jitter and dropout (needed unless ``scan`` is ideal).

    Returns:
        ``points [N, 4]`` float32 (x, y, z in the LiDAR frame, raw id; only beams with a return within
        ``max_range``, in channel-major beam order), their world positions ``[N, 3]`` (float32 tensor) and
        their beam indices ``int32 [N]`` (``channel * N_PC + column``).
    """
    scan = scan or ScanModel()
    if not scan.ideal and rng is None:
        raise ValueError("scan_lidar needs an rng for a scan model with phase, jitter or dropout")
    beams, beam_index = scan.beams(spec, phase, rng, device=scene.device)
    dirs = _rotate(T_world_lidar[:3, :3], beams)
    centre = torch.as_tensor(T_world_lidar[:3, 3], dtype=torch.float32, device=scene.device)
    if spec.beam_origins_m is None:
        start = torch.zeros_like(dirs)
        origin = centre.expand_as(dirs)
    else:  # each laser's beam starts where the spec puts it (e.g. 0.2 m above an HDL-64E's base)
        d = beams.cpu().numpy()
        start_np = spec.beam_origins(
            portable.arctan2(d[:, 1], d[:, 0]), beam_index // spec.points_per_channel
        )
        start = torch.from_numpy(start_np).to(device=scene.device, dtype=torch.float32)
        origin = centre + _rotate(T_world_lidar[:3, :3], start.to(torch.float64))
    hits = scene.raycast(origin.contiguous(), dirs.contiguous(), max_dist=spec.max_range)
    keep = torch.isfinite(hits.dist) & (hits.dist <= spec.max_range)
    dist = hits.dist[keep]
    local = start[keep] + beams[keep].to(torch.float32) * dist[:, None]
    world = origin[keep] + dirs[keep] * dist[:, None]
    points = torch.cat([local, hits.raw_id[keep].to(torch.float32)[:, None]], dim=1)
    return points.cpu().numpy(), world, beam_index[keep.cpu().numpy()].astype(np.int32)


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
    camera: CameraModel | None = None,
    fisheye_source: str = "raycast",
    max_dist: float = 1000.0,
    remapper: CubemapToFisheye | None = None,
    scan: ScanModel | None = None,
    scan_phase: float = 0.0,
    scan_rng: np.random.Generator | None = None,
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
        scan: LiDAR deviations from the ideal grid (``None``: ideal), see :class:`ScanModel`.
        scan_phase: The frame's azimuth phase.
        scan_rng: Source of the frame's jitter and dropout.
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
    points, world, beam = scan_lidar(scene, T_world_lidar, lidar, scan, scan_phase, scan_rng)
    visible = lidar_visibility(scene, T_world_cam[:3, 3], world)
    return FrameData(
        *cube, *fish, lidar=points, lidar_visible=visible, lidar_beam=beam, lidar_phase=scan_phase
    )
