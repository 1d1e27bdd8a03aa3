"""Benchmark the cubemap -> fisheye remap against cv2.remap, side by side in one run.

Measures, on one thread:
  * lookup-table build time;
  * RGB bilinear + labels nearest + depth nearest from 5 faces to a fisheye, for ``CubemapToFisheye`` and for
    ``cv2.remap`` on the same data (OpenCV's fastest layout: the faces as one padded atlas with fixed-point
    ``CV_16SC2`` maps, so cv2 does a single remap per modality, as py360convert does).

With ``--erp``, the equirectangular source beside the cube at the same output size (``EquirectToFisheye`` from a
``2S x 4S`` panorama, the cube faces' angular resolution at their centres, against ``CubemapToFisheye`` from five
``S^2`` faces): the bilinear and nearest table builds (the camera's ray grid built beforehand, so only the table is
timed), the same two for a new orientation (what a per-sample gimbal view costs without a cached table), and the
RGB / label / depth remaps.

And, with ``--models``, one row per camera-model family (each a published calibration scaled to an
``out x out`` sensor, ``tests/geometry/golden/calibrations.json``): the time to build the camera's ray grid and
valid mask (back-projection of every pixel: closed forms or vectorised Newton), the bilinear lookup table from
scratch, and one RGB remap with it.

Usage:
    python scripts/bench_remap.py [--face 1024] [--out 1536] [--repeat 7]
    python scripts/bench_remap.py --erp [--face 1024 512] [--out 1536 512] [--repeat 7]
    python scripts/bench_remap.py --models [--face 1024] [--out 1536] [--repeat 3]

OpenCV comes from the optional ``bench`` extra (``pip install -e ".[bench]"``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.geometry import (
    CameraModel,
    CubemapToFisheye,
    EquirectToFisheye,
    camera_from_dict,
    gimbal_rotation,
    ideal_camera,
)
from airfisheye_bench.geometry.cubemap import clear_table_cache, direction_to_face

CALIBRATIONS = Path(__file__).resolve().parents[1] / "tests" / "geometry" / "golden" / "calibrations.json"


def timeit(fn, repeat: int) -> float:
    """Minimum wall time in ms over ``repeat`` runs after one warm-up (robust to other load on the machine)."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return min(times)


def cv2_atlas_maps(camera: CameraModel, s: int):
    """Maps for cv2.remap into a vertical atlas of the 5 faces, each padded by one texel (edge replicate)."""
    import cv2

    rays = camera.ray_grid(torch.float64).reshape(-1, 3)
    face, u, v = direction_to_face(rays, s)
    inside = camera.valid_mask().reshape(-1) & (face >= 0)
    mx = torch.where(inside, u + 1, -10.0).reshape(camera.height, camera.width).numpy().astype(np.float32)
    my = torch.where(inside, face.clamp_min(0) * (s + 2) + v + 1, -10.0)
    my = my.reshape(camera.height, camera.width).numpy().astype(np.float32)
    return cv2.convertMaps(mx, my, cv2.CV_16SC2)


def to_atlas(faces_hwc: np.ndarray) -> np.ndarray:
    """``[5, S, S, C]`` -> padded ``[5 * (S + 2), S + 2, C]`` (replicated edges; what a cv2 pipeline would build)."""
    padded = np.pad(faces_hwc, ((0, 0), (1, 1), (1, 1), (0, 0)), mode="edge")
    return padded.reshape(-1, *padded.shape[2:])


def bench(face: int, out: int, repeat: int) -> dict[str, float]:
    import cv2

    cv2.setNumThreads(1)
    torch.set_num_threads(1)
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (5, face, face, 3), dtype=np.uint8)
    label = rng.integers(0, 23, (5, face, face, 1), dtype=np.uint8)
    depth = rng.uniform(1, 120, (5, face, face, 1)).astype(np.float32)
    camera = ideal_camera(out, out)

    clear_table_cache()
    t0 = time.perf_counter()
    remap = CubemapToFisheye(camera, face)
    remap.table("bilinear")  # includes the camera's ray grid, built on first use
    t1 = time.perf_counter()
    remap.table("nearest")
    lut_ms = ((t1 - t0) * 1e3, (time.perf_counter() - t1) * 1e3)

    # Ours takes [5, C, S, S]. Permuting the decoded HWC arrays gives that shape without a copy (channels-last
    # memory), which is what the datamodule passes; both libraries read the same bytes.
    rgb_t, label_t, depth_t = (torch.from_numpy(x).permute(0, 3, 1, 2) for x in (rgb, label, depth))
    ours = {
        "rgb": timeit(lambda: remap(rgb_t, "bilinear"), repeat),
        "label": timeit(lambda: remap(label_t, "nearest", fill=255), repeat),
        "depth": timeit(lambda: remap(depth_t, "nearest"), repeat),
    }
    m1, m2 = cv2_atlas_maps(camera, face)
    atl_rgb, atl_label, atl_depth = to_atlas(rgb), to_atlas(label)[..., 0], to_atlas(depth)[..., 0]
    cv = {
        "rgb": timeit(lambda: cv2.remap(atl_rgb, m1, m2, cv2.INTER_LINEAR), repeat),
        "label": timeit(lambda: cv2.remap(atl_label, m1, m2, cv2.INTER_NEAREST, borderValue=255), repeat),
        "depth": timeit(lambda: cv2.remap(atl_depth, m1, m2, cv2.INTER_NEAREST), repeat),
    }
    cv_with_atlas = timeit(lambda: (to_atlas(rgb), to_atlas(label), to_atlas(depth)), repeat)
    return {"lut_ms": lut_ms, "ours": ours, "cv2": cv, "cv2_atlas_ms": cv_with_atlas}


