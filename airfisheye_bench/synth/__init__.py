"""Procedural synthetic AirFisheye generator: scenes, ray casting and rendering (writer: see the writer modules).

Example:
    >>> from airfisheye_bench.synth import Scene, Lighting, ENVIRONMENTS
    >>> ENVIRONMENTS
    ('suburban', 'modular_houses', 'town', 'downtown')
"""

from airfisheye_bench.synth.classes import RAW_CLASSES, RAW_TO_TRAIN, SKY_ID, TRAIN_CLASSES, ClassInfo
from airfisheye_bench.synth.scene import ENVIRONMENTS, Lighting, RayHits, Scene

__all__ = [
    "ENVIRONMENTS",
    "RAW_CLASSES",
    "RAW_TO_TRAIN",
    "SKY_ID",
    "TRAIN_CLASSES",
    "ClassInfo",
    "Lighting",
    "RayHits",
    "Scene",
]
