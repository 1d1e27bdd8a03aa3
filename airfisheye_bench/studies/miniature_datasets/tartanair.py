"""A tiny TartanAir V2 root written in the toolkit's exact layout and encodings, from an analytic scene.

Everything here follows github:castacks/tartanairpy (commit e8535a8b) and its submodules, transcribed, never our
own geometry code (agreeing with our own generator would not be evidence):

- faces: :func:`tartanair_face_ray` inverts image_sampler ``six_images_numba.py`` ``sample_coor`` (camera frame x
  right, y down, z forward; the normalised face coordinate ``(1 + x/z) / 2`` etc.), with texel centres at
  ``(i + 0.5) / S`` (``planar_as_base.py``: ``grid_sample(align_corners=False)``); :func:`tartanair_project` is
  ``sample_coor`` itself;
- depth: float32 *planar* depth, ``depth.view("<u1")`` written by OpenCV (channel 0 -> PNG blue), i.e. PNG RGBA =
  bytes 2, 1, 0, 3 (``reader.py`` ``write_float_depth``);
- seg: 8-bit PNG of the environment's ``seg_label_map.json`` values (``{"name_map": {name: value}}``);
- LiDAR: ``lidar/<frame>_lcam_front_lidar.ply``, binary little-endian float x, y, z (mvs_utils
  ``point_cloud_helper.write_PLY``), beams of mvs_utils ``VELODYNE_VLP_16`` (elevations -15..15 every 2 deg) at a
  coarser azimuth step, in the axes ``lidar_frame`` names;
- poses: ``pose_lcam_front.txt``, ``x y z qx qy qz qw`` in NED.

The scene, in the camera frame of each frame: ground ``y = +1.5`` (road where ``x < 0``, grass elsewhere), walls
``x = +6`` (fence), ``x = -4`` (tree), ``z = +8 + frame`` (building), ``z = -5`` (chair: a name our table leaves
unmapped), all up to ``y = -3``; sky above (depth 1e4, no LiDAR return).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

FACES = ("front", "back", "left", "right", "top", "bottom")
SKY_DEPTH = 1.0e4
#: Two environments whose maps give the same names different values (TartanAir's labels are per environment).
NAME_MAPS = {
    "CoalMine": {"sky": 3, "road": 17, "grass": 40, "fence": 88, "tree": 120, "building": 59, "chair": 200},
    "OldTownFall": {"sky": 59, "road": 2, "grass": 9, "fence": 11, "tree": 240, "building": 3, "chair": 180},
}
TRAJECTORIES = ("Data_easy/P000", "Data_easy/P001", "Data_hard/P000")
VLP16_ELEVATIONS = tuple(range(-15, 16, 2))
#: Colour of each label name (RGB faces).
COLORS = {
    "sky": (70, 130, 180),
    "road": (128, 64, 128),
    "grass": (152, 251, 152),
    "fence": (190, 153, 153),
    "tree": (107, 142, 35),
    "building": (70, 70, 70),
    "chair": (250, 170, 30),
}


def tartanair_face_ray(face: str, col: np.ndarray, row: np.ndarray, size: int) -> np.ndarray:
    """Camera-frame ray (not unit; component 1 along the face's axis) through texel centres ``(col, row)``: the
    inverse of ``sample_coor`` (``a = 2u - 1``, ``b = 2v - 1`` with ``u = (col + 0.5) / S``)."""
    a = 2.0 * (np.asarray(col) + 0.5) / size - 1.0
    b = 2.0 * (np.asarray(row) + 0.5) / size - 1.0
    one = np.ones_like(a)
    return np.stack(
        {
            "front": (a, b, one),  # u = (1 + x/z)/2, v = (1 + y/z)/2
            "right": (one, b, -a),  # u = (1 - z/x)/2, v = (1 + y/x)/2
            "back": (-a, b, -one),  # u = (1 + x/z)/2, v = (1 - y/z)/2, z < 0
            "left": (-one, b, a),  # u = (1 - z/x)/2, v = (1 - y/x)/2, x < 0
            "bottom": (a, one, -b),  # u = (1 + x/y)/2, v = (1 - z/y)/2
            "top": (a, -one, b),  # u = (1 - x/y)/2, v = (1 - z/y)/2, y < 0
        }[face],
        axis=-1,
    )


def tartanair_project(point: np.ndarray, size: int) -> tuple[str, float, float]:
    """``sample_coor`` for one camera-frame point: (face, column, row) in pixels (texel centres at integers)."""
    x, y, z = (float(v) for v in point)
    q, h = np.pi / 4, 3 * np.pi / 4
    a_y, a_z, azimuth = np.arctan2(x, y), np.arctan2(z, y), np.arctan2(z, x)
    if -q < a_y < q and -q < a_z < q:
        face, u, v = "bottom", (1 + x / y) / 2, (1 - z / y) / 2
    elif (a_y > h or a_y < -h) and (a_z > h or a_z < -h):
        face, u, v = "top", (1 - x / y) / 2, (1 - z / y) / 2
    elif q <= azimuth < h:
        face, u, v = "front", (1 + x / z) / 2, (1 + y / z) / 2
    elif -q <= azimuth < q:
        face, u, v = "right", (1 - z / x) / 2, (1 + y / x) / 2
    elif -h <= azimuth < -q:
        face, u, v = "back", (1 + x / z) / 2, (1 - y / z) / 2
    else:
        face, u, v = "left", (1 - z / x) / 2, (1 - y / x) / 2
    return face, u * size - 0.5, v * size - 0.5


def scene_hit(directions: np.ndarray, frame: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(range [N], label name index [N] into COLORS' keys)`` of camera-frame directions ``[N, 3]``."""
    d = directions / np.linalg.norm(directions, axis=-1, keepdims=True)
    names = list(COLORS)
    planes = [
        (1, 1.5, None),
        (0, 6.0, "fence"),
        (0, -4.0, "tree"),
        (2, 8.0 + frame, "building"),
        (2, -5.0, "chair"),
    ]
    best = np.full(d.shape[:-1], np.inf)
    label = np.full(d.shape[:-1], names.index("sky"))
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, offset, name in planes:
            t = offset / d[..., axis]
            t = np.where(t > 0, t, np.inf)
            if name is not None:  # walls end 3 m above the camera
                t = np.where(t * d[..., 1] >= -3.0, t, np.inf)
            closer = t < best
            best = np.where(closer, t, best)
            if name is None:
                hit_x = t * d[..., 0]
                label = np.where(
                    closer, np.where(hit_x < 0, names.index("road"), names.index("grass")), label
                )
            else:
                label = np.where(closer, names.index(name), label)
    return best, label


def depth_png_bytes_order(depth: np.ndarray) -> np.ndarray:
    """``uint8 [S, S, 4]`` PNG RGBA of planar depth as OpenCV writes ``depth.view("<u1")`` (BGRA -> RGBA)."""
    raw = np.ascontiguousarray(depth.astype("<f4"))[..., None].view("<u1")
    return np.ascontiguousarray(raw[..., [2, 1, 0, 3]])


def write_ply_xyz(path: Path, points: np.ndarray) -> None:
    """A binary little-endian PLY of float x, y, z (the header ``plyfile`` writes for ``write_PLY``)."""
    header = f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
    header += "property float x\nproperty float y\nproperty float z\nend_header\n"
    path.write_bytes(header.encode("ascii") + np.ascontiguousarray(points, dtype="<f4").tobytes())


#: LiDAR axes -> rotation from the camera frame (x right, y down, z forward).
FROM_CAMERA = {
    "flu": np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]),
    "ned": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
    "camera": np.eye(3),
}


