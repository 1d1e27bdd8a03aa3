"""Benchmark serving KITTI-360 samples (``data.format=kitti360``): CPU time per sample, and the curl against the
devkit's per-point loop, side by side in one process.

A root in the real layout is written first (:mod:`airfisheye_bench.studies.miniature_datasets.kitti360`: 1400^2
PNG images, HDL-64E scans of ~125k returns in KITTI's firing order), or ``--root`` points at a real one. Rows,
each over the training frames (one thread, CPU time, min and median of ``--repeats``):

* ``depth`` and ``completion`` at ``--size`` (default 512) with ``accumulate`` 0 and 2 (up to five scans in the
  target), the latter in frame order with the source's reuse of the neighbours' curled scans and without it;
* the curl of one scan: :func:`~airfisheye_bench.geometry.deskew.curl_points` against a line-by-line port of the
  devkit's ``curl_velodyne_data`` loop (:mod:`~airfisheye_bench.studies.miniature_datasets.kitti360_devkit`, the
  tests' reference), on the same points.

    python scripts/bench_kitti360.py
    python scripts/bench_kitti360.py --root /data/KITTI-360 --size 512 --repeats 5
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from airfisheye_bench.geometry.deskew import curl_points, scan_fraction  # noqa: E402
from airfisheye_bench.studies.miniature_datasets.kitti360 import SEQUENCES, write_kitti360  # noqa: E402
from airfisheye_bench.studies.miniature_datasets.kitti360_devkit import devkit_curl  # noqa: E402
from datamodules.dataset import AirFisheyeDataset, CameraConfig  # noqa: E402


def cpu_ms(fn, repeats: int) -> tuple[float, float]:
    """(min, median) CPU milliseconds of ``fn()`` over ``repeats`` calls."""
    times = []
    for _ in range(repeats):
        start = time.process_time()
        fn()
        times.append(1000.0 * (time.process_time() - start))
    return min(times), statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--root", type=Path, default=None, help="a KITTI-360 root (default: write one)")
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        root = args.root
        if root is None:
            root = write_kitti360(
                Path(tmp) / "kitti360", sequences=SEQUENCES, frames=5, unposed=(), size=1400
            )
        print(f"root {root}, served at {args.size}^2, one thread, CPU ms per sample (min / median)")
        print("| task | accumulate | ms / sample | points in the target |")
        print("|---|---|---|---|")
        rows = [("depth", 0, True), ("completion", 0, True)]
        rows += [(task, 2, reuse) for task in ("depth", "completion") for reuse in (False, True)]
        for task, accumulate, reuse in rows:
            ds = AirFisheyeDataset.from_root(
                root,
                "train",
                task,
                source="fisheye",
                camera=CameraConfig(size=args.size),
                format="kitti360",
                format_options={"accumulate": accumulate},
            )
            ds[0]  # compile the numba kernels and fill the caches first
            n = len(ds)

            def one_pass(ds=ds, n=n, reuse=reuse) -> None:
                for i in range(n):
                    if not reuse:  # every sample reads and curls its neighbours' scans itself
                        ds.reader._recent.clear()
                    ds[i]

            best, median = cpu_ms(one_pass, args.repeats)
            points = len(ds.reader.depth_points(ds.sample_ids[0], ds.lidar_min_range).points)
            label = f"{accumulate}" + (
                "" if accumulate == 0 else (" (scans reused)" if reuse else " (no reuse)")
            )
            print(f"| {task} | {label} | {best / n:.1f} / {median / n:.1f} | {points} |")

        sid = ds.sample_ids[min(1, len(ds) - 1)]
        seq, frame = sid.rsplit("/", 1)
        points = ds.reader.lidar_scan(sid).points
        src = ds.reader
        D, dt = src._motion(seq, int(frame))
        ours = cpu_ms(lambda: curl_points(points, D, scan_fraction(points) * src._scan_period(seq) / dt), 5)
        devkit = cpu_ms(lambda: devkit_curl(root, seq, int(frame), points), 1)
        diff = np.abs(
            curl_points(points, D, scan_fraction(points)) - devkit_curl(root, seq, int(frame), points)
        )
        print(
            f"curl of {len(points)} points: curl_points {ours[0]:.1f} ms, the devkit's loop (Python port) "
            f"{devkit[0]:.0f} ms, ratio {devkit[0] / ours[0]:.0f}x; max difference {diff.max():.2e} m"
        )


if __name__ == "__main__":
    main()
