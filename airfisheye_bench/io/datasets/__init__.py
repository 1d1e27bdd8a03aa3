"""The dataset formats the benchmark reads, one :class:`~airfisheye_bench.io.datasets.base.DatasetSource` each.

``data.format`` picks one (``docs/design.md``, "Dataset formats"); :func:`open_dataset` builds it.

Example:
    >>> sorted(DATASET_FORMATS)[:1]
    ['airfisheye']
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.io.datasets.base import (
    DatasetSource,
    DepthPoints,
    check_options,
    modalities_of,
    unserved_modality,
)
from airfisheye_bench.io.datasets.kitti360 import Kitti360Source
from airfisheye_bench.io.datasets.omni360 import Omni360Source
from airfisheye_bench.io.datasets.tartanair import TartanAirSource
from airfisheye_bench.io.datasets.woodscape import WoodScapeSource
from airfisheye_bench.io.reader import DatasetReader

#: ``data.format`` -> the class reading that format: ``cls(root, **options)``, its options and their defaults in
#: ``cls.OPTIONS`` (``data.format_options``).
DATASET_FORMATS: dict[str, type] = {
    "airfisheye": DatasetReader,
    "kitti360": Kitti360Source,
    "omni360": Omni360Source,
    "tartanair": TartanAirSource,
    "woodscape": WoodScapeSource,
}


def open_dataset(
    root: str | Path, format: str = "airfisheye", options: dict[str, Any] | None = None
) -> DatasetSource:
    """The :class:`DatasetSource` of ``root`` in ``format`` (its ``data.format_options`` in ``options``)."""
    if format not in DATASET_FORMATS:
        raise ConfigError(f"data.format={format!r}: expected one of {', '.join(DATASET_FORMATS)}")
    cls = DATASET_FORMATS[format]
    return cls(root, **check_options(format, dict(options or {}), cls.OPTIONS))


__all__ = [
    "DATASET_FORMATS",
    "DatasetSource",
    "DepthPoints",
    "check_options",
    "modalities_of",
    "open_dataset",
    "unserved_modality",
]