def write_frame(
    traj: Path, frame: int, name_map: dict[str, int], size: int, lidar_frame: str, azimuths: int
) -> None:
    stem = f"{frame:06d}"
    names = list(COLORS)
    values = np.array([name_map[n] for n in names], dtype=np.uint8)
    colors = np.array([COLORS[n] for n in names], dtype=np.uint8)
    rows, cols = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    for face in FACES:
        ray = tartanair_face_ray(face, cols, rows, size)
        rng, label = scene_hit(ray, frame)
        planar = np.where(np.isfinite(rng), rng / np.linalg.norm(ray, axis=-1), SKY_DEPTH).astype(np.float32)
        cam = f"lcam_{face}"
        for folder in ("image", "depth", "seg"):
            (traj / f"{folder}_{cam}").mkdir(parents=True, exist_ok=True)
        Image.fromarray(colors[label]).save(traj / f"image_{cam}" / f"{stem}_{cam}.png")
        Image.fromarray(depth_png_bytes_order(planar), "RGBA").save(
            traj / f"depth_{cam}" / f"{stem}_{cam}_depth.png"
        )
        Image.fromarray(values[label], "L").save(traj / f"seg_{cam}" / f"{stem}_{cam}_seg.png")
    # VLP-16 beams in FLU (azimuth counter-clockwise from x), cast in the camera frame, stored in lidar_frame axes.
    el = np.radians(np.array(VLP16_ELEVATIONS, dtype=np.float64))[:, None]
    az = np.radians(np.arange(azimuths) * 360.0 / azimuths - 180.0)[None, :]
    flu = np.stack(
        np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)), -1
    ).reshape(-1, 3)
    cam = flu @ FROM_CAMERA["flu"]  # FROM_CAMERA["flu"] maps camera -> FLU; its transpose maps back
    rng, _ = scene_hit(cam, frame)
    hit = np.isfinite(rng)
    points_cam = cam[hit] * rng[hit, None]
    (traj / "lidar").mkdir(exist_ok=True)
    write_ply_xyz(traj / "lidar" / f"{stem}_lcam_front_lidar.ply", points_cam @ FROM_CAMERA[lidar_frame].T)


def write_tartanair_fixture(
    root: Path,
    size: int = 48,
    frames: int = 3,
    lidar_frame: str = "ned",
    azimuths: int = 360,
    environments: tuple[str, ...] = tuple(NAME_MAPS),
) -> Path:
    """Write ``environments`` (of :data:`NAME_MAPS`) x :data:`TRAJECTORIES` x ``frames`` frames under ``root``
    (one environment: a 3-trajectory download); returns ``root``."""
    root = Path(root)
    for env in environments:
        name_map = NAME_MAPS[env]
        (root / env).mkdir(parents=True, exist_ok=True)
        (root / env / "seg_label_map.json").write_text(json.dumps({"name_map": name_map}, indent=4))
        for rel in TRAJECTORIES:
            traj = root / env / rel
            traj.mkdir(parents=True, exist_ok=True)
            for frame in range(frames):
                write_frame(traj, frame, name_map, size, lidar_frame, azimuths)
            # Frame i: i metres north, 2 m up, yawed 10 deg * i about NED z; quaternion x y z w.
            lines = []
            for i in range(frames):
                half = np.radians(10.0 * i) / 2
                lines.append(
                    f"{float(i):.6f} 0.000000 -2.000000 0.000000 0.000000 {np.sin(half):.6f} {np.cos(half):.6f}"
                )
            (traj / "pose_lcam_front.txt").write_text("\n".join(lines) + "\n")
    return root
