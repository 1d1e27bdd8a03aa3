"""A one-image overview of a generated (or real) dataset sample, for a quick visual check.

Top block: the cube faces as a cross (up above front; left, front, right; down below) for RGB, raw labels and
depth. Bottom row: the pre-rendered fisheye RGB, the fisheye remapped from the cube faces
(``CubemapToFisheye``), fisheye labels and depth, and the LiDAR scan projected into the fisheye image
(motion-compensated ``T_cam_lidar``) coloured by range and by ground-truth visibility (green visible, red occluded).

By default the sheet is written inside the dataset folder, ``<root>/contact_sheet.png``: it travels with the data
it shows, and the manifest leaves it out (a preview, not data), so verification still passes.

Example:
    >>> path = write_contact_sheet("/data/tiny")   # /data/tiny/contact_sheet.png  # doctest: +SKIP
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from airfisheye_bench.atomic import atomic_write_bytes
from airfisheye_bench.geometry import FACE_NAMES, CubemapToFisheye
from airfisheye_bench.geometry.transforms import transform_points
from airfisheye_bench.io.codecs import encode_rgb
from airfisheye_bench.io.datasets.airfisheye import DatasetReader
from airfisheye_bench.io.layout import CONTACT_SHEET_NAME

_CROSS = {"up": (0, 1), "left": (1, 0), "front": (1, 1), "right": (1, 2), "down": (2, 1)}  # (row, col)
_CAPTION = 14


def turbo(x: np.ndarray) -> np.ndarray:
    """Turbo colour map (polynomial approximation) of values in [0, 1] -> ``uint8 [..., 3]``."""
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    r = 0.13572138 + x * (
        4.61539260 + x * (-42.66032258 + x * (132.13108234 + x * (-152.94239396 + x * 59.28637943)))
    )
    g = 0.09140261 + x * (
        2.19418839 + x * (4.84296658 + x * (-14.18503333 + x * (4.27729857 + x * 2.82956604)))
    )
    b = 0.10667330 + x * (
        12.64194608 + x * (-60.58204836 + x * (110.36276771 + x * (-89.90310912 + x * 27.34824973)))
    )
    return (np.clip(np.stack([r, g, b], -1), 0, 1) * 255 + 0.5).astype(np.uint8)


def colorize_depth(depth: np.ndarray, lo: float | None = None, hi: float | None = None) -> np.ndarray:
    """Range map -> colours on a log scale between ``lo`` and ``hi`` (default: the 1st/99th percentiles of the
    valid values); near = red, far = blue, black where invalid (0)."""
    d = np.asarray(depth, np.float64)
    valid = d > 0
    if not valid.any():
        return np.zeros((*d.shape, 3), np.uint8)
    lo = float(np.percentile(d[valid], 1)) if lo is None else lo
    hi = float(np.percentile(d[valid], 99)) if hi is None else hi
    lo, hi = max(lo, 1e-3), max(hi, lo * 1.01)
    x = 1.0 - (np.log(np.clip(d, lo, hi)) - np.log(lo)) / (np.log(hi) - np.log(lo))
    out = turbo(x)
    out[~valid] = 0
    return out


def colorize_labels(labels: np.ndarray, palette: np.ndarray) -> np.ndarray:
    """Label ids -> palette colours (``palette [256, 3]``); 255 stays black."""
    out = palette[labels]
    out[labels == 255] = 0
    return out


def _cross(faces: np.ndarray) -> np.ndarray:
    """``[5, S, S, 3]`` faces in FACE_NAMES order -> ``[3S, 3S, 3]`` cross."""
    s = faces.shape[1]
    out = np.full((3 * s, 3 * s, 3), 40, np.uint8)
    for f, name in enumerate(FACE_NAMES):
        r, c = _CROSS[name]
        out[r * s : (r + 1) * s, c * s : (c + 1) * s] = faces[f]
    return out


def _tile(img: np.ndarray, size: int, caption: str) -> Image.Image:
    """Resize (nearest, keeps labels crisp) to ``size`` wide and add a caption strip."""
    h, w = img.shape[:2]
    pil = Image.fromarray(img).resize((size, max(1, round(size * h / w))), Image.NEAREST)
    out = Image.new("RGB", (pil.width, pil.height + _CAPTION), (255, 255, 255))
    out.paste(pil, (0, _CAPTION))
    ImageDraw.Draw(out).text((2, 1), caption, fill=(0, 0, 0))
    return out


def _overlay(base: np.ndarray, uv: np.ndarray, colors: np.ndarray) -> np.ndarray:
    """Draw points (``uv [N, 2]`` pixel coordinates, far to near) over a darkened copy of ``base``."""
    out = (base.astype(np.float32) * 0.45).astype(np.uint8)
    h, w = out.shape[:2]
    row = np.clip(np.round(uv[:, 1]).astype(int), 0, h - 1)
    col = np.clip(np.round(uv[:, 0]).astype(int), 0, w - 1)
    out[row, col] = colors  # duplicates: NumPy keeps the last (nearest) in practice; fine for a preview
    return out


def make_contact_sheet(root: str | Path, sample_id: str | None = None, tile: int = 256) -> np.ndarray:
    """Compose the overview of one sample (default: the first training frame) -> ``uint8 [H, W, 3]``."""
    reader = DatasetReader(root)
    spec = reader.spec
    if sample_id is None:
        split = "train" if "train" in reader.split_names else reader.split_names[0]
        sample_id = reader.split(split)[0]
    raw_pal = spec.raw_palette()
    calib = reader.calib(sample_id)
    camera = calib.fisheye_camera()
    tiles: list[list[Image.Image]] = [[], []]

    cube_rgb = None
    if spec.has("cubemap"):
        cube_rgb = reader.cubemap(sample_id, "rgb")
        cube_seg = reader.cubemap(sample_id, "seg")
        cube_depth = reader.cubemap(sample_id, "depth")
        depth_range = (
            np.percentile(cube_depth[cube_depth > 0], [1, 99]) if (cube_depth > 0).any() else (1.0, 120.0)
        )
        tiles[0] += [
            _tile(_cross(cube_rgb), tile, "cube faces: RGB"),
            _tile(_cross(colorize_labels(cube_seg, raw_pal)), tile, "cube faces: raw labels"),
            _tile(_cross(colorize_depth(cube_depth, *depth_range)), tile, "cube faces: depth (log)"),
        ]

    if spec.has("fisheye"):
        fish_rgb = reader.fisheye(sample_id, "rgb")
        fish_seg = reader.fisheye(sample_id, "seg")
        fish_depth = reader.fisheye(sample_id, "depth")
        source = spec.sensors.get("fisheye", {}).get("source", "")
        tiles[1].append(_tile(fish_rgb, tile, f"fisheye RGB ({source})".replace(" ()", "")))
    else:
        fish_rgb = fish_seg = fish_depth = None
    if cube_rgb is not None:
        remap = CubemapToFisheye(camera, cube_rgb.shape[1])
        remapped = remap.remap(np.ascontiguousarray(cube_rgb.transpose(0, 3, 1, 2)), mode="bilinear")
        remapped = np.ascontiguousarray(remapped.transpose(1, 2, 0))
        tiles[1].append(_tile(remapped, tile, "fisheye remapped from cube"))
        if fish_rgb is None:
            fish_rgb = remapped
    if fish_seg is not None:
        tiles[1] += [
            _tile(colorize_labels(fish_seg, raw_pal), tile, "fisheye raw labels"),
            _tile(colorize_depth(fish_depth), tile, "fisheye depth (log, 1-99 %)"),
        ]

    if spec.has("lidar") and fish_rgb is not None:
        points = reader.lidar(sample_id)
        cam_pts = transform_points(reader.T_cam_lidar(sample_id), points[:, :3].astype(np.float64))
        uv, valid = camera.project(cam_pts)
        valid &= camera.in_image(uv)
        rng = np.linalg.norm(cam_pts, axis=1)
        order = np.argsort(-rng[valid])  # far first, near points drawn on top
        uv_v, rng_v = uv[valid][order], rng[valid][order]
        lo_hi = (
            (None, None)
            if fish_depth is None or not (fish_depth > 0).any()
            else np.percentile(fish_depth[fish_depth > 0], [1, 99])
        )
        colors = colorize_depth(rng_v, *lo_hi) if len(rng_v) else np.zeros((0, 3), np.uint8)
        tiles[1].append(_tile(_overlay(fish_rgb, uv_v, colors), tile, "LiDAR by range"))
        if spec.has("lidar_visible"):
            vis = reader.lidar_visible(sample_id)[valid][order]
            colors = np.where(
                vis[:, None], np.array([[40, 220, 40]], np.uint8), np.array([[230, 30, 30]], np.uint8)
            )
            tiles[1].append(_tile(_overlay(fish_rgb, uv_v, colors), tile, "LiDAR: visible / occluded"))

    rows = [r for r in tiles if r]
    width = max(sum(t.width for t in r) for r in rows)
    height = sum(max(t.height for t in r) for r in rows) + _CAPTION
    sheet = Image.new("RGB", (width, height), (255, 255, 255))
    ImageDraw.Draw(sheet).text((2, 1), f"{spec.name}: {sample_id}", fill=(0, 0, 0))
    y = _CAPTION
    for r in rows:
        x = 0
        for t in r:
            sheet.paste(t, (x, y))
            x += t.width
        y += max(t.height for t in r)
    return np.asarray(sheet)


def write_contact_sheet(
    root: str | Path, out_path: str | Path | None = None, sample_id: str | None = None, tile: int = 256
) -> Path:
    """Write :func:`make_contact_sheet` as a PNG (atomically) and return its path.

    Args:
        root: The dataset folder.
        out_path: Where to write; default ``<root>/contact_sheet.png`` (:data:`CONTACT_SHEET_NAME`).
        sample_id: The frame to show (default: the first of the first split).
        tile: Width of a tile in pixels.
    """
    out_path = Path(root) / CONTACT_SHEET_NAME if out_path is None else Path(out_path)
    atomic_write_bytes(out_path, encode_rgb(make_contact_sheet(root, sample_id, tile), ".png"))
    return out_path
