"""Semantic categories of the synthetic AirFisheye generator.

The paper labels 23 raw object categories and merges them into 13 training classes (Fig. 6); the exact lists
were never published, so these are our own, in the same spirit: fine-grained *raw* ids are what the renderer
writes to disk (``uint8``), and :data:`RAW_TO_TRAIN` is the merge that ``dataset.yaml`` records. ``255`` is the
ignore id in both spaces (e.g. pixels outside the fisheye image circle); it is not a class.

Example:
    >>> from airfisheye_bench.synth.classes import RAW_CLASSES, TRAIN_CLASSES, RAW_TO_TRAIN, SKY_ID
    >>> len(RAW_CLASSES), len(TRAIN_CLASSES)
    (23, 13)
    >>> TRAIN_CLASSES[RAW_TO_TRAIN[RAW_ID["lane_marking"]]].name
    'road'
    >>> raw_to_train_lut()[[SKY_ID, 255]].tolist()
    [0, 255]
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from airfisheye_bench.io.benchmark_classes import BENCHMARK_CLASSES

__all__ = [
    "IGNORE_ID",
    "RAW_CLASSES",
    "RAW_ID",
    "RAW_TO_TRAIN",
    "SKY_ID",
    "TRAIN_CLASSES",
    "ClassInfo",
    "raw_to_train_lut",
]

IGNORE_ID = 255


class ClassInfo(NamedTuple):
    """One semantic category: its id, name and a palette colour for visualisation (not a rendering albedo)."""

    id: int
    name: str
    color: tuple[int, int, int]


# Raw categories (ids are dense 0..22). The comment names the training class each one merges into.
RAW_CLASSES: list[ClassInfo] = [
    ClassInfo(0, "sky", (70, 130, 180)),  # sky
    ClassInfo(1, "road", (128, 64, 128)),  # road
    ClassInfo(2, "lane_marking", (255, 255, 255)),  # road
    ClassInfo(3, "parking", (160, 100, 160)),  # road
    ClassInfo(4, "sidewalk", (244, 35, 232)),  # sidewalk
    ClassInfo(5, "grass", (152, 251, 152)),  # grass
    ClassInfo(6, "bare_ground", (150, 110, 70)),  # ground
    ClassInfo(7, "water", (30, 60, 220)),  # water
    ClassInfo(8, "house", (220, 140, 70)),  # building
    ClassInfo(9, "building", (70, 70, 70)),  # building
    ClassInfo(10, "roof", (180, 40, 40)),  # roof
    ClassInfo(11, "tree", (107, 142, 35)),  # tree
    ClassInfo(12, "trunk", (90, 60, 20)),  # tree
    ClassInfo(13, "bush", (60, 200, 60)),  # bush
    ClassInfo(14, "hedge", (40, 160, 90)),  # bush
    ClassInfo(15, "car", (0, 0, 142)),  # vehicle
    ClassInfo(16, "van", (0, 60, 100)),  # vehicle
    ClassInfo(17, "lorry", (0, 0, 70)),  # vehicle
    ClassInfo(18, "pole", (153, 153, 153)),  # pole
    ClassInfo(19, "traffic_sign", (220, 220, 0)),  # pole
    ClassInfo(20, "fence", (190, 153, 153)),  # barrier
    ClassInfo(21, "wall", (102, 102, 156)),  # barrier
    ClassInfo(22, "street_furniture", (250, 170, 30)),  # barrier
]

# The training classes are the benchmark's (io.benchmark_classes), which the public datasets map onto too.
TRAIN_CLASSES: list[ClassInfo] = [ClassInfo(c.id, c.name, c.color) for c in BENCHMARK_CLASSES]

RAW_ID: dict[str, int] = {c.name: c.id for c in RAW_CLASSES}
_TRAIN_ID: dict[str, int] = {c.name: c.id for c in TRAIN_CLASSES}

_MERGE: dict[str, str] = {
    "sky": "sky",
    "road": "road",
    "lane_marking": "road",
    "parking": "road",
    "sidewalk": "sidewalk",
    "grass": "grass",
    "bare_ground": "ground",
    "water": "water",
    "house": "building",
    "building": "building",
    "roof": "roof",
    "tree": "tree",
    "trunk": "tree",
    "bush": "bush",
    "hedge": "bush",
    "car": "vehicle",
    "van": "vehicle",
    "lorry": "vehicle",
    "pole": "pole",
    "traffic_sign": "pole",
    "fence": "barrier",
    "wall": "barrier",
    "street_furniture": "barrier",
}

RAW_TO_TRAIN: dict[int, int] = {RAW_ID[raw]: _TRAIN_ID[train] for raw, train in _MERGE.items()}
"""Raw id -> training id for every raw class (the ignore id 255 is not a key; see :func:`raw_to_train_lut`)."""

SKY_ID: int = RAW_ID["sky"]


def raw_to_train_lut() -> np.ndarray:
    """A 256-entry ``uint8`` lookup table: ``lut[raw_label]`` gives training labels; unknown ids (and 255) map to 255.

    Example:
        >>> import numpy as np
        >>> raw_to_train_lut()[np.array([[1, 2], [255, 7]], dtype=np.uint8)].tolist()
        [[1, 1], [255, 5]]
    """
    lut = np.full(256, IGNORE_ID, dtype=np.uint8)
    for raw, train in RAW_TO_TRAIN.items():
        lut[raw] = train
    return lut
