"""TartanAir V2 semantic labels -> the benchmark's training classes: the one table, :data:`TARTANAIR_TO_TRAIN`.

TartanAir V2 labels are per environment: each environment folder holds ``seg_label_map.json``,
``{"name_map": {"<label name>": <uint8 value in the seg PNGs>, ...}}`` (github:castacks/tartanairpy
``tartanair/visualizer.py`` ``vis_seg_palette`` reads it so; ``docs/modalities.rst``, "Raw semantic segmentation").
The same value means different things in different environments, so a value is mapped through its environment's
names: name -> training class by :data:`TARTANAIR_TO_TRAIN` (exact names, lower case, as the toolkit's
``segfiles.zip`` lists them); a name absent from the table, and a value absent from the map, is ignored (255).

The training classes are the synthetic dataset's 13 (``airfisheye_bench.synth.classes.TRAIN_CLASSES``; this layer
may not import ``synth``, so :data:`TRAIN_CLASS_NAMES` repeats them and a test checks they agree).

Example:
    >>> lut = label_lut({"sky": 3, "building": 59, "chair": 180})
    >>> lut[[3, 59, 180, 7]].tolist()
    [0, 6, 255, 255]
"""

from __future__ import annotations

import numpy as np

IGNORE = 255

#: The synthetic dataset's training classes (id = position) and their palette colours.
TRAIN_CLASSES: tuple[tuple[str, tuple[int, int, int]], ...] = (
    ("sky", (70, 130, 180)),
    ("road", (128, 64, 128)),
    ("sidewalk", (244, 35, 232)),
    ("grass", (152, 251, 152)),
    ("ground", (150, 110, 70)),
    ("water", (30, 60, 220)),
    ("building", (70, 70, 70)),
    ("roof", (180, 40, 40)),
    ("tree", (107, 142, 35)),
    ("bush", (60, 200, 60)),
    ("vehicle", (0, 0, 142)),
    ("pole", (153, 153, 153)),
    ("barrier", (190, 153, 153)),
)
TRAIN_CLASS_NAMES: tuple[str, ...] = tuple(name for name, _ in TRAIN_CLASSES)

#: TartanAir V2 label name -> training class name. Chosen from the names of all environments in
#: github:castacks/tartanairpy ``segfiles.zip``: outdoor surfaces and objects the synthetic classes describe. Indoor
#: furniture, props and ambiguous names (``instancedfoliageactor``, ``staticmeshactor``, ``z``) stay unmapped.
TARTANAIR_TO_TRAIN: dict[str, str] = {
    # sky
    "sky": "sky",
    "skysphere": "sky",
    "sky0": "sky",
    # road
    "road": "road",
    "roadelevated": "road",
    "groundasphalt": "road",
    "floorcrosswalk": "road",
    "roadmarkers": "road",
    # sidewalk
    "sidewalk": "sidewalk",
    "bridgesidewalk": "sidewalk",
    "walkway": "sidewalk",
    "elevatedwalkway": "sidewalk",
    "groundpavement": "sidewalk",
    "groundpavers": "sidewalk",
    "groundcobblestone": "sidewalk",
    # grass
    "grass": "grass",
    "grassclump": "grass",
    "groundgrass": "grass",
    # ground (bare ground, terrain and walkable floors)
    "ground": "ground",
    "groundconcrete": "ground",
    "grounddirt": "ground",
    "groundlandscape": "ground",
    "groundstones": "ground",
    "groundtile": "ground",
    "groundembankment": "ground",
    "groundtiretracks": "ground",
    "landscape": "ground",
    "dirt": "ground",
    "floor": "ground",
    "floordirt": "ground",
    "rock": "ground",
    "stone": "ground",
    "mountain": "ground",
    # water
    "water": "water",
    "waterplane": "water",
    "waterfall": "water",
    # building (walls of buildings: TartanAir's ``wall`` is mostly a building's wall)
    "building": "building",
    "buildingbase": "building",
    "buildingstructure": "building",
    "buildingtower": "building",
    "house": "building",
    "wall": "building",
    "concretewall": "building",
    "wallinterior": "building",
    "window": "building",
    "door": "building",
    "balcony": "building",
    "chimney": "building",
    "column": "building",
    "pillar": "building",
    "ceiling": "building",
    "stairs": "building",
    "stair": "building",
    "steps": "building",
    # roof
    "roof": "roof",
    "rooftrim": "roof",
    "roofdetail": "roof",
    "roofcaps": "roof",
    "pentroof": "roof",
    # tree
    "tree": "tree",
    "trees": "tree",
    "treetrunk": "tree",
    "leaves": "tree",
    "foliage": "tree",
    "log": "tree",
    # bush
    "bush": "bush",
    "hedge": "bush",
    "plant": "bush",
    "plants": "bush",
    "plantsivy": "bush",
    "groundplant": "bush",
    "flower": "bush",
    # vehicle
    "car": "vehicle",
    "truck": "vehicle",
    "vehicle": "vehicle",
    "cargocar": "vehicle",
    "semitrailer": "vehicle",
    # pole (poles and what they carry)
    "pole": "pole",
    "lightpole": "pole",
    "utilitypole": "pole",
    "signpole": "pole",
    "trafficlightpole": "pole",
    "powerlinepole": "pole",
    "telegraphpole": "pole",
    "electricpole": "pole",
    "metalpole": "pole",
    "woodpole": "pole",
    "post": "pole",
    "lamppost": "pole",
    "lightpost": "pole",
    "signpost": "pole",
    "streetlight": "pole",
    "streetlamp": "pole",
    "trafficlight": "pole",
    "sign": "pole",
    "streetsign": "pole",
    "streetsigns": "pole",
    "trafficsign": "pole",
    # barrier
    "fence": "barrier",
    "fencepost": "barrier",
    "metalfence": "barrier",
    "woodenfence": "barrier",
    "railing": "barrier",
    "metalrailing": "barrier",
    "woodenrailing": "barrier",
    "bridgerailing": "barrier",
    "guardrail": "barrier",
    "barrier": "barrier",
    "concretebarrier": "barrier",
    "trafficbarrier": "barrier",
    "plasticbarrier": "barrier",
    "bollard": "barrier",
    "gate": "barrier",
    "metalgate": "barrier",
    "perimeterwall": "barrier",
    "dividerwall": "barrier",
}


def train_id(name: str) -> int:
    """The training id of a TartanAir label name (:data:`IGNORE` when the table does not map it).

    Example:
        >>> train_id("Sidewalk"), train_id("chair")
        (2, 255)
    """
    target = TARTANAIR_TO_TRAIN.get(name.strip().lower())
    return IGNORE if target is None else TRAIN_CLASS_NAMES.index(target)


def label_lut(name_map: dict[str, int]) -> np.ndarray:
    """``uint8 [256]``: seg PNG value -> training id, for one environment's ``name_map``."""
    lut = np.full(256, IGNORE, dtype=np.uint8)
    for name, value in name_map.items():
        lut[int(value)] = train_id(name)
    return lut


__all__ = ["IGNORE", "TARTANAIR_TO_TRAIN", "TRAIN_CLASSES", "TRAIN_CLASS_NAMES", "label_lut", "train_id"]
