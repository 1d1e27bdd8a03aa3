"""AirSim360 / Omni360-X class lists and their mapping onto training classes.

A scene's class list (``semantic_lists_<env>.txt`` in the demo sample, ``<prefix>_semantic_list`` in the
Omni360-Scene release) has one class a line: the name is the line's first word, the id its last (the reading of
github:Insta360-Research-Team/AirSim360 ``data/demo_sample/instance/read_instance_labels_example.py``
``load_id_to_class_name``, which also skips lines of fewer than two words). The id is what the label PNGs hold in
their alpha channel; alpha 0 is background ("usually background and can be ignored", the demo's
``instance/README.md``) unless the list names it.

Ids are per scene, so a pixel's alpha is mapped through its scene's list: id -> name -> training class. Two class
sets (``format_options.classes``):

- ``dataset``: every name of the selected scenes' lists, in the order they first appear (scenes sorted, each list
  by id); :func:`dataset_classes`.
- ``benchmark``: the benchmark's 13 classes (:mod:`airfisheye_bench.io.benchmark_classes`) through
  :data:`OMNI360_TO_BENCHMARK` (names compared lower case, letters only: ``Tree_01`` is ``tree``), with
  ``format_options.benchmark_map`` adding or overriding names. A name that neither covers is refused (one line
  naming the list file): the released lists were not published when this table was written, and a silently ignored
  class would distort every score of the class it belongs to.

Example:
    >>> table = benchmark_table(ClassList(Path("l.txt"), {0: "Sky", 3: "Road_02", 7: "Person"}), {})
    >>> table.lut[[0, 3, 7, 9]].tolist(), table.known[[0, 3, 9]].tolist()
    ([0, 1, 255, 255], [True, True, False])
"""

from __future__ import annotations

import colorsys
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.io.benchmark_classes import BENCHMARK_CLASSES, BENCHMARK_ID
from airfisheye_bench.io.dataset_spec import ClassDef
from airfisheye_bench.io.errors import DatasetFormatError

__all__ = [
    "BACKGROUND_ID",
    "IGNORE",
    "OMNI360_TO_BENCHMARK",
    "ClassList",
    "LabelTable",
    "benchmark_table",
    "check_benchmark_map",
    "dataset_classes",
    "dataset_table",
    "normalise",
    "read_class_list",
]

IGNORE = 255
#: The alpha of unlabelled pixels (ignored unless a list names it).
BACKGROUND_ID = 0

#: Omni360 class name (normalised: lower case, letters only) -> benchmark class, or ``None``: deliberately ignored
#: (no such benchmark class). The benchmark's own names first, then the usual names of Unreal Engine scene
#: categories and of Cityscapes-style label sets for the same things; TartanAir's rules where they overlap
#: (a wall is a building's, a sign is a pole, free-standing walls are barriers).
OMNI360_TO_BENCHMARK: dict[str, str | None] = {
    # sky
    "sky": "sky",
    "skysphere": "sky",
    "skydome": "sky",
    "skybox": "sky",
    "cloud": "sky",
    "clouds": "sky",
    # road
    "road": "road",
    "roads": "road",
    "street": "road",
    "asphalt": "road",
    "highway": "road",
    "lane": "road",
    "lanemarking": "road",
    "lanemarks": "road",
    "roadmarking": "road",
    "crosswalk": "road",
    "parking": "road",
    "parkinglot": "road",
    # sidewalk
    "sidewalk": "sidewalk",
    "pavement": "sidewalk",
    "walkway": "sidewalk",
    "footpath": "sidewalk",
    "path": "sidewalk",
    "plaza": "sidewalk",
    "curb": "sidewalk",
    "kerb": "sidewalk",
    # grass
    "grass": "grass",
    "lawn": "grass",
    "turf": "grass",
    # ground
    "ground": "ground",
    "terrain": "ground",
    "landscape": "ground",
    "dirt": "ground",
    "soil": "ground",
    "sand": "ground",
    "gravel": "ground",
    "rock": "ground",
    "rocks": "ground",
    "stone": "ground",
    "floor": "ground",
    "mountain": "ground",
    # water
    "water": "water",
    "river": "water",
    "lake": "water",
    "sea": "water",
    "ocean": "water",
    "pond": "water",
    # building
    "building": "building",
    "buildings": "building",
    "house": "building",
    "skyscraper": "building",
    "tower": "building",
    "wall": "building",
    "facade": "building",
    "window": "building",
    "door": "building",
    "stairs": "building",
    "bridge": "building",
    # roof
    "roof": "roof",
    "rooftop": "roof",
    # tree
    "tree": "tree",
    "trees": "tree",
    "trunk": "tree",
    "palm": "tree",
    "foliage": "tree",
    "vegetation": "tree",
    # bush
    "bush": "bush",
    "bushes": "bush",
    "shrub": "bush",
    "hedge": "bush",
    "plant": "bush",
    "plants": "bush",
    "flower": "bush",
    "flowers": "bush",
    # vehicle
    "vehicle": "vehicle",
    "vehicles": "vehicle",
    "car": "vehicle",
    "cars": "vehicle",
    "truck": "vehicle",
    "bus": "vehicle",
    "van": "vehicle",
    "taxi": "vehicle",
    "train": "vehicle",
    "tram": "vehicle",
    # pole
    "pole": "pole",
    "poles": "pole",
    "lamppost": "pole",
    "streetlight": "pole",
    "streetlamp": "pole",
    "lightpole": "pole",
    "utilitypole": "pole",
    "trafficlight": "pole",
    "trafficsign": "pole",
    "sign": "pole",
    "signpost": "pole",
    # barrier
    "barrier": "barrier",
    "fence": "barrier",
    "railing": "barrier",
    "guardrail": "barrier",
    "bollard": "barrier",
    "gate": "barrier",
    # no benchmark class: ignored on purpose
    "background": None,
    "unlabeled": None,
    "unlabelled": None,
    "none": None,
    "void": None,
    "other": None,
    "others": None,
    "person": None,
    "people": None,
    "pedestrian": None,
    "human": None,
    "rider": None,
    "bicycle": None,
    "motorcycle": None,
    "animal": None,
    "bird": None,
    "drone": None,
}

