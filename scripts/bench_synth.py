"""Benchmark the synthetic scene renderer: camera rays (shaded), LiDAR rays, visibility rays and whole frames.

A *frame* is what the generator records per time step: the five ``S x S`` cube faces rendered with shading
(RGB + raw class + range), one LiDAR scan (``channels x points_per_channel`` beams, nearest hit) and the
ground-truth camera visibility of every LiDAR return (``Scene.segment_visible``). Poses are random drone
views (altitude 10-65 m, gimbal pitch 0-45 deg down, random heading), seeded, the same for every run.

Prints a markdown table (min over repeats of wall-clock time, per environment).

Usage:
    python scripts/bench_synth.py                       # 256^2 faces, 64x2048 LiDAR, 1 thread
    python scripts/bench_synth.py --threads 2 --face-size 256 --frames 4 --envs suburban downtown
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

from airfisheye_bench.geometry.cubemap import face_rays
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.synth.scene import ENVIRONMENTS, Lighting, Scene


def camera_rotation(yaw: float, pitch: float) -> torch.Tensor:
    """``R_world_cam`` (OpenCV camera) looking along heading ``yaw`` (from +x, CCW), tilted ``pitch`` down."""
    fwd = torch.tensor([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), -math.sin(pitch)])
    right = torch.tensor([math.sin(yaw), -math.cos(yaw), 0.0])
    down = torch.linalg.cross(fwd, right)
    return torch.stack([right, down, fwd], dim=1)


def level_rotation(yaw: float) -> torch.Tensor:
    """``R_world_lidar`` of a level LiDAR (x forward, y left, z up) heading along ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    return torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def random_poses(scene: Scene, n: int, seed: int = 0) -> list[tuple[torch.Tensor, float, float]]:
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = scene.bounds
    out = []
    for _ in range(n):
        x, y = rng.uniform(x0 * 0.7, x1 * 0.7), rng.uniform(y0 * 0.7, y1 * 0.7)
        z = float(scene.obstacle_height(torch.tensor([[x, y]], dtype=torch.float32), 3.0)[0]) + rng.uniform(
            10.0, 65.0
        )
        out.append(
            (
                torch.tensor([x, y, z], dtype=torch.float32),
                rng.uniform(0, 2 * math.pi),
                math.radians(rng.uniform(0, 45)),
            )
        )
    return out


CPU_SECONDS = [0.0]  # process CPU time of the best runs (all threads), for a load-independent figure


def timed(fn, repeats: int) -> tuple[float, object]:
    """Best wall-clock time over ``repeats`` runs (the CPU time of that run is added to CPU_SECONDS)."""
    best, best_cpu, out = float("inf"), 0.0, None
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        dt = time.perf_counter() - t
        if dt < best:
            best, best_cpu = dt, time.process_time() - c
    CPU_SECONDS[0] += best_cpu
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--envs", nargs="+", default=list(ENVIRONMENTS), choices=ENVIRONMENTS)
    parser.add_argument("--face-size", type=int, default=256)
    parser.add_argument("--channels", type=int, default=64)
    parser.add_argument("--points-per-channel", type=int, default=2048)
    parser.add_argument("--frames", type=int, default=3, help="poses per environment")
    parser.add_argument("--repeats", type=int, default=2, help="timing repeats per pose (min is kept)")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--size-m", type=float, default=400.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)

    cam_rays = face_rays(args.face_size).reshape(-1, 3)
    spec = LidarSpec(channels=args.channels, points_per_channel=args.points_per_channel)
    beams = spec.beam_directions().reshape(-1, 3)
    light = Lighting.random(torch.Generator().manual_seed(args.seed))
    n_cam, n_lidar = cam_rays.shape[0], beams.shape[0]

    print(
        f"faces 5x{args.face_size}^2 ({n_cam} camera rays), LiDAR {args.channels}x{args.points_per_channel} "
        f"({n_lidar} beams), torch threads {args.threads}, {args.frames} poses x {args.repeats} repeats (min)\n"
    )
    print(
        "| environment | primitives | build s | camera rays/s (shaded) | LiDAR rays/s | visibility rays/s "
        "| frames/s | CPU s/frame |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for env in args.envs:
        t_build, scene = timed(lambda env=env: Scene.generate(env, args.seed, size_m=args.size_m), 1)
        t_cam = t_lidar = t_vis = 0.0
        n_vis = 0
        CPU_SECONDS[0] = 0.0
        for pos, yaw, pitch in random_poses(scene, args.frames, args.seed):
            dirs = (cam_rays @ camera_rotation(yaw, pitch).T).contiguous()
            origin = pos.expand(n_cam, 3).contiguous()
            dt, _ = timed(lambda s=scene, d=dirs, o=origin: s.render(o, d, light), args.repeats)
            t_cam += dt
            ldirs = (beams @ level_rotation(yaw).T).contiguous()
            lorig = pos.expand(n_lidar, 3).contiguous()
            dt, hits = timed(lambda s=scene, d=ldirs, o=lorig: s.raycast(o, d, spec.max_range), args.repeats)
            t_lidar += dt
            keep = torch.isfinite(hits.dist)
            pts = (lorig[keep] + ldirs[keep] * hits.dist[keep, None]).contiguous()
            cam_o = (pos + torch.tensor([0.0, 0.0, -0.1])).expand_as(pts).contiguous()
            dt, _ = timed(lambda s=scene, p=pts, o=cam_o: s.segment_visible(o, p), args.repeats)
            t_vis += dt
            n_vis += pts.shape[0]
        f = args.frames
        fps = f / (t_cam + t_lidar + t_vis)
        print(
            f"| {env} | {scene.num_primitives} | {t_build:.2f} | {n_cam * f / t_cam / 1e6:.2f} M | "
            f"{n_lidar * f / t_lidar / 1e6:.2f} M | {n_vis / max(t_vis, 1e-9) / 1e6:.2f} M | {fps:.2f} | "
            f"{CPU_SECONDS[0] / f:.2f} |"
        )


if __name__ == "__main__":
    main()
