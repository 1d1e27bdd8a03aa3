"""scripts/bench_occlusion_memory.py (:mod:`airfisheye_bench.studies.occlusion_memory`) measures a real call of each method in a fresh process."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from airfisheye_bench.geometry import ideal_camera
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.occlusion import occlusion_mask
from airfisheye_bench.studies import lidar_scene, occlusion_memory

pytestmark = [
    pytest.mark.slow,  # a fresh interpreter that compiles the kernels: ~15 s
    pytest.mark.skipif(
        not Path("/proc/self/clear_refs").exists(), reason="peak-memory reset needs Linux /proc"
    ),
]


def test_each_row_is_the_methods_own_call_in_a_fresh_process():
    bench = occlusion_memory
    lidar = lidar_scene
    row = bench.run_child("zbuffer", 96, repeats=1, seed=0)
    # The child scored the same scan the benchmark scene gives here: its mask is the real method's.
    points = lidar.scan(LidarSpec(), lidar.structured_scene(0))
    _, T = lidar.camera_rig(*lidar.SCENES["structured"][1:])
    mask = occlusion_mask(points, T, ideal_camera(96, 96, fov_deg=190.0), LidarSpec(), "zbuffer")
    assert (row["points"], row["kept"]) == (len(points), int(np.count_nonzero(mask)))
    # A z-buffer allocates at least its depth buffer and the points' pixel indices during the call.
    assert row["numpy_peak_mib"] * 2**20 >= 96 * 96 * 4 + 8 * row["kept"]
    assert row["first_peak_mib"] >= row["steady_peak_mib"] - 1.0 and row["cache_mib"] >= 0.0
    assert row["cpu_ms"] > 0.0
