"""The sources of a run on several datasets: ``data.sources`` and ``data.source_options`` resolved and checked.

A source is a dataset root in any :data:`~airfisheye_bench.io.datasets.DATASET_FORMATS` format, or a synthetic
preset. ``data.sources`` lists source *names*; a name means something by itself, and
``data.source_options.<name>`` sets or overrides its settings (:data:`SOURCE_KEYS`):

* ``synthetic``: the synthetic ``data.preset`` (``quickstart`` when null) at ``data.dataset_seed``;
* a synthetic preset (``tiny``, ``quickstart``, ...): that preset at ``data.dataset_seed``;
* a format (``airfisheye``, ``tartanair``, ...): that format; its root and options are ``data.root`` /
  ``data.format_options`` when ``data.format`` is that format, else ``data.source_options.<name>.root``;
* any other name: only what ``data.source_options.<name>`` gives (a ``root``, or a ``preset``).

The classes of every source are the benchmark's training classes (:data:`~airfisheye_bench.synth.classes.TRAIN_CLASSES`,
:class:`CommonClasses`); a source whose dataset has other training classes maps them with
``class_map: {its class: a benchmark class or null (ignored)}`` (:func:`class_lut`). Nothing here reads a dataset:
``train.py`` resolves the sources before it writes anything. :mod:`datamodules.multi_source` serves them
(docs/design.md, "More than one source").

Example:
    >>> sources = resolve_sources(["tiny", "tiny_b"], {"tiny_b": {"preset": "tiny", "dataset_seed": 1}},
    ...                           defaults={"preset": "quickstart"})
    >>> [(s.name, s.preset, s.dataset_seed, s.root) for s in sources]
    [('tiny', 'tiny', 0, None), ('tiny_b', 'tiny', 1, None)]
    >>> resolve_sources(["tiny", "mine"], None)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    airfisheye_bench.errors.ConfigError: data.sources: unknown source name 'mine'; a source is synthetic (data.preset), ...
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from airfisheye_bench.errors import ConfigError, UserError
from airfisheye_bench.io import DatasetFormatError
from airfisheye_bench.io.dataset_spec import IMAGE_SOURCES
from airfisheye_bench.io.datasets import DATASET_FORMATS, dataset_format, root_description
from airfisheye_bench.synth.classes import TRAIN_CLASSES
from airfisheye_bench.synth.presets import PRESETS

#: The settings of one source (``data.source_options.<name>.<key>``); unset ones follow the name and ``data.*``.
SOURCE_KEYS = (
    "format",  # how root is laid out (DATASET_FORMATS)
    "root",  # the dataset folder; null: the synthetic preset
    "format_options",  # that format's options
    "preset",  # the synthetic preset (root null)
    "dataset_seed",  # the synthetic dataset's seed
    "splits",  # [train, val, test] split names of this source (default data.splits)
    "source",  # cubemap | fisheye image source of this source (default data.source)
    "class_map",  # {its training class: a benchmark class, or null: ignored}
    "weight",  # sampling proportion (all sources or none)
)
#: The names a source takes by itself besides the presets and the formats.
SYNTHETIC = "synthetic"
#: The name of a run's one source when ``data.sources`` is unset (never shown: its samples are served unprefixed).
SINGLE = "data"
#: The preset of ``synthetic`` when ``data.preset`` is null (configs/data/synthetic.yaml's).
DEFAULT_PRESET = "quickstart"
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]*$")
#: Breakdown groups of the metrics: a source may not be named like one (``test/<source>/<metric>`` keys).
_RESERVED_PREFIXES = ("ring_", "range_")


def check_location(format: str, root: str | Path | None, preset: str | None, key: str = "data") -> None:
    """Refuse a dataset location that cannot be read: an unknown format, no root for a format that needs one, an
    unknown preset, a root that is no folder. ``key`` is the config path the message names.

    Raises:
        ConfigError: naming ``<key>.format`` / ``<key>.root`` / ``<key>.preset`` and what is expected.

    Example:
        >>> check_location("airfisheye", None, "tny")
        Traceback (most recent call last):
        ...
        airfisheye_bench.errors.ConfigError: data.preset='tny': expected one of tiny, quickstart, ... (or give data.root)
    """
    dataset_format(format, f"{key}.format")
    if root is None and format != "airfisheye":
        raise ConfigError(
            f"{key}.format={format} reads that dataset from disk: give {key}.root=/path/to/it (see the dataset "
            "table of docs/datasets.md)"
        )
    if root is None and preset is None:
        raise ConfigError(
            f"give {key}.root (a dataset folder) or {key}.preset (a synthetic preset such as quickstart)"
        )
    if root is None and preset not in PRESETS:  # refused before anything is generated
        raise ConfigError(
            f"{key}.preset={preset!r}: expected one of {', '.join(PRESETS)} (or give {key}.root)"
        )
    if root is not None and not Path(root).is_dir():
        raise ConfigError(f"{key}.root={str(root)!r} is not a folder; point it at {root_description(format)}")


@dataclass(frozen=True)
class SourceConfig:
    """One resolved source of a run (see the module docstring for how a name resolves).

    Attributes:
        name: Its name in ``data.sources`` (logged metrics: ``<stage>/<name>/<metric>``).
        format: How ``root`` is laid out.
        root: The dataset folder, or ``None`` for the synthetic ``preset``.
        format_options: The format's options.
        preset: The synthetic preset (``root`` ``None``).
        dataset_seed: The synthetic dataset's seed.
        splits: Its train, val and test split names (``None``: ``data.splits``).
        source: ``cubemap`` or ``fisheye`` (``None``: ``data.source``).
        class_map: Its training class name -> benchmark class name or ``None`` (ignored); ``None``: same classes.
        weight: Its sampling proportion (``None``: every frame once per epoch).
    """

    name: str
    format: str = "airfisheye"
    root: str | None = None
    format_options: dict[str, Any] = field(default_factory=dict)
    preset: str | None = None
    dataset_seed: int = 0
    splits: tuple[str, str, str] | None = None
    source: str | None = None
    class_map: dict[str, str | None] | None = None
    weight: float | None = None

    @property
    def key(self) -> str:
        """The config path of its settings, for messages."""
        return f"data.source_options.{self.name}"

    def describe(self) -> str:
        """``tiny_b (synthetic tiny, dataset_seed 1)`` or ``woodscape (woodscape at /data/ws)``."""
        if self.root is None:
            return f"{self.name} (synthetic {self.preset}, dataset_seed {self.dataset_seed})"
        return f"{self.name} ({self.format} at {self.root})"

    def record(self) -> dict[str, Any]:
        """What ``results.json`` records of the source's settings."""
        out: dict[str, Any] = {"source": self.name, "format": self.format}
        if self.root is None:
            out |= {"preset": self.preset, "dataset_seed": self.dataset_seed}
        else:
            out["root"] = str(self.root)
        if self.format_options:
            out["format_options"] = dict(self.format_options)
        if self.weight is not None:
            out["weight"] = self.weight
        return out


