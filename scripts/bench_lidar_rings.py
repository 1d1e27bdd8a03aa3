"""Benchmark the LiDAR organisation and ``ordering`` against an earlier commit, side by side in one process.

The earlier commit's ``geometry/lidar.py``, ``geometry/occlusion.py`` (or package) and ``geometry/_kernels.py`` are
read with ``git show <commit>:...`` into a temporary package and imported next to today's code; both then run on
the same 64 x 2048 scan of ``scripts/bench_lidar.py``'s structured scene, taking turns within every repeat
(single-threaded; wall clock and process CPU time, min and median). Rows:

* ``organize_scan``: step 1 alone; ``occlusion_mask(ordering)``: projection, organisation and the test;
* on the paper's uniform 64 x 2048 sensor (the old code's only kind), and, today's code only, on a sensor with a
  64-entry channel table and beam origins (HDL-64E-like, 2048 per revolution over 270 deg) with the rings
  estimated from the table, and with the rings given (a ring field or the firing order).

    python scripts/bench_lidar_rings.py                 # against fe33d38 (before channel tables)
    python scripts/bench_lidar_rings.py --commit HEAD~3 --repeats 20
"""

from __future__ import annotations

import argparse
import importlib
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.geometry import ideal_camera
from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.lidar_layout import organize_scan, rings_from_elevation
from airfisheye_bench.geometry.occlusion import occlusion_mask
from airfisheye_bench.studies.lidar_scene import camera_rig, ray_box_entry, scan, structured_scene

ROOT = Path(__file__).resolve().parents[1]

#: The earlier commit's files the old ``lidar`` and ``occlusion`` need, under ``airfisheye_bench/``: its camera and
#: transforms too (``occlusion`` checks for its own camera class), and the constants its camera reads.
OLD_FILES = (
    "constants.py",
    "geometry/_arrays.py",
    "geometry/_kernels.py",
    "geometry/camera.py",
    "geometry/lidar.py",
    "geometry/occlusion.py",
    "geometry/transforms.py",
)
_OLD_IMPORT = re.compile(r"airfisheye_bench\.(?:geometry\.)?(\w+)")


def import_old(commit: str, folder: Path):
    """The commit's ``lidar``, ``occlusion`` and ``camera`` modules, imported as a package of their own."""
    package = folder / "old_geometry"
    package.mkdir()
    (package / "__init__.py").write_text("")
    for name in OLD_FILES:
        text = subprocess.run(
            ["git", "show", f"{commit}:airfisheye_bench/{name}"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        text = text.replace(
            "from airfisheye_bench.geometry import _kernels", "from old_geometry import _kernels"
        )
        text = _OLD_IMPORT.sub(lambda m: f"old_geometry.{m.group(1)}", text)
        (package / Path(name).name).write_text(text)
    sys.path.insert(0, str(folder))
    return tuple(importlib.import_module(f"old_geometry.{m}") for m in ("lidar", "occlusion", "camera"))


def times_ms(fns: dict, repeats: int) -> dict[str, tuple[float, float, float]]:
    """Min wall, min CPU and median CPU ms of each function, taking turns within every repeat."""
    walls = {k: [] for k in fns}
    cpus = {k: [] for k in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            walls[name].append(time.perf_counter() - t0)
            cpus[name].append(time.process_time() - c0)
    return {k: (min(walls[k]) * 1e3, min(cpus[k]) * 1e3, float(np.median(cpus[k])) * 1e3) for k in fns}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--commit", default="fe33d38")
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--size", type=int, default=512)
    args = parser.parse_args()
    torch.set_num_threads(1)

    spec = LidarSpec()  # the paper's 64 x 2048 over 270 deg
    boxes = structured_scene(0)
    points = scan(spec, boxes)
    _, T = camera_rig()
    camera = ideal_camera(args.size, args.size, fov_deg=190.0)
    # The same scene scanned by an HDL-64E-like sensor (its table, offsets and beam origins; 2048 over 270 deg)
    table = LidarSpec.from_preset("hdl64e", points_per_channel=2048, hfov_deg=270.0)
    dirs = table.beam_directions(torch.float64).reshape(-1, 3).numpy()
    channel = np.repeat(np.arange(table.channels), table.points_per_channel)
    starts = table.beam_origins(np.arctan2(dirs[:, 1], dirs[:, 0]), channel)
    t = np.full(len(dirs), np.inf)
    for c in range(table.channels):  # cast each laser from its mean origin (they differ by 2.6 cm sideways)
        rows = channel == c
        t[rows] = ray_box_entry(starts[rows].mean(axis=0), dirs[rows], boxes)
    hit = t <= table.max_range
    table_points, rings = starts[hit] + dirs[hit] * t[hit, None], channel[hit]
    r, _, el = spherical_coordinates(table_points)
    agree = (rings_from_elevation(r, el, table) == rings).mean()

    with tempfile.TemporaryDirectory() as tmp:
        old_lidar, old_occlusion, old_camera = import_old(args.commit, Path(tmp))
        old_spec = old_lidar.LidarSpec()
        camera_then = old_camera.FisheyeCamera(args.size, args.size, fov_deg=190.0)
        fns = {
            f"organize_scan, uniform ({args.commit})": lambda: old_lidar.organize_scan(points, old_spec),
            "organize_scan, uniform (today)": lambda: organize_scan(points, spec),
            f"ordering, uniform ({args.commit})": lambda: old_occlusion.occlusion_mask(
                points, T, camera_then, old_spec
            ),
            "ordering, uniform (today)": lambda: occlusion_mask(points, T, camera, spec),
            "organize_scan, channel table + origins, rings estimated (today)": lambda: organize_scan(
                table_points, table
            ),
            "ordering, channel table + origins, rings estimated (today)": lambda: occlusion_mask(
                table_points, T, camera, table
            ),
            "ordering, channel table, rings given (today)": lambda: occlusion_mask(
                table_points, T, camera, table, rings=rings
            ),
        }
        same = np.array_equal(fns[f"ordering, uniform ({args.commit})"](), fns["ordering, uniform (today)"]())
        for fn in fns.values():  # compile and warm up
            fn()
        result = times_ms(fns, args.repeats)
    base = {"organize_scan": result[f"organize_scan, uniform ({args.commit})"][1]}
    base["ordering"] = result[f"ordering, uniform ({args.commit})"][1]
    print(
        f"{len(points)} points (64 x 2048, 270 deg), {args.size}^2 fisheye, {args.repeats} repeats, 1 thread"
    )
    print(f"uniform masks identical to {args.commit}: {same}")
    print(
        f"HDL-64E-like scan: {len(table_points)} points; rings estimated from the table = true: {agree:.4f}\n"
    )
    print("| code | ms (wall, min) | ms (CPU, min) | ms (CPU, median) | x old (CPU, min) |")
    print("|---|---|---|---|---|")
    for name, (wall, cpu, median) in result.items():
        ratio = cpu / base["organize_scan" if name.startswith("organize") else "ordering"]
        print(f"| {name} | {wall:.1f} | {cpu:.1f} | {median:.1f} | {ratio:.2f} |")


if __name__ == "__main__":
    main()
