"""A tiny AirSim360 / Omni360-X root in the dataset's exact layouts and encodings, rendered from an analytic scene.

The files follow github:Insta360-Research-Team/AirSim360 ``data/demo_sample/`` (``README.md``,
``PANORAMIC_DATA_FORMAT.md``, ``scripts/read_demo_ground_truth.py``, ``instance/README.md``,
``instance/read_instance_labels_example.py``), written with the libraries its readers use, never through this
project's readers:

- scene ``NYC`` in the Omni360-Scene release's naming: ``nyc_Raw_Part1/``, ``nyc_Raw_Part2/`` (the release splits
  large scenes' panoramas into parts) ``panorama_<n>.png``; ``nyc_Depth/Depth_<n>.h5`` (h5py, dataset ``/depth``,
  float32 metres); ``nyc_seg_panorama/`` and ``nyc_instance_panorama/`` ``panorama_<n>.png``;
  ``nyc_semantic_list.txt``;
- scene ``Demo`` in the demo sample's naming: ``panorama/panorama_<n>.png``; ``depth/Depth_<n>.exr`` (OpenEXR, the
  range in the R channel, G and B zero) except the last frame, ``depth/panorama_<n>.npy``; ``semantic/``,
  ``instance/``; ``semantic_lists_demo.txt``.

Labels: RGBA PNGs with the class id in alpha (semantic: the class colour in RGB; instance: one RGB per object). The
class lists give the two scenes different ids for the same names (ids are per scene), one name (``Statue``) that the
benchmark table does not know, and alpha 0 for the sky in ``Demo`` (unlisted there: background).

The scene, in the panorama's frame (x right, y down, z ahead; the ERP convention written out in :func:`erp_ray`):
ground ``y = +1.5`` (road where ``x < 0``, grass elsewhere), walls ``x = +6`` (fence), ``x = -4`` (tree),
``z = +8 + frame`` (building), ``z = -5`` (statue), all up to ``y = -3``; sky above, its depth the 1000 m far plane.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

#: Label name -> RGB (semantic PNGs, and the panorama's colours).
COLORS = {
    "Sky": (70, 130, 180),
    "Road": (128, 64, 128),
    "Grass": (152, 251, 152),
    "Fence": (190, 153, 153),
    "Tree_01": (107, 142, 35),
    "Building": (70, 70, 70),
    "Statue": (250, 170, 30),
}
NAMES = tuple(COLORS)
#: Per scene: name -> class id (the alpha values). Demo leaves the sky unlisted: alpha 0, background.
CLASS_IDS = {
    "NYC": {"Sky": 1, "Road": 2, "Grass": 3, "Fence": 4, "Tree_01": 5, "Building": 6, "Statue": 7},
    "Demo": {"Building": 10, "Road": 20, "Grass": 30, "Fence": 40, "Tree_01": 50, "Statue": 60},
}
SKY_DEPTH = 1000.0  # the renderer's far plane


def erp_ray(height: int, width: int) -> np.ndarray:
    """Unit directions ``[H, W, 3]`` through the pixel centres of an ERP panorama: longitude
    ``2 pi (j + 0.5) / W - pi`` (0 straight ahead at the middle, increasing to the right), latitude
    ``pi / 2 - pi (i + 0.5) / H`` (the top row looks up), in x right, y down, z ahead."""
    lon = 2.0 * np.pi * (np.arange(width) + 0.5) / width - np.pi
    lat = np.pi / 2.0 - np.pi * (np.arange(height) + 0.5) / height
    lon, lat = np.meshgrid(lon, lat)
    return np.stack([np.cos(lat) * np.sin(lon), -np.sin(lat), np.cos(lat) * np.cos(lon)], axis=-1)


def scene_hit(directions: np.ndarray, frame: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(range [N] (inf: sky), name index [N] into NAMES, object [N])`` of directions ``[N, 3]`` (any length)."""
    d = directions / np.linalg.norm(directions, axis=-1, keepdims=True)
    planes = [
        (1, 1.5, None),
        (0, 6.0, "Fence"),
        (0, -4.0, "Tree_01"),
        (2, 8.0 + frame, "Building"),
        (2, -5.0, "Statue"),
    ]
    best = np.full(d.shape[:-1], np.inf)
    label = np.full(d.shape[:-1], NAMES.index("Sky"))
    obj = np.zeros(d.shape[:-1], np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k, (axis, offset, name) in enumerate(planes):
            t = offset / d[..., axis]
            t = np.where(t > 0, t, np.inf)
            if name is not None:  # walls end 3 m above the camera
                t = np.where(t * d[..., 1] >= -3.0, t, np.inf)
            closer = t < best
            best = np.where(closer, t, best)
            obj = np.where(closer, k + 1, obj)
            if name is None:
                ground = np.where(t * d[..., 0] < 0, NAMES.index("Road"), NAMES.index("Grass"))
                label = np.where(closer, ground, label)
            else:
                label = np.where(closer, NAMES.index(name), label)
    return best, label, obj


def render(height: int, width: int, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(rgb uint8 [H, W, 3], depth float32 [H, W] with the far plane for sky, name index, object)``."""
    rng, label, obj = scene_hit(erp_ray(height, width).reshape(-1, 3), frame)
    palette = np.array([COLORS[n] for n in NAMES], np.int64)
    shade = (np.arange(height * width) % 7 - 3)[:, None]  # a little texture, so bilinear sampling shows
    rgb = np.clip(palette[label] + shade, 0, 255).astype(np.uint8)
    depth = np.where(np.isfinite(rng), rng, SKY_DEPTH).astype(np.float32)
    shape = (height, width)
    return rgb.reshape(*shape, 3), depth.reshape(shape), label.reshape(shape), obj.reshape(shape)


def _rgba(rgb: np.ndarray, alpha: np.ndarray) -> Image.Image:
    return Image.fromarray(np.dstack([rgb, alpha]).astype(np.uint8), "RGBA")


def _write_labels(folder: Path, seg_dir: str, ins_dir: str, stem: str, ids: dict, label, obj) -> None:
    alpha = np.array([ids.get(n, 0) for n in NAMES], np.uint8)[label]
    colours = np.array([COLORS[n] for n in NAMES], np.uint8)[label]
    _rgba(colours, alpha).save(folder / seg_dir / f"{stem}.png")
    # Instance RGB: one colour per object (the ground's road and grass are one object of two classes).
    instance_rgb = np.stack([obj * 40 % 256, obj * 90 % 256, obj * 20 + 5], -1).astype(np.uint8)
    _rgba(instance_rgb, alpha).save(folder / ins_dir / f"{stem}.png")


def write_h5_depth(path: Path, depth: np.ndarray) -> None:
    """The release's encoding: HDF5 dataset ``/depth``, float32 metres."""
    import h5py

    with h5py.File(path, "w") as h5:
        h5.create_dataset("depth", data=depth.astype(np.float32))


def write_exr_depth(path: Path, depth: np.ndarray) -> None:
    """The demo's encoding: the range in an EXR's R channel (a three-channel float image)."""
    import OpenEXR

    zero = np.zeros_like(depth, np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"R": depth.astype(np.float32), "G": zero, "B": zero}) as exr:
        exr.write(str(path))


def write_omni360_fixture(root: Path, height: int = 32, frames: int = 5) -> Path:
    """Write the two scenes (module docstring) of ``frames`` frames each at ``height x 2 height``; returns ``root``."""
    width = 2 * height
    nyc, demo = root / "NYC", root / "Demo"
    for folder in (
        "nyc_Raw_Part1",
        "nyc_Raw_Part2",
        "nyc_Depth",
        "nyc_seg_panorama",
        "nyc_instance_panorama",
    ):
        (nyc / folder).mkdir(parents=True, exist_ok=True)
    for folder in ("panorama", "depth", "semantic", "instance"):
        (demo / folder).mkdir(parents=True, exist_ok=True)
    for scene, name in ((nyc, "NYC"), (demo, "Demo")):
        listing = scene / ("nyc_semantic_list.txt" if name == "NYC" else "semantic_lists_demo.txt")
        lines = [f"{n} {i}" for n, i in sorted(CLASS_IDS[name].items(), key=lambda kv: kv[1])]
        listing.write_text("\n".join(lines) + "\n", encoding="utf-8")
    for n in range(frames):
        stem = f"panorama_{n}"
        rgb, depth, label, obj = render(height, width, n)
        part = "nyc_Raw_Part1" if n < (frames + 1) // 2 else "nyc_Raw_Part2"
        Image.fromarray(rgb).save(nyc / part / f"{stem}.png")
        write_h5_depth(nyc / "nyc_Depth" / f"Depth_{n}.h5", depth)
        _write_labels(nyc, "nyc_seg_panorama", "nyc_instance_panorama", stem, CLASS_IDS["NYC"], label, obj)
        _rgba(rgb, np.full(depth.shape, 255, np.uint8)).save(
            demo / "panorama" / f"{stem}.png"
        )  # UE writes RGBA
        if n < frames - 1:
            write_exr_depth(demo / "depth" / f"Depth_{n}.exr", depth)
        else:
            np.save(demo / "depth" / f"{stem}.npy", depth)
        _write_labels(demo, "semantic", "instance", stem, CLASS_IDS["Demo"], label, obj)
    return root