def single_source(location: Mapping[str, Any]) -> SourceConfig:
    """The one source of a run without ``data.sources``: the top-level ``data.format``, ``root``,
    ``format_options``, ``preset`` and ``dataset_seed``, checked by :func:`check_location` (messages name ``data.*``).

    Example:
        >>> single_source({"preset": "tiny"})
        SourceConfig(name='data', format='airfisheye', root=None, format_options={}, preset='tiny', dataset_seed=0, splits=None, source=None, class_map=None, weight=None)
    """
    fmt, root, preset = location.get("format") or "airfisheye", location.get("root"), location.get("preset")
    check_location(fmt, root, preset)
    return SourceConfig(
        name=SINGLE,
        format=fmt,
        root=str(root) if root is not None else None,
        format_options=_plain(dict(location.get("format_options") or {})),
        preset=preset if root is None else None,
        dataset_seed=int(location.get("dataset_seed") or 0),
    )


@contextlib.contextmanager
def naming_source(source: SourceConfig, mixture: bool) -> Iterator[None]:
    """Name ``source`` in front of a user error raised inside (a run of several sources: which one failed); a run
    of one source keeps the message as it is."""
    if not mixture:
        yield
        return
    try:
        yield
    except DatasetFormatError as err:  # built from its file and message: the file stays first
        raise type(err)(
            err.path, f"{err.message} (data.sources: source {source.describe()})", err.key
        ) from None
    except UserError as err:
        raise type(err)(f"data.sources: source {source.describe()}: {err}") from None
    except ValueError as err:
        raise ConfigError(f"data.sources: source {source.describe()}: {err}") from None