_LETTERS = re.compile(r"[^a-z]")


def normalise(name: str) -> str:
    """A class name as :data:`OMNI360_TO_BENCHMARK` keys it: lower case, letters only.

    Example:
        >>> normalise("Street_Light-02"), normalise("SkySphere")
        ('streetlight', 'skysphere')
    """
    return _LETTERS.sub("", name.lower())


@dataclass(frozen=True)
class ClassList:
    """One scene's class list: ``names`` maps the alpha id to the class name."""

    path: Path
    names: dict[int, str]


@dataclass(frozen=True)
class LabelTable:
    """A scene's alpha id -> training id (``lut``, ``uint8 [256]``, 255 ignored) and which alphas it knows
    (``known``, ``bool [256]``: the list's ids and the background); ``path`` is the list, for messages."""

    lut: np.ndarray
    known: np.ndarray
    path: Path


def read_class_list(path: str | Path) -> ClassList:
    """Parse a class list (module docstring); blank lines, ``#`` comments and lines of one word are skipped.

    Raises:
        DatasetFormatError: naming the file and line: a last word that is no integer in ``0..255``, an id listed
            twice, or no class at all.

    Example:
        >>> import tempfile
        >>> f = Path(tempfile.mkdtemp()) / "semantic_lists_nyc.txt"
        >>> _ = f.write_text("Sky 1\\nRoad  road surface 2\\n\\nclasses\\n")
        >>> read_class_list(f).names
        {1: 'Sky', 2: 'Road'}
    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise DatasetFormatError(path, "missing (the class names of the label ids)") from None
    except (OSError, UnicodeDecodeError) as err:
        raise DatasetFormatError(path, f"unreadable class list ({err})") from None
    names: dict[int, str] = {}
    for number, line in enumerate(lines, start=1):
        words = line.split()
        if len(words) < 2 or words[0].startswith("#"):
            continue
        try:
            class_id = int(words[-1])
        except ValueError:
            class_id = -1
        if not 0 <= class_id <= 255:
            raise DatasetFormatError(
                path,
                f"expected '<name> ... <id>' with an id in 0..255, got {line.strip()!r}",
                key=f"line {number}",
            )
        if class_id in names:
            raise DatasetFormatError(
                path,
                f"id {class_id} is listed twice ({names[class_id]!r}, {words[0]!r})",
                key=f"line {number}",
            )
        names[class_id] = words[0]
    if not names:
        raise DatasetFormatError(path, "no class: expected lines '<name> <id>'")
    return ClassList(path, names)


def dataset_classes(lists: Sequence[ClassList]) -> tuple[ClassDef, ...]:
    """``classes: dataset``: every name of ``lists`` once, in first appearance (each list by id), coloured apart.

    Example:
        >>> a = ClassList(Path("a"), {2: "road", 1: "sky"})
        >>> b = ClassList(Path("b"), {1: "sky", 5: "tree"})
        >>> [(c.id, c.name) for c in dataset_classes([a, b])]
        [(0, 'sky'), (1, 'road'), (2, 'tree')]
    """
    order: list[str] = []
    for class_list in lists:
        for _, name in sorted(class_list.names.items()):
            if name not in order:
                order.append(name)
    if len(order) > IGNORE:
        raise DatasetFormatError(
            lists[0].path, f"{len(order)} class names in the scenes' lists; at most {IGNORE} can be trained"
        )
    return tuple(ClassDef(i, name, _colour(i)) for i, name in enumerate(order))


def dataset_table(class_list: ClassList, classes: Sequence[ClassDef]) -> LabelTable:
    """A scene's alpha -> :func:`dataset_classes` id."""
    index = {c.name: c.id for c in classes}
    return _table(class_list, {i: index[name] for i, name in class_list.names.items()})


