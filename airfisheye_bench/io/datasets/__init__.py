"""The dataset formats the benchmark reads, one :class:`~airfisheye_bench.io.datasets.base.DatasetSource` subclass
each.

``data.format`` picks one (``docs/design.md``, "Dataset formats"); :func:`open_dataset` builds it.

Example:
    >>> sorted(DATASET_FORMATS)[:1]
    ['airfisheye']
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.io.datasets.airfisheye import DatasetReader
from airfisheye_bench.io.datasets.base import (
    DatasetSource,
    DepthPoints,
    check_options,
    legacy_lidar,
    lidar_option_conflict,
    modalities_of,
    unserved_modality,
)
from airfisheye_bench.io.datasets.kitti360 import Kitti360Source
from airfisheye_bench.io.datasets.omni360 import Omni360Source
from airfisheye_bench.io.datasets.tartanair import TartanAirSource
from airfisheye_bench.io.datasets.woodscape import WoodScapeSource

#: ``data.format`` -> the class reading that format: ``cls(root, **options)``, its options and their defaults in
#: ``cls.OPTIONS`` (``data.format_options``).
DATASET_FORMATS: dict[str, type[DatasetSource]] = {
    "airfisheye": DatasetReader,
    "kitti360": Kitti360Source,
    "omni360": Omni360Source,
    "tartanair": TartanAirSource,
    "woodscape": WoodScapeSource,
}


def root_description(format: str) -> str:
    """What ``data.root`` must point at in ``format`` (said wherever a root is refused: the config check, the
    datamodule).

    Example:
        >>> root_description("kitti360")
        'the root of the kitti360 dataset, as the dataset table of docs/datasets.md shows it'
    """
    if format not in DATASET_FORMATS or format == "airfisheye":
        return "a dataset in the AirFisheye layout, holding dataset.yaml; null: the synthetic data.preset"
    return f"the root of the {format} dataset, as the dataset table of docs/datasets.md shows it"


def open_dataset(
    root: str | Path, format: str = "airfisheye", options: dict[str, Any] | None = None
) -> DatasetSource:
    """The :class:`DatasetSource` of ``root`` in ``format`` (its ``data.format_options`` in ``options``)."""
    cls = dataset_format(format)
    return cls(root, **check_options(format, dict(options or {}), cls.OPTIONS))


def dataset_format(format: str, key: str = "data.format") -> type[DatasetSource]:
    """The reader class of ``format``: the one rule of ``data.format`` (``key`` names it in the message).

    Raises:
        ConfigError: ``format`` is none of :data:`DATASET_FORMATS`.
    """
    if format not in DATASET_FORMATS:
        raise ConfigError(f"{key}={format!r}: expected one of {', '.join(DATASET_FORMATS)}")
    return DATASET_FORMATS[format]


__all__ = [
    "DATASET_FORMATS",
    "DatasetSource",
    "DepthPoints",
    "check_options",
    "dataset_format",
    "legacy_lidar",
    "lidar_option_conflict",
    "modalities_of",
    "open_dataset",
    "root_description",
    "unserved_modality",
]
