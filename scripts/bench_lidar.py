"""Benchmark LiDAR-to-fisheye occlusion handling: speed and accuracy against exact visibility.

A structured synthetic scene (ground, buildings, poles, near floating obstacles; axis-aligned boxes) is
scanned by casting the beams of a ``LidarSpec`` (64 x 2048, 270 deg), then projected into an equidistant 190
deg fisheye whose centre is offset from the LiDAR. The exact visibility of every point from the camera
centre is known analytically (a ray-box test), so each method's precision and recall can be measured:

* precision = kept points that are visible / kept points,
* recall = kept points that are visible / visible points that project into the image.

Timings are the minimum over ``--repeats`` runs of the full ``occlusion_mask`` call (projection, organisation
and the test), single-threaded: wall clock, and CPU time of the process (the better figure on a shared machine).
The methods take turns within each repeat, so a busy machine slows them alike. ``ordering`` runs the compiled
kernels; ``ordering (numpy)`` the previous vectorised numpy solver (the same mask), for comparison.

    python scripts/bench_lidar.py                       # 1536^2 and 512^2, prints a markdown table
    python scripts/bench_lidar.py --sizes 512 --check   # also check ordering == ordering_reference
    python scripts/bench_lidar.py --variants            # also the readings of III-C offered as options
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

from airfisheye_bench.geometry import CAM_FROM_FLU, FisheyeCamera, euler_to_matrix, make_transform
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.occlusion import _ordering, occlusion_mask, ordering_reference


def ray_box_entry(origin: np.ndarray, dirs: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Distance along unit rays ``dirs [N, 3]`` from ``origin`` into the first box ``[M, 2, 3]`` (inf: none).

    Slab test; a ray starting inside a box enters it at distance 0.
    """
    t = np.full(len(dirs), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        for lo, hi in boxes:  # a loop over boxes (tens), vectorised over rays
            t1, t2 = (lo - origin) * inv, (hi - origin) * inv
            near = np.nan_to_num(np.minimum(t1, t2), nan=-np.inf).max(axis=1)
            far = np.nan_to_num(np.maximum(t1, t2), nan=np.inf).min(axis=1)
            hit = (near <= far) & (far > 0)
            t = np.where(hit, np.minimum(t, np.maximum(near, 0.0)), t)
    return t


def structured_scene(seed: int = 0) -> np.ndarray:
    """Boxes ``[M, 2, 3]`` (min, max corners) in the LiDAR frame; the LiDAR flies 6 m above the ground."""
    rng = np.random.default_rng(seed)
    boxes = [((-150.0, -150.0, -7.0), (150.0, 150.0, -6.0))]  # ground
    while len(boxes) < 26:  # buildings
        cx, cy = rng.uniform(-60, 60, 2)
        sx, sy = rng.uniform(3, 12, 2)
        if abs(cx) > sx / 2 + 8 or abs(cy) > sy / 2 + 8:
            boxes.append(
                ((cx - sx / 2, cy - sy / 2, -6.0), (cx + sx / 2, cy + sy / 2, -6.0 + rng.uniform(3, 25)))
            )
    while len(boxes) < 56:  # poles and trunks
        cx, cy = rng.uniform(-25, 25, 2)
        w = rng.uniform(0.2, 0.6)
        if max(abs(cx), abs(cy)) > 2:
            boxes.append(
                ((cx - w / 2, cy - w / 2, -6.0), (cx + w / 2, cy + w / 2, -6.0 + rng.uniform(4, 12)))
            )
    for _ in range(6):  # near floating obstacles (branches, signs), 2-7 m ahead
        x, y, z = rng.uniform(2, 6), rng.uniform(-4, 4), rng.uniform(-3, 0)
        boxes.append(
            ((x, y, z), (x + rng.uniform(0.2, 1.0), y + rng.uniform(0.2, 2.0), z + rng.uniform(0.3, 1.5)))
        )
    return np.asarray(boxes, dtype=np.float64)


def scan(spec: LidarSpec, boxes: np.ndarray) -> np.ndarray:
    """Points hit by the spec's beams (LiDAR at the origin), within its range."""
    dirs = spec.beam_directions(torch.float64).reshape(-1, 3).numpy()
    t = ray_box_entry(np.zeros(3), dirs, boxes)
    hit = t <= spec.max_range
    return dirs[hit] * t[hit, None]


def camera_rig(offset=(0.1, 0.3, -0.4), pitch_deg: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """``(centre, T_cam_lidar)``: a forward camera pitched down, centred at ``offset`` in the LiDAR frame."""
    centre = np.asarray(offset, dtype=np.float64)
    R_lidar_cam = euler_to_matrix(0.0, math.radians(pitch_deg), 0.0) @ CAM_FROM_FLU.T
    R = R_lidar_cam.T
    return centre, make_transform(R, -R @ centre)


def visible(points: np.ndarray, centre: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Exact visibility from ``centre``: no box is entered before the point itself is reached."""
    v = points - centre
    dist = np.linalg.norm(v, axis=1)
    return ray_box_entry(centre, v / dist[:, None], boxes) >= dist * (1 - 1e-9) - 1e-9


def min_time_ms(fn, repeats: int) -> tuple[float, float]:
    """Minimum wall-clock and process CPU time of ``fn`` in ms (CPU time is robust to a busy machine)."""
    return min_times_ms({"fn": fn}, repeats)["fn"]


def min_times_ms(fns: dict, repeats: int) -> dict[str, tuple[float, float]]:
    """:func:`min_time_ms` of several functions, taking turns within each repeat (a fair side-by-side)."""
    best = {name: (math.inf, math.inf) for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            best[name] = (min(best[name][0], wall), min(best[name][1], cpu))
    return {name: (wall * 1e3, cpu * 1e3) for name, (wall, cpu) in best.items()}


def mask_fn(points, T, camera, spec, method: str):
    """The mask of one table row: an ``occlusion_mask`` method, or the numpy solver (``ordering (numpy)``)."""
    if method == "ordering (numpy)":
        return lambda: _ordering(points, T, camera, spec, "vectorised")
    return lambda: occlusion_mask(points, T, camera, spec, method)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1536, 512])
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--check", action="store_true", help="also check ordering against ordering_reference")
    parser.add_argument(
        "--variants", action="store_true", help="also measure the ordering options (first size)"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)

    spec = LidarSpec()  # 64 x 2048, 270 x (-45..15) deg
    boxes = structured_scene(args.seed)
    points = scan(spec, boxes)
    centre, T = camera_rig()
    print(
        f"scene: {len(boxes)} boxes, {len(points)} LiDAR points; camera {centre.tolist()} m from the LiDAR\n"
    )
    print(
        "| image | method | ms (wall) | ms (CPU) | x zbuffer (CPU) | precision | recall | kept | hidden kept |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for size in args.sizes:
        camera = FisheyeCamera(size, size, fov_deg=190.0)
        truth = occlusion_mask(points, T, camera, spec, "none") & visible(points, centre, boxes)
        fns = {
            m: mask_fn(points, T, camera, spec, m)
            for m in ("ordering", "ordering (numpy)", "zbuffer", "none")
        }
        masks = {method: fn() for method, fn in fns.items()}  # also compiles / warms up
        times = min_times_ms(fns, args.repeats)
        rows = {}
        for method, mask in masks.items():
            tp = int((mask & truth).sum())
            rows[method] = (times[method], tp / max(int(mask.sum()), 1), tp / max(int(truth.sum()), 1), mask)
        for method, ((wall, cpu), precision, recall, mask) in rows.items():
            ratio = cpu / rows["zbuffer"][0][1]
            print(
                f"| {size}^2 | {method} | {wall:.1f} | {cpu:.1f} | {ratio:.2f} | {precision:.4f} | {recall:.4f} "
                f"| {int(mask.sum())} | {int((mask & ~truth).sum())} |"
            )
        if args.check:
            reference = ordering_reference(points, T, camera, spec)
            same = [np.array_equal(reference, rows[m][3]) for m in ("ordering", "ordering (numpy)")]
            print(f"\n{size}^2: ordering == ordering (numpy) == ordering_reference: {same[0] and same[1]}\n")
    if args.variants:
        measure_variants(points, boxes, spec, FisheyeCamera(args.sizes[0], args.sizes[0]), args.repeats)


VARIANTS = {
    "literal (default)": {},
    "elevation_tolerance=+1 (lenient)": {"elevation_tolerance": 1.0},
    "elevation_tolerance=-0.25 (margin)": {"elevation_tolerance": -0.25},
    "elevation_window=1": {"elevation_window": 1},
    "azimuth_window=16": {"azimuth_window": 16},
    "azimuth_window=64, elevation_window=4": {"azimuth_window": 64, "elevation_window": 4},
}
RIGS = {
    "sideways": ((0.0, 0.5, 0.0), 0.0),
    "below": ((0.0, 0.0, -0.5), 30.0),
    "mixed": ((0.1, 0.3, -0.4), 20.0),
}


def measure_variants(points, boxes, spec, camera, repeats) -> None:
    """Hidden points kept / visible points dropped by each reading of III-C, for three camera placements."""
    print(f"\nordering options, {camera.width}^2: hidden points kept / visible points dropped (CPU ms)\n")
    print("| option | " + " | ".join(RIGS) + " |")
    print("|---|" + "---|" * len(RIGS))
    truths = {}
    for rig, (offset, pitch) in RIGS.items():
        centre, T = camera_rig(offset, pitch)
        truths[rig] = (T, occlusion_mask(points, T, camera, spec, "none"), visible(points, centre, boxes))
    for name, options in VARIANTS.items():
        cells = []
        for T, projects, seen in truths.values():
            mask = occlusion_mask(points, T, camera, spec, "ordering", **options)
            _, ms = min_time_ms(
                lambda T=T, o=options: occlusion_mask(points, T, camera, spec, "ordering", **o), repeats
            )
            cells.append(f"{int((mask & ~seen).sum())} / {int((projects & seen & ~mask).sum())} ({ms:.0f})")
        print(f"| {name} | " + " | ".join(cells) + " |")
    for rig, (_, projects, seen) in truths.items():
        print(
            f"\n{rig}: {int((projects & ~seen).sum())} hidden of {int(projects.sum())} projected points",
            end="",
        )
    print()


if __name__ == "__main__":
    main()