def resolve_sources(
    names: Sequence[str] | None,
    options: Mapping[str, Mapping[str, Any] | None] | None,
    defaults: Mapping[str, Any] | None = None,
) -> tuple[SourceConfig, ...]:
    """``data.sources`` and ``data.source_options`` -> the run's sources, checked (nothing is read or generated).

    Args:
        names: ``data.sources`` (``None`` or empty: a single-source run, returns ``()``).
        options: ``data.source_options``: settings by source name (:data:`SOURCE_KEYS`).
        defaults: The top-level ``data`` keys a name inherits (``format``, ``root``, ``format_options``,
            ``preset``, ``dataset_seed``).

    Raises:
        ConfigError: one line naming the key: an unknown or repeated source name, settings for a name not in
            ``data.sources``, an unknown setting, a location that cannot be read, weights on some sources only.
    """
    if names is None or (isinstance(names, Sequence) and not isinstance(names, str) and not names):
        return ()
    if isinstance(names, str) or not isinstance(names, Sequence):
        raise ConfigError(
            f"data.sources={names!r}: expected a list of source names, e.g. data.sources=[tiny,quickstart]"
        )
    names = [str(n) for n in names]
    defaults = dict(defaults or {})
    options = dict(options or {})
    if not isinstance(options, Mapping):
        raise ConfigError(
            "data.source_options: expected settings by source name, e.g. {tiny_b: {preset: tiny}}"
        )
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ConfigError(f"data.sources lists {repeated} more than once; give each source one name")
    stray = sorted(set(options) - set(names))
    if stray:
        raise ConfigError(
            f"data.source_options.{stray[0]}: no source {stray[0]!r} in data.sources={names}; add it there or "
            "drop its settings"
        )
    sources = tuple(_resolve(name, dict(options.get(name) or {}), defaults) for name in names)
    weighted = [s.name for s in sources if s.weight is not None]
    if weighted and len(weighted) != len(sources):
        unweighted = [s.name for s in sources if s.weight is None]
        raise ConfigError(
            f"data.source_options.{unweighted[0]}.weight is unset but {weighted} have one: give every source a "
            "weight (sampling proportions) or none (every frame once per epoch)"
        )
    return sources


def _resolve(name: str, given: dict[str, Any], defaults: Mapping[str, Any]) -> SourceConfig:
    key = f"data.source_options.{name}"
    if not _NAME.match(name) or name.startswith(_RESERVED_PREFIXES):
        raise ConfigError(
            f"data.sources: {name!r} is not a source name: letters, digits, '_' and '-', not starting with "
            f"{' or '.join(_RESERVED_PREFIXES)} (the metric breakdown's keys)"
        )
    unknown = sorted(set(given) - set(SOURCE_KEYS))
    if unknown:
        raise ConfigError(f"{key}.{unknown[0]}: unknown setting; a source takes {', '.join(SOURCE_KEYS)}")
    implied: dict[str, Any]
    if name == SYNTHETIC:
        # data=tartanair and the like set no preset: the synthetic data is then the default preset's.
        implied = {"format": "airfisheye", "root": None, "preset": defaults.get("preset") or DEFAULT_PRESET}
    elif name in PRESETS:
        implied = {"format": "airfisheye", "root": None, "preset": name}
    elif name in DATASET_FORMATS:
        same = defaults.get("format", "airfisheye") == name
        implied = {
            "format": name,
            "root": defaults.get("root") if same else None,
            "format_options": defaults.get("format_options") if same else None,
            "preset": None,
        }
    elif given.get("root") is None and given.get("preset") is None:
        raise ConfigError(
            f"data.sources: unknown source name {name!r}; a source is {SYNTHETIC} (data.preset), a synthetic "
            f"preset ({', '.join(PRESETS)}), a format ({', '.join(DATASET_FORMATS)}), or any name with a root or "
            f"preset under {key} (e.g. {key}.root=/path {key}.format=airfisheye)"
        )
    else:
        implied = {"format": "airfisheye", "root": None, "preset": None}
    settings = {"dataset_seed": defaults.get("dataset_seed", 0), **implied, **given}
    if settings.get("root") is not None:
        settings["preset"] = given.get("preset")  # a root is read as it is: no preset applies
    fmt, root, preset = settings.get("format") or "airfisheye", settings.get("root"), settings.get("preset")
    try:
        check_location(fmt, root, preset, key)
    except ConfigError as err:
        raise ConfigError(f"data.sources: source {name}: {err}") from None
    image_source = settings.get("source")
    if image_source is not None and image_source not in IMAGE_SOURCES:
        raise ConfigError(f"{key}.source={image_source!r}: expected one of {', '.join(IMAGE_SOURCES)}")
    splits = settings.get("splits")
    if splits is not None and (isinstance(splits, str) or len(splits) != 3):
        raise ConfigError(f"{key}.splits={splits!r}: expected [train, val, test] split names")
    class_map = settings.get("class_map")
    if class_map is not None and not isinstance(class_map, Mapping):
        raise ConfigError(
            f"{key}.class_map: expected {{its class: a benchmark class or null}}, got {class_map!r}"
        )
    weight = settings.get("weight")
    if weight is not None and (
        isinstance(weight, bool) or not isinstance(weight, (int, float)) or not weight > 0
    ):
        raise ConfigError(f"{key}.weight={weight!r}: expected a number > 0 (a sampling proportion)")
    seed = settings.get("dataset_seed")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(f"{key}.dataset_seed={seed!r}: expected an integer >= 0")
    return SourceConfig(
        name=name,
        format=fmt,
        root=str(root) if root is not None else None,
        format_options=_plain(dict(settings.get("format_options") or {})),
        preset=preset if root is None else None,
        dataset_seed=seed,
        splits=tuple(str(s) for s in splits) if splits is not None else None,
        source=image_source,
        class_map={str(k): (None if v is None else str(v)) for k, v in class_map.items()}
        if class_map
        else None,
        weight=float(weight) if weight is not None else None,
    )


