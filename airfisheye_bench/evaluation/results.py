"""``results.json``: one evaluated model on one split, in the format the leaderboard collects.

``{"version", "task", "split", "primary_metric", "metrics": {key: value}, "breakdown": {"ring_60-80/rmse": ...},
"dataset": {...identity...}, "model": {...}, "config": {...}, "created": ISO time}``. Metric values are fractions
(mIoU 0.512) or metres; NaN (e.g. a class absent from the split) is written as ``null``.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import math
from pathlib import Path
from typing import Any

from airfisheye_bench.atomic import atomic_write_text

RESULTS_VERSION = 1
PRIMARY_METRIC = {"seg": "mIoU", "depth": "rmse", "completion": "rmse"}


def _clean(value: Any) -> Any:
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    return value


def write_results(
    path: str | Path,
    task: str,
    split: str,
    metrics: dict[str, Any],
    breakdown: dict[str, Any] | None = None,
    dataset: dict[str, Any] | None = None,
    model: dict[str, Any] | None = None,
    config: dict[str, Any] | None = None,
) -> Path:
    """Write ``results.json`` atomically and return its path."""
    if task not in PRIMARY_METRIC:
        raise ValueError(f"task must be one of {sorted(PRIMARY_METRIC)}, got {task!r}")
    record = {
        "version": RESULTS_VERSION,
        "task": task,
        "split": split,
        "primary_metric": PRIMARY_METRIC[task],
        "metrics": _clean(metrics),
        "breakdown": _clean(breakdown or {}),
        "dataset": _clean(dataset or {}),
        "model": _clean(model or {}),
        "config": _clean(config or {}),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }
    path = Path(path)
    atomic_write_text(path, json.dumps(record, indent=2, sort_keys=False) + "\n")
    return path


def dataset_identity(root: str | Path, name: str) -> dict[str, Any]:
    """Which data a result was measured on: name, root and the SHA-256 of its ``manifest.json`` when present."""
    root = Path(root)
    identity: dict[str, Any] = {"root": str(root), "name": name}
    manifest = root / "manifest.json"
    if manifest.is_file():
        identity["manifest_sha256"] = hashlib.sha256(manifest.read_bytes()).hexdigest()
    return identity


def load_results(path: str | Path) -> dict[str, Any]:
    """Read a ``results.json``; errors name the file and what is wrong."""
    path = Path(path)
    try:
        record = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise ValueError(f"{path}: not a readable results.json ({err})") from err
    missing = {"version", "task", "split", "metrics"} - set(record)
    if missing:
        raise ValueError(f"{path}: results.json is missing {sorted(missing)}")
    return record