def benchmark_table(class_list: ClassList, benchmark_map: Mapping[str, str | None]) -> LabelTable:
    """A scene's alpha -> benchmark id: ``benchmark_map`` (exact names) first, then :data:`OMNI360_TO_BENCHMARK`.

    Raises:
        DatasetFormatError: naming the list and the names neither maps, and the option that maps them.
    """
    ids: dict[int, int] = {}
    unknown: list[str] = []
    for class_id, name in sorted(class_list.names.items()):
        if name in benchmark_map:
            target = benchmark_map[name]
        elif normalise(name) in OMNI360_TO_BENCHMARK:
            target = OMNI360_TO_BENCHMARK[normalise(name)]
        else:
            unknown.append(name)
            continue
        if target is not None:
            ids[class_id] = BENCHMARK_ID[target]
    if unknown:
        raise DatasetFormatError(
            class_list.path,
            f"class names {unknown} have no benchmark class: map each with data.format_options.benchmark_map="
            "{<name>: <a benchmark class, or null: ignored>} (or use data.format_options.classes=dataset)",
        )
    return _table(class_list, ids)


def check_benchmark_map(benchmark_map: Mapping | None, lists: Sequence[ClassList]) -> dict[str, str | None]:
    """``format_options.benchmark_map`` checked: names of the scenes' lists onto benchmark classes or null.

    Raises:
        ConfigError: a name no list has, or a target that is no benchmark class.

    Example:
        >>> check_benchmark_map({"Tarmac": "road"}, [ClassList(Path("l.txt"), {4: "Tarmac"})])
        {'Tarmac': 'road'}
    """
    if benchmark_map is None:
        return {}
    if not isinstance(benchmark_map, Mapping):
        raise ConfigError(
            f"data.format_options.benchmark_map={benchmark_map!r}: expected {{class name: benchmark class or null}}"
        )
    listed = {name for class_list in lists for name in class_list.names.values()}
    names = [c.name for c in BENCHMARK_CLASSES]
    out: dict[str, str | None] = {}
    for key, target in benchmark_map.items():
        if str(key) not in listed:
            raise ConfigError(
                f"data.format_options.benchmark_map.{key}: no scene's class list names {key!r} "
                f"(they name {sorted(listed)})"
            )
        if target is not None and target not in names:
            raise ConfigError(
                f"data.format_options.benchmark_map.{key}={target!r}: expected a benchmark class ({', '.join(names)}) "
                "or null (ignored)"
            )
        out[str(key)] = None if target is None else str(target)
    return out


def _table(class_list: ClassList, ids: Mapping[int, int]) -> LabelTable:
    lut = np.full(256, IGNORE, np.uint8)
    known = np.zeros(256, bool)
    known[list(class_list.names)] = True
    known[BACKGROUND_ID] = True
    for class_id, train_id in ids.items():
        lut[class_id] = train_id
    return LabelTable(lut, known, class_list.path)


def _colour(i: int) -> tuple[int, int, int]:
    """A display colour per class: hues a golden angle apart, so neighbouring ids differ."""
    r, g, b = colorsys.hsv_to_rgb((i * 0.618033988749895) % 1.0, 0.65, 0.9)
    return round(r * 255), round(g * 255), round(b * 255)