def _plain(value: Any) -> Any:
    """Config containers (OmegaConf's, from Hydra) as plain dicts and lists, for records and JSON."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, Sequence) and not isinstance(value, str):
        return [_plain(v) for v in value]
    return value


# ------------------------------------------------------------------------------------------------- classes


@dataclass(frozen=True)
class CommonClasses:
    """The training classes every source is served in (what a ``DatasetSpec`` offers the datamodule of them).

    Example:
        >>> common = CommonClasses.benchmark("tiny + tiny_b")
        >>> common.num_train_classes, common.train_class_names[:2], common.train_palette()[1].tolist()
        (13, ['sky', 'road'], [128, 64, 128])
    """

    name: str
    train_class_names: list[str]
    colors: tuple[tuple[int, int, int], ...]
    ignore_index: int = 255

    @classmethod
    def benchmark(cls, name: str) -> CommonClasses:
        """The benchmark's training classes (the synthetic dataset's)."""
        return cls(name, [c.name for c in TRAIN_CLASSES], tuple(tuple(c.color) for c in TRAIN_CLASSES))

    @property
    def num_train_classes(self) -> int:
        return len(self.train_class_names)

    def train_palette(self) -> np.ndarray:
        """``uint8 [256, 3]`` colours by training id."""
        pal = np.zeros((256, 3), np.uint8)
        pal[: len(self.colors)] = np.asarray(self.colors, np.uint8)
        return pal


def class_lut(
    source: SourceConfig, names: Sequence[str], ignore_index: int, common: CommonClasses
) -> torch.Tensor | None:
    """``int64 [256]`` lookup table: a source's training id -> the common id (``None``: the same classes).

    Raises:
        ConfigError: the source has other classes and no (or an incomplete) ``class_map``, naming it.

    Example:
        >>> common = CommonClasses.benchmark("x")
        >>> src = SourceConfig("ws", root="/ws", class_map={"car": "vehicle", "lane": "road", "void": None})
        >>> lut = class_lut(src, ["void", "car", "lane"], 255, common)
        >>> lut[[0, 1, 2, 255]].tolist()
        [255, 10, 1, 255]
    """
    names = list(names)
    if source.class_map is None:
        if names == common.train_class_names:
            return None
        raise ConfigError(
            f"{source.key}.class_map is needed: source {source.name} has the training classes {names}, not the "
            f"benchmark's {common.train_class_names}; map each of its classes to one of these (or null: ignored)"
        )
    missing = [n for n in names if n not in source.class_map]
    extra = sorted(set(source.class_map) - set(names))
    bad = sorted(
        {v for v in source.class_map.values() if v is not None and v not in common.train_class_names}
    )
    if missing or extra or bad:
        problem = (
            f"misses its classes {missing}"
            if missing
            else f"names {extra}, not classes of its dataset ({names})"
            if extra
            else f"maps to {bad}, not benchmark classes ({common.train_class_names})"
        )
        raise ConfigError(f"{source.key}.class_map {problem}")
    lut = torch.full((256,), common.ignore_index, dtype=torch.int64)
    for i, n in enumerate(names):
        target = source.class_map[n]
        if target is not None:
            lut[i] = common.train_class_names.index(target)
    lut[ignore_index] = common.ignore_index
    return lut


def mixture_identity(sources: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The identity of a run's mixture from its sources' identities (``results.json``'s ``dataset``).

    ``content_sha256`` hashes the sources' content identities and weights, in order, when every source has one,
    so a leaderboard groups runs on the same mixture together.

    Example:
        >>> m = mixture_identity([{"source": "a", "content_sha256": "1" * 64}, {"source": "b", "content_sha256": "2" * 64}])
        >>> m["name"], m["sources"], len(m["content_sha256"])
        ('a + b', ['a', 'b'], 64)
    """
    names = [str(s["source"]) for s in sources]
    identity: dict[str, Any] = {"name": " + ".join(names), "sources": names}
    if all(s.get("content_sha256") for s in sources):
        parts = [[s["content_sha256"], s.get("weight")] for s in sources]
        identity["content_sha256"] = hashlib.sha256(json.dumps(parts).encode()).hexdigest()
    return identity


__all__ = [
    "DEFAULT_PRESET",
    "SINGLE",
    "SOURCE_KEYS",
    "SYNTHETIC",
    "CommonClasses",
    "SourceConfig",
    "check_location",
    "class_lut",
    "mixture_identity",
    "naming_source",
    "resolve_sources",
    "single_source",
]
