"""Peak memory and time of each occlusion method, to test the paper's claim that ordering needs less memory.

The paper (III-C) argues that ordering the scan is cheaper in memory than image-based methods such as a z-buffer,
whose buffers grow with the image. Each (method, image size) is measured in a fresh process on the structured
scene of ``scripts/bench_lidar.py`` (:mod:`~airfisheye_bench.studies.lidar_scene`) (a 64 x 2048 scan), single-threaded:

* ``per-camera cache``: resident memory the first call leaves behind (per-pixel scale maps and similar, kept for
  the next frames of the same camera; the numba kernels are compiled beforehand on a 64^2 camera, so compilation
  is not counted);
* ``first call peak`` / ``steady peak``: the peak resident memory above what was resident before the call
  (Linux ``VmHWM``, reset through ``/proc/self/clear_refs``), for the first call and a later one;
* ``numpy peak``: the peak of Python and numpy allocations during a steady call (``tracemalloc``; memory that
  compiled kernels or Qhull allocate themselves shows only in the resident figures);
* ``ms (CPU)``: the minimum process CPU time of ``--repeats`` steady calls.

glibc is told to serve every allocation above 64 KiB with ``mmap`` (``MALLOC_MMAP_THRESHOLD_``), so freed
buffers leave the resident set at once and each peak is the call's own.

    python scripts/bench_occlusion_memory.py                 # 512^2 and 1536^2, every method, a markdown table
    python scripts/bench_occlusion_memory.py --sizes 512 --methods ordering zbuffer
    python scripts/bench_occlusion_memory.py --json docs/figures/occlusion_memory.json   # also the rows, with provenance
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import json
import os
import subprocess
import sys
import time
import tracemalloc
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.geometry import ideal_camera
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.occlusion import occlusion_mask
from airfisheye_bench.studies.lidar_scene import SCENES, camera_rig, scan, structured_scene
from airfisheye_bench.studies.provenance import provenance

METHODS = ("none", "zbuffer", "hpr", "ordering")


def _status_kib(field: str) -> int:
    """A ``/proc/self/status`` field (``VmRSS``, ``VmHWM``) in KiB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise RuntimeError(f"/proc/self/status has no {field}")


def _settle() -> int:
    """Free what can be freed, reset the peak resident size to the current one, and return that (KiB)."""
    gc.collect()
    ctypes.CDLL("libc.so.6").malloc_trim(0)
    Path("/proc/self/clear_refs").write_text("5")  # resets VmHWM to VmRSS (Linux >= 4.0)
    return _status_kib("VmRSS")


def measure(method: str, size: int, repeats: int, seed: int) -> dict[str, float]:
    """One (method, size) in this process; see the module docstring."""
    torch.set_num_threads(1)
    spec = LidarSpec()
    _, offset, pitch = SCENES["structured"]
    points = scan(spec, structured_scene(seed))
    _, T = camera_rig(offset, pitch)
    occlusion_mask(points, T, ideal_camera(64, 64, fov_deg=190.0), spec, method)  # compile the kernels

    camera = ideal_camera(size, size, fov_deg=190.0)
    before = _settle()
    occlusion_mask(points, T, camera, spec, method)
    first_peak = _status_kib("VmHWM") - before
    cached = _settle() - before

    steady = _settle()
    tracemalloc.start()
    mask = occlusion_mask(points, T, camera, spec, method)
    traced_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    steady_peak = _status_kib("VmHWM") - steady

    cpu = []
    for _ in range(repeats):
        c0 = time.process_time()
        occlusion_mask(points, T, camera, spec, method)
        cpu.append(time.process_time() - c0)
    return {
        "points": len(points),
        "kept": int(np.count_nonzero(mask)),
        "cache_mib": cached / 1024,
        "first_peak_mib": first_peak / 1024,
        "steady_peak_mib": steady_peak / 1024,
        "numpy_peak_mib": traced_peak / 2**20,
        "cpu_ms": min(cpu) * 1e3,
    }


def run_child(method: str, size: int, repeats: int, seed: int) -> dict[str, float]:
    """:func:`measure` in a fresh interpreter, with glibc's mmap threshold fixed (see the module docstring)."""
    env = dict(os.environ, MALLOC_MMAP_THRESHOLD_="65536", OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    args = ["--child", method, "--sizes", str(size), "--repeats", str(repeats), "--seed", str(seed)]
    out = subprocess.run(
        [sys.executable, "-m", "airfisheye_bench.studies.occlusion_memory", *args],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[512, 1536])
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, help="also write the rows here, with their provenance")
    parser.add_argument("--child", choices=METHODS, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(measure(args.child, args.sizes[0], args.repeats, args.seed)))
        return

    print(
        "| image | method | per-camera cache MiB | first call peak MiB | steady peak MiB | numpy peak MiB "
        "| ms (CPU) | kept / points |"
    )
    print("|---|---|---|---|---|---|---|---|")
    source = None
    if args.json is not None:
        source = provenance("scripts/bench_occlusion_memory.py", argv)
    rows = []
    for size in args.sizes:
        for method in args.methods:
            r = run_child(method, size, args.repeats, args.seed)
            rows.append({"size": size, "method": method, **r})
            print(
                f"| {size}^2 | {method} | {r['cache_mib']:.1f} | {r['first_peak_mib']:.1f} "
                f"| {r['steady_peak_mib']:.1f} | {r['numpy_peak_mib']:.1f} | {r['cpu_ms']:.1f} "
                f"| {r['kept']} / {r['points']} |"
            )
    if args.json is not None:
        record = {"scene": "structured", "repeats": args.repeats, "seed": args.seed, "rows": rows}
        atomic_write_text(args.json, json.dumps({**record, "provenance": source}, indent=2) + "\n")


if __name__ == "__main__":  # the fresh process of run_child
    main()
