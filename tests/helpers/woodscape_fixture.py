"""A tiny WoodScape root in the real layout, written by the tests (no WoodScape file is in the repository).

Layout and encodings as github:valeoai/WoodScape documents them (``README.md``, ``scripts/calibration/front.json``,
``scripts/parsers/segmentation/image_annotator.py``): ``rgb_images/<id>_<CAM>.png`` (RGB),
``semantic_annotations/gtLabels/<id>_<CAM>.png`` (8-bit single channel, class index 0..9) and ``rgbLabels`` (the
colours, written as cv2 writes them), ``calibration/<id>_<CAM>.json`` (``front.json``'s keys, floats as there).
The ids are real ones of the devkit's lists, so they land in the split the devkit puts them in.

Images are 128x98 (crop_to_4x3 serves 128x96, dropping row 0 and row 97); the calibration is ``front.json``'s
scaled by 0.1, each camera nudged a little (as WoodScape's per-vehicle calibrations differ).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from tests.helpers import calibration_fixtures as fx

#: Ids of ``omnidet/data/train.txt`` and ``val.txt`` (github:valeoai/WoodScape).
TRAIN_IDS = ("00000_FV", "00001_FV", "00028_RV", "00044_MVR", "00140_MVL", "00141_MVL")
VAL_IDS = ("00020_FV", "00102_MVR", "00165_MVL", "00175_RV")
WIDTH, HEIGHT = 128, 98

#: ``scripts/calibration/front.json`` (github:valeoai/WoodScape).
FRONT_JSON = fx.WOODSCAPE_FRONT
#: ``semantic_mapping_9_classes.json``'s BGR colours by class index (void 0 is black).
BGR = [(0, 0, 0), (255, 0, 255), (255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 255), (255, 255, 0),
       (0, 255, 255), (128, 128, 255), (0, 128, 128)]  # fmt: skip
_NUDGE = {
    "FV": (0.0, 0.0, 1.0),
    "MVL": (0.4, -0.3, 1.004),
    "MVR": (-0.5, 0.2, 0.997),
    "RV": (0.3, 0.5, 1.002),
}


def calibration(view: str, scale: float = 0.1) -> dict:
    """``front.json`` scaled to a ``WIDTH x HEIGHT`` image, the camera ``view``'s nudge applied."""
    dx, dy, k = _NUDGE[view]
    doc = json.loads(json.dumps(FRONT_JSON))
    intr = doc["intrinsic"]
    for i in range(1, 5):
        intr[f"k{i}"] = round(intr[f"k{i}"] * scale * k, 6)
    intr["cx_offset"] = round(intr["cx_offset"] * scale + dx, 4)
    intr["cy_offset"] = round(intr["cy_offset"] * scale + dy, 4)
    intr["width"], intr["height"] = float(WIDTH), float(HEIGHT)
    doc["name"] = view
    return doc


def label_of(index: int) -> np.ndarray:
    """The gtLabels of image ``index``: stripes of every class, and class ``index % 10`` at row 1, columns 0..3."""
    label = (np.arange(WIDTH)[None, :] // 13 % 10).repeat(HEIGHT, 0).astype(np.uint8)
    label[1, :4] = index % 10
    return label


def rgb_of(index: int) -> np.ndarray:
    """The RGB image of image ``index``: a gradient, pixel (row 1, col 0) = (index, 1, 2)."""
    v, u = np.mgrid[:HEIGHT, :WIDTH]
    rgb = np.stack([u * 2, v * 2, np.full_like(u, 40 + index)], -1).astype(np.uint8)
    rgb[1, 0] = (index, 1, 2)
    return rgb


def write_woodscape(root: Path, calib_dir: str = "calibration") -> Path:
    """Write the fixture under ``root``; returns ``root``."""
    for folder in (
        "rgb_images",
        "semantic_annotations/gtLabels",
        "semantic_annotations/rgbLabels",
        calib_dir,
    ):
        (root / folder).mkdir(parents=True, exist_ok=True)
    for index, sid in enumerate(TRAIN_IDS + VAL_IDS):
        view = sid.split("_")[1]
        Image.fromarray(rgb_of(index), "RGB").save(root / "rgb_images" / f"{sid}.png")
        label = label_of(index)
        Image.fromarray(label, "L").save(root / "semantic_annotations" / "gtLabels" / f"{sid}.png")
        # cv2.imwrite of a BGR array: the file holds RGB = BGR reversed.
        colours = np.array(BGR, np.uint8)[label]
        Image.fromarray(colours[..., ::-1].copy(), "RGB").save(
            root / "semantic_annotations/rgbLabels" / f"{sid}.png"
        )
        (root / calib_dir / f"{sid}.json").write_text(json.dumps(calibration(view), indent=2))
    return root