def bench_sources(face: int, out: int, repeat: int) -> dict[str, dict[str, float]]:
    """Cube faces and an equirectangular panorama to one fisheye, side by side: table builds and remaps (ms)."""
    torch.set_num_threads(1)
    rng = np.random.default_rng(0)
    h, w = 2 * face, 4 * face
    data = {
        "cube": (
            rng.integers(0, 256, (5, face, face, 3), dtype=np.uint8),
            rng.integers(0, 23, (5, face, face, 1), dtype=np.uint8),
            rng.uniform(1, 120, (5, face, face, 1)).astype(np.float32),
        ),
        "erp": (
            rng.integers(0, 256, (h, w, 3), dtype=np.uint8),
            rng.integers(0, 23, (h, w, 1), dtype=np.uint8),
            rng.uniform(1, 120, (h, w, 1)).astype(np.float32),
        ),
    }
    camera = ideal_camera(out, out)
    camera.valid_mask()  # the ray grid is the camera's, shared by both sources: not timed
    make = {
        "cube": lambda rotation=None: CubemapToFisheye(camera, face, rotation=rotation),
        "erp": lambda rotation=None: EquirectToFisheye(camera, (h, w), rotation=rotation),
    }
    result = {}
    for source in ("cube", "erp"):
        builds = {"bilinear": [], "nearest": [], "rotated bilinear": [], "rotated nearest": []}
        for i in range(max(1, repeat // 2)):
            clear_table_cache()
            remap = make[source]()
            rotated = make[source](gimbal_rotation(yaw_deg=7.0 + i, pitch_deg=31.0 + i))
            for name, r, mode in (
                ("bilinear", remap, "bilinear"),
                ("nearest", remap, "nearest"),
                ("rotated bilinear", rotated, "bilinear"),
                ("rotated nearest", rotated, "nearest"),
            ):
                t0 = time.perf_counter()
                r.table(mode)
                builds[name].append((time.perf_counter() - t0) * 1e3)
        # The decoded HWC arrays viewed channels-first without a copy, as the datamodule passes them.
        axes = (0, 3, 1, 2) if source == "cube" else (2, 0, 1)
        rgb, label, depth = (torch.from_numpy(x).permute(*axes) for x in data[source])
        remap = make[source]()
        result[source] = {
            **{name: min(times) for name, times in builds.items()},
            "rgb": timeit(lambda remap=remap, rgb=rgb: remap(rgb, "bilinear"), repeat),
            "label": timeit(lambda remap=remap, label=label: remap(label, "nearest", fill=255), repeat),
            "depth": timeit(lambda remap=remap, depth=depth: remap(depth, "nearest"), repeat),
        }
    return result


def print_sources(faces: list[int], outs: list[int], repeat: int) -> None:
    print(
        "| source | output | table build bilinear / nearest (ms) | new orientation bilinear / nearest (ms) "
        "| RGB / label / depth (ms) | remap total (ms) |"
    )
    print("|---|---|---|---|---|---|")
    for face, out in zip(faces, outs, strict=True):
        r = bench_sources(face, out, repeat)
        for source, label in (("cube", f"cube 5x{face}^2"), ("erp", f"ERP {2 * face}x{4 * face}")):
            x = r[source]
            print(
                f"| {label} | {out}^2 | {x['bilinear']:.0f} / {x['nearest']:.0f} "
                f"| {x['rotated bilinear']:.0f} / {x['rotated nearest']:.0f} "
                f"| {x['rgb']:.1f} / {x['label']:.1f} / {x['depth']:.1f} | {x['rgb'] + x['label'] + x['depth']:.1f} |",
                flush=True,
            )


def model_cameras(out: int) -> dict[str, CameraModel]:
    """One camera per model family on an ``out x out`` sensor: the published calibrations, scaled."""
    cal = {k: v["camera"] for k, v in json.loads(CALIBRATIONS.read_text())["cameras"].items()}
    cams = {
        "equidistant": ideal_camera(out, out),
        "kannala_brandt (old form)": ideal_camera(
            out, out, model="kannala_brandt", k=(0.05, -0.01, 0.002, -0.0003)
        ),
    }
    for family, name in (
        ("kannala_brandt (TUM-VI)", "tumvi512_cam0_kb"),
        ("double_sphere (TUM-VI)", "tumvi512_cam0_ds"),
        ("eucm (TUM-VI)", "tumvi512_cam0_eucm"),
        ("unified (KITTI-360 image_02)", "kitti360_image_02"),
        ("ocam (Kodak SP360)", "ocam_kodak_sp360"),
        ("pinhole_radtan (ROS plumb_bob)", "ros_kodak_plumb_bob"),
    ):
        cams[family] = camera_from_dict(cal[name]).resized(out, out)
    ws = cal[
        "woodscape_front"
    ]  # 1280 x 966: scale the lens by out / 1280 onto a square sensor, same centre offsets
    s = out / ws["width"]
    off_x, off_y = ws["cx"] - (ws["width"] - 1) / 2, ws["cy"] - (ws["height"] - 1) / 2
    cams["radial_poly (WoodScape front)"] = camera_from_dict(
        {
            "model": "radial_poly",
            "width": out,
            "height": out,
            **{k: ws[k] * s for k in ("k1", "k2", "k3", "k4")},
            "cx": (out - 1) / 2 + off_x * s,
            "cy": (out - 1) / 2 + off_y * s,
        }
    )
    return cams


def bench_models(face: int, out: int, repeat: int) -> None:
    """One row per camera-model family: ray grid + valid mask, bilinear table, one RGB remap."""
    torch.set_num_threads(1)
    rgb = torch.from_numpy(np.random.default_rng(0).integers(0, 256, (5, face, face, 3), dtype=np.uint8))
    rgb = rgb.permute(0, 3, 1, 2)
    print(
        f"| model (calibration) | {out}^2: ray grid + valid mask (ms) | bilinear table from scratch (ms) "
        f"| RGB remap (ms) | valid pixels |"
    )
    print("|---|---|---|---|---|")
    for family, cam in model_cameras(out).items():
        grid, table = [], []
        for _ in range(repeat):
            fresh = camera_from_dict(cam.to_dict())  # new instance: nothing cached
            clear_table_cache()
            t0 = time.perf_counter()
            fresh.valid_mask()
            t1 = time.perf_counter()
            remap = CubemapToFisheye(fresh, face)
            remap.table("bilinear")
            grid.append((t1 - t0) * 1e3)
            table.append((time.perf_counter() - t0) * 1e3)
        rgb_ms = timeit(lambda remap=remap: remap(rgb, "bilinear"), repeat)
        valid = float(fresh.valid_mask().float().mean())
        print(f"| {family} | {min(grid):.0f} | {min(table):.0f} | {rgb_ms:.1f} | {valid:.1%} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--face", type=int, nargs="+", default=[1024, 512])
    parser.add_argument("--out", type=int, nargs="+", default=[1536, 512])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--models", action="store_true", help="one row per camera-model family instead")
    parser.add_argument("--erp", action="store_true", help="the panorama source beside the cube instead")
    args = parser.parse_args()
    if args.erp:
        print_sources(args.face, args.out, args.repeat)
        return
    if args.models:
        bench_models(args.face[0], args.out[0], args.repeat)
        return
    print(
        "| faces | output | LUT build (ms) | ours RGB / label / depth (ms) | cv2 RGB / label / depth (ms) "
        "| ours total | cv2 total | ratio | cv2 incl. atlas copy |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for face, out in zip(args.face, args.out, strict=True):
        r = bench(face, out, args.repeat)
        ours, cv = sum(r["ours"].values()), sum(r["cv2"].values())
        fmt = lambda d: " / ".join(f"{d[k]:.1f}" for k in ("rgb", "label", "depth"))  # noqa: E731
        print(
            f"| 5x{face}^2 | {out}^2 | {r['lut_ms'][0]:.0f} / {r['lut_ms'][1]:.0f} | {fmt(r['ours'])} | {fmt(r['cv2'])} | {ours:.1f} | {cv:.1f} "
            f"| {ours / cv:.2f}x | {cv + r['cv2_atlas_ms']:.1f} |"
        )


if __name__ == "__main__":
    main()
