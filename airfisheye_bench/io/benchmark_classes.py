"""The benchmark's training classes: the 13 classes the synthetic AirFisheye data trains on.

They live here, below both ``synth`` (whose raw categories merge into them, :mod:`airfisheye_bench.synth.classes`)
and the public dataset sources of :mod:`airfisheye_bench.io.datasets`, which map their own classes onto them for
training on several sources at once (``data.format_options.classes: benchmark``; each source documents its table).

Example:
    >>> [c.name for c in BENCHMARK_CLASSES][:3]
    ['sky', 'road', 'sidewalk']
    >>> BENCHMARK_ID["vehicle"]
    10
"""

from __future__ import annotations

from airfisheye_bench.io.dataset_spec import ClassDef

__all__ = ["BENCHMARK_CLASSES", "BENCHMARK_ID"]

BENCHMARK_CLASSES: tuple[ClassDef, ...] = (
    ClassDef(0, "sky", (70, 130, 180)),
    ClassDef(1, "road", (128, 64, 128)),
    ClassDef(2, "sidewalk", (244, 35, 232)),
    ClassDef(3, "grass", (152, 251, 152)),
    ClassDef(4, "ground", (150, 110, 70)),
    ClassDef(5, "water", (30, 60, 220)),
    ClassDef(6, "building", (70, 70, 70)),
    ClassDef(7, "roof", (180, 40, 40)),
    ClassDef(8, "tree", (107, 142, 35)),
    ClassDef(9, "bush", (60, 200, 60)),
    ClassDef(10, "vehicle", (0, 0, 142)),
    ClassDef(11, "pole", (153, 153, 153)),
    ClassDef(12, "barrier", (190, 153, 153)),
)

#: Benchmark class name -> its training id.
BENCHMARK_ID: dict[str, int] = {c.name: c.id for c in BENCHMARK_CLASSES}
