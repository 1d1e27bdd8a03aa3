"""Deterministic YAML reading and writing shared by ``dataset.yaml`` and ``calib.yaml``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.io.errors import DatasetFormatError


def to_plain(obj: Any) -> Any:
    """Convert numpy scalars/arrays, tuples and paths to plain YAML-safe Python values (recursively)."""
    if isinstance(obj, dict):
        return {
            str(k) if not isinstance(k, int | np.integer) else int(k): to_plain(v) for k, v in obj.items()
        }
    if isinstance(obj, list | tuple):
        return [to_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_plain(obj.tolist())
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "tolist") and hasattr(obj, "dim"):  # torch tensor, without importing torch
        return to_plain(obj.tolist())
    return obj


def dump_yaml(data: dict, header: str | None = None) -> str:
    """Serialise ``data`` to YAML text with a stable key order and float formatting."""
    text = yaml.safe_dump(
        to_plain(data), sort_keys=False, default_flow_style=None, width=120, allow_unicode=True
    )
    if header:
        text = "".join(f"# {line}\n" if line else "#\n" for line in header.splitlines()) + text
    return text


def write_yaml(path: str | Path, data: dict, header: str | None = None) -> None:
    """Atomically write ``data`` as YAML (optionally preceded by a ``#`` comment ``header``)."""
    atomic_write_text(path, dump_yaml(data, header))


def read_yaml(path: str | Path) -> dict:
    """Read a YAML mapping; errors name the file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DatasetFormatError(path, "file does not exist") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise DatasetFormatError(path, f"invalid YAML ({exc})") from exc
    if not isinstance(data, dict):
        raise DatasetFormatError(path, f"top level must be a mapping, got {type(data).__name__}")
    return data


class FieldReader:
    """Typed access to nested YAML keys with errors naming the file and the dotted key.

    Example:
        >>> r = FieldReader("calib.yaml", {"cubemap": {"face_size": 64}})
        >>> r.int("cubemap.face_size", minimum=1)
        64
    """

    _MISSING = object()

    def __init__(self, path: str | Path, data: dict) -> None:
        self.path = Path(path)
        self.data = data

    def error(self, key: str, message: str) -> DatasetFormatError:
        return DatasetFormatError(self.path, message, key=key)

    def get(self, key: str, default: Any = _MISSING) -> Any:
        node: Any = self.data
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                if default is not self._MISSING:
                    return default
                raise self.error(key, "is missing")
            node = node[part]
        return node

    def mapping(self, key: str, default: Any = _MISSING) -> dict:
        value = self.get(key, default)
        if not isinstance(value, dict):
            raise self.error(key, f"must be a mapping, got {type(value).__name__}")
        return value

    def seq(self, key: str, default: Any = _MISSING) -> list:
        value = self.get(key, default)
        if not isinstance(value, list):
            raise self.error(key, f"must be a list, got {type(value).__name__}")
        return value

    def str(self, key: str, default: Any = _MISSING, choices: tuple[str, ...] | None = None) -> str:
        value = self.get(key, default)
        if not isinstance(value, str) or not value:
            raise self.error(key, f"must be a non-empty string, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {list(choices)}, got {value!r}")
        return value

    def int(
        self, key: str, default: Any = _MISSING, minimum: int | None = None, maximum: int | None = None
    ) -> int:
        value = self.get(key, default)
        return check_int(self, key, value, minimum, maximum)

    def float(self, key: str, default: Any = _MISSING, positive: bool = False) -> float:
        value = self.get(key, default)
        if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
            raise self.error(key, f"must be a finite number, got {value!r}")
        if positive and value <= 0:
            raise self.error(key, f"must be positive, got {value!r}")
        return float(value)

    def matrix(self, key: str, shape: tuple[int, ...]) -> np.ndarray:
        value = self.get(key)
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise self.error(key, f"must be a numeric array of shape {list(shape)}") from None
        if arr.shape != shape or not np.isfinite(arr).all():
            raise self.error(
                key, f"must be a finite numeric array of shape {list(shape)}, got shape {list(arr.shape)}"
            )
        return arr


def check_int(
    reader: FieldReader, key: str, value: Any, minimum: int | None = None, maximum: int | None = None
) -> int:
    """Validate that ``value`` is an int within bounds, raising an error that names ``key``."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise reader.error(key, f"must be an integer, got {value!r}")
    if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        raise reader.error(key, f"must be in [{minimum}, {maximum}], got {value}")
    return value
