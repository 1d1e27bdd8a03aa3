"""Live check of the cube-face convention against TartanAir V2's own six-face sampler.

Loads ``sample_coor`` from a checkout of github:castacks/image_sampler (tartanairpy's
``tartanair/image_resampling/image_sampler`` submodule; it needs numba), sends every ray of a 190 deg equidistant
fisheye through it and through :func:`~airfisheye_bench.geometry.cubemap.direction_to_face`, and prints how often
the two pick the same face (``top`` = our ``up``, ``bottom`` = ``down``) and the largest difference of the face pixel
coordinates, per face. With ``--tartanairpy <checkout>`` it also compares the toolkit's planar depth -> distance
(``tartanair/reader.py`` ``TartanAirImageReader.depth_to_dist``) with :func:`~airfisheye_bench.geometry.cube_depth.
planar_to_range` on a random 640^2 face.

Usage:
    python scripts/check_tartanair_sampler.py /path/to/image_sampler [--face-size 640] [--size 512]
        [--tartanairpy /path/to/tartanairpy]
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import types
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.geometry import ideal_camera
from airfisheye_bench.geometry.cube_depth import planar_to_range
from airfisheye_bench.geometry.cubemap import FACE_NAMES, direction_to_face

#: ``six_images_common.OFFSETS`` columns (x, y in the 4 x 3 image cross) -> face, as that file draws the cross.
CROSS = {(1, 1): "front", (2, 1): "right", (1, 2): "bottom", (0, 1): "left", (1, 0): "top", (3, 1): "back"}
OURS = {"front": "front", "left": "left", "right": "right", "up": "top", "down": "bottom"}


def load_sample_coor(checkout: Path):
    """``sample_coor`` of ``six_images_numba.py``, with ``six_images_common`` reduced to its ``OFFSETS``
    (the full module imports the torch/cupy sampler)."""
    common = types.ModuleType("image_sampler.six_images_common")
    common.OFFSETS = np.array([[1, 2, 1, 0, 1, 3], [1, 1, 2, 1, 0, 1]], dtype=np.int32)
    text = (checkout / "six_images_common.py").read_text()
    assert "[ [1, 2, 1, 0, 1, 3],\n              [1, 1, 2, 1, 0, 1] ]" in text, "OFFSETS changed upstream"
    sys.modules["image_sampler"] = types.ModuleType("image_sampler")
    sys.modules["image_sampler"].__path__ = [str(checkout)]
    sys.modules["image_sampler.six_images_common"] = common
    spec = importlib.util.spec_from_file_location(
        "image_sampler.six_images_numba", checkout / "six_images_numba.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.sample_coor


def depth_to_dist_difference(checkout: Path) -> float:
    """Largest relative difference between the toolkit's ``depth_to_dist`` and ``planar_to_range`` (640^2)."""
    package = types.ModuleType("tartanair")
    package.__path__ = [str(checkout / "tartanair")]
    base = types.ModuleType("tartanair.tartanair_module")  # the reader's base class only holds dataset names
    base.TartanAirModule = object
    sys.modules.update({"tartanair": package, "tartanair.tartanair_module": base})
    spec = importlib.util.spec_from_file_location("tartanair.reader", checkout / "tartanair" / "reader.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # needs OpenCV, as the toolkit does
    depth = np.random.default_rng(0).uniform(0.5, 100.0, (640, 640)).astype(np.float32)
    theirs = module.TartanAirImageReader().depth_to_dist(depth)
    return float(np.max(np.abs(theirs - planar_to_range(depth)) / theirs))


def main(argv: list[str] | None = None) -> dict[str, float]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkout", type=Path, help="a checkout of github:castacks/image_sampler")
    parser.add_argument("--face-size", type=int, default=640)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument(
        "--tartanairpy", type=Path, default=None, help="a checkout of github:castacks/tartanairpy"
    )
    args = parser.parse_args(argv)
    sample_coor = load_sample_coor(args.checkout)
    camera = ideal_camera(args.size, args.size, fov_deg=190.0, model="equidistant")
    grid = np.stack(np.meshgrid(np.arange(args.size, dtype=np.float64), np.arange(args.size)), -1).reshape(
        -1, 2
    )
    rays = camera.unproject(grid)[camera.valid_mask().numpy().reshape(-1)]
    m, offsets = sample_coor(rays.T.astype(np.float32), np.ones(len(rays), dtype=bool))
    theirs = np.array([CROSS[(int(a), int(b))] for a, b in offsets.T])
    # Their normalised face coordinate m spans the face's outer edges (grid_sample, align_corners=False).
    col_t, row_t = m[0] * args.face_size - 0.5, m[1] * args.face_size - 0.5
    face, u, v = direction_to_face(torch.from_numpy(rays), args.face_size)
    ours = np.array([OURS[FACE_NAMES[f]] if f >= 0 else "back" for f in face.tolist()])
    same = ours == theirs
    lo, hi = -0.5, args.face_size - 0.5
    edge = np.minimum.reduce([np.abs(col_t - lo), np.abs(col_t - hi), np.abs(row_t - lo), np.abs(row_t - hi)])
    far = float(edge[~same].max()) if (~same).any() else 0.0
    print(
        f"{len(rays)} rays; same face: {same.mean():.5f}; the others lie within {far:.1e} px of a face edge"
    )
    out = {"same_face": float(same.mean())}
    for name in ("front", "left", "right", "top", "bottom"):
        k = same & (theirs == name)
        err = np.maximum(np.abs(u.numpy()[k] - col_t[k]), np.abs(v.numpy()[k] - row_t[k]))
        out[name] = float(err.max())
        print(
            f"{name}: {k.sum()} rays, max |pixel difference| {err.max():.2e} px at face size {args.face_size}"
        )
    if args.tartanairpy is not None:
        out["depth_to_dist"] = depth_to_dist_difference(args.tartanairpy)
        print(f"depth_to_dist vs planar_to_range: max relative difference {out['depth_to_dist']:.1e}")
    return out


if __name__ == "__main__":
    main()
