"""Benchmark LiDAR-to-fisheye occlusion handling: speed and accuracy against exact visibility.

A structured synthetic scene (ground, buildings, poles, near floating obstacles; axis-aligned boxes) is
scanned by casting the beams of a ``LidarSpec`` (64 x 2048, 270 deg), then projected into an equidistant 190
deg fisheye whose centre is offset from the LiDAR. The exact visibility of every point from the camera
centre is known analytically (a ray-box test), so each method's precision and recall can be measured:

* precision = kept points that are visible / kept points,
* recall = kept points that are visible / visible points that project into the image.

Timings are the minimum (and median) over ``--repeats`` runs of the full ``occlusion_mask`` call (projection,
organisation and the test), single-threaded: wall clock, and CPU time of the process (the better figure on a
shared machine). The methods take turns within each repeat, so a busy machine slows them alike. ``ordering``
runs the compiled kernels; ``ordering (numpy)`` the vectorised numpy solver (the same mask), for comparison;
``zbuffer (5 px, 1 m)`` is the z-buffer with the fixed window and absolute margin it had before they were
derived from the LiDAR's spacing.

``--scans`` measures every method on scans whose beams do not sit on the spec's column centres, as a real
spinning LiDAR's: ``boundary`` (every beam half a column off), ``ring phase`` (a random azimuth phase per ring),
``jitter`` (ring phase plus 0.1 cell of noise per beam in azimuth and elevation, 5% of returns dropped) and
``shuffled`` (the nominal beams in a random order).

    python scripts/bench_lidar.py                       # 1536^2 and 512^2, prints a markdown table
    python scripts/bench_lidar.py --sizes 512 --check   # also check ordering == ordering_reference
    python scripts/bench_lidar.py --scans               # also precision / recall on realistic scans
    python scripts/bench_lidar.py --variants            # also the readings of III-C offered as options
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from airfisheye_bench.geometry import ideal_camera
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.occlusion import occlusion_mask, ordering_mask, ordering_reference
from airfisheye_bench.studies.lidar_scene import SCENES, camera_rig, scan, structured_scene, visible


def min_time_ms(fn, repeats: int) -> tuple[float, float]:
    """Minimum wall-clock and process CPU time of ``fn`` in ms (CPU time is robust to a busy machine)."""
    return min_times_ms({"fn": fn}, repeats)["fn"][:2]


def min_times_ms(fns: dict, repeats: int) -> dict[str, tuple[float, float, float]]:
    """Minimum wall-clock, minimum and median CPU ms of several functions, taking turns within each repeat
    (a fair side-by-side)."""
    walls = {name: [] for name in fns}
    cpus = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            walls[name].append(time.perf_counter() - t0)
            cpus[name].append(time.process_time() - c0)
    return {
        name: (min(walls[name]) * 1e3, min(cpus[name]) * 1e3, float(np.median(cpus[name])) * 1e3)
        for name in fns
    }


#: Table rows: name -> (``occlusion_mask`` method, options); ``ordering (numpy)`` is the numpy solver.
METHODS = {
    "ordering": ("ordering", {}),
    "ordering (numpy)": ("ordering", {}),
    "zbuffer": ("zbuffer", {}),
    "zbuffer (5 px, 1 m)": ("zbuffer", {"kernel": 5, "threshold": 1.0, "relative": False}),
    "hpr": ("hpr", {}),
    "none": ("none", {}),
}


def mask_fn(points, T, camera, spec, name: str):
    """The mask of one table row (see :data:`METHODS`)."""
    if name == "ordering (numpy)":
        return lambda: ordering_mask(points, T, camera, spec, "vectorised")
    method, options = METHODS[name]
    return lambda: occlusion_mask(points, T, camera, spec, method, **options)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1536, 512])
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scene", choices=sorted(SCENES), default="structured")
    parser.add_argument("--check", action="store_true", help="also check ordering against ordering_reference")
    parser.add_argument(
        "--variants", action="store_true", help="also measure the ordering options (first size)"
    )
    parser.add_argument(
        "--scans", action="store_true", help="also every method on realistic scans (last size)"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)

    spec = LidarSpec()  # 64 x 2048, 270 x (-45..15) deg
    boxes, offset, pitch = SCENES[args.scene]
    boxes = structured_scene(args.seed) if boxes is None else boxes
    points = scan(spec, boxes)
    centre, T = camera_rig(offset, pitch)
    print(
        f"scene: {len(boxes)} boxes, {len(points)} LiDAR points; camera {centre.tolist()} m from the LiDAR\n"
    )
    print(
        "| image | method | ms (wall) | ms (CPU) | median ms (CPU) | x zbuffer (CPU) | precision | recall | kept "
        "| hidden kept |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for size in args.sizes:
        camera = ideal_camera(size, size, fov_deg=190.0)
        truth = occlusion_mask(points, T, camera, spec, "none") & visible(points, centre, boxes)
        fns = {name: mask_fn(points, T, camera, spec, name) for name in METHODS}
        masks = {name: fn() for name, fn in fns.items()}  # also compiles / warms up
        times = min_times_ms(fns, args.repeats)
        rows = {}
        for name, mask in masks.items():
            tp = int((mask & truth).sum())
            rows[name] = (times[name], tp / max(int(mask.sum()), 1), tp / max(int(truth.sum()), 1), mask)
        for name, ((wall, cpu, median), precision, recall, mask) in rows.items():
            ratio = cpu / rows["zbuffer"][0][1]
            print(
                f"| {size}^2 | {name} | {wall:.1f} | {cpu:.1f} | {median:.1f} | {ratio:.2f} | {precision:.4f} "
                f"| {recall:.4f} | {int(mask.sum())} | {int((mask & ~truth).sum())} |"
            )
        if args.check:
            reference = ordering_reference(points, T, camera, spec)
            same = [np.array_equal(reference, rows[m][3]) for m in ("ordering", "ordering (numpy)")]
            print(f"\n{size}^2: ordering == ordering (numpy) == ordering_reference: {same[0] and same[1]}\n")
    if args.variants:
        measure_variants(points, boxes, spec, ideal_camera(args.sizes[0], args.sizes[0]), args.repeats)
    if args.scans:
        measure_scans(boxes, spec, centre, T, ideal_camera(args.sizes[-1], args.sizes[-1], fov_deg=190.0))


SCANS = ("nominal", "boundary", "ring phase", "jitter", "shuffled")


def measure_scans(boxes, spec, centre, T, camera) -> None:
    """Precision / recall of every method on scans whose beams sit where a real sensor's may."""
    names = [name for name in METHODS if name != "ordering (numpy)"]
    print(f"\nrealistic scans, {camera.width}^2: precision / recall\n")
    print("| scan | hidden / projected | " + " | ".join(names) + " |")
    print("|---|---|" + "---|" * len(names))
    for variant in SCANS:
        points = scan(spec, boxes, variant, seed=1)
        projects = occlusion_mask(points, T, camera, spec, "none")
        truth = projects & visible(points, centre, boxes)
        cells = []
        for name in names:
            mask = mask_fn(points, T, camera, spec, name)()
            tp = int((mask & truth).sum())
            cells.append(f"{tp / max(int(mask.sum()), 1):.4f} / {tp / max(int(truth.sum()), 1):.4f}")
        hidden = f"{int((projects & ~truth).sum())} / {int(projects.sum())}"
        print(f"| {variant} | {hidden} | " + " | ".join(cells) + " |")


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
