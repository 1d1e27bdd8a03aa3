"""``results.json``: one evaluated model on one split, in the format the leaderboard collects.

``{"version", "task", "split", "primary_metric", "metrics": {key: value}, "breakdown": {"ring_60-80/rmse": ...},
"dataset": {...identity...}, "model": {...}, "config": {...}, "created": ISO time}``, and for completion
``"sparse_coverage": {"ring_0-30": ...}`` (the sparse input's pixels per ground-truth pixel by ring). Metric values are fractions
(mIoU 0.512) or metres; NaN (e.g. a class absent from the split) is written as ``null``.

``model`` says what was evaluated, which the leaderboard labels each row with (:func:`evaluated_label`):
``source`` (``checkpoint`` | ``onnx`` | ``predictions``), ``checkpoint`` / ``onnx`` / ``predictions`` (the file
or folder), ``precision`` of an ONNX model (``fp32`` | ``int8``), ``tta`` (``null`` | ``flip``), ``stage``
(``training`` for the test at the end of ``train.py``, else absent), ``run_name``, the training run the weights
come from (:func:`~airfisheye_bench.runs.checkpoint_run_name`) or the ``name=`` given, and for the weights of a
multirun's job ``sweep_overrides``, what its sweep chose (``["data.batch_size=8", ...]``,
:mod:`airfisheye_bench.sweeps`). Files written before these
keys existed stay readable: a missing key is inferred where it can be (an ``.int8.onnx`` file name, the run
directory of the checkpoint) and left out of the label otherwise.

Training (its test at the end of a run) and evaluation write and read the record through this module, and print it
with :func:`format_results_table`; it sits in ``runs``, beside the run directories it is written into and below
both, so neither depends on the other.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.io.content import content_identity
from airfisheye_bench.specs import get_task

__all__ = [
    "RESULTS_VERSION",
    "dataset_identity",
    "evaluated_label",
    "format_results_table",
    "load_results",
    "write_results",
]

RESULTS_VERSION = 1


def json_safe(value: Any) -> Any:
    """``value`` as JSON holds it: tensors and numpy scalars as numbers, NaN and infinities as ``null``, tuples as
    lists, keys as strings."""
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
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
    sources: dict[str, Any] | None = None,
    sparse_coverage: dict[str, float] | None = None,
    cross_lens: dict[str, Any] | None = None,
) -> Path:
    """Write ``results.json`` atomically and return its path; ``primary_metric`` is the task spec's.

    ``sources`` (a run of several datasets, ``data.sources``): by source name, ``{"dataset": its identity,
    "metrics": ..., "breakdown": ...}``; ``metrics`` and ``breakdown`` are then the pooled ones and ``dataset`` the
    mixture's identity (:func:`source_records` turns such a file into one record per source).

    ``sparse_coverage`` (a task with a sparse input: completion): its pixels per ground-truth pixel by ring over the
    split, ``{"ring_0-30": 0.031, ...}`` (``datamodules.coverage``), how dense the input the model saw was.

    ``cross_lens`` (``lenses=`` / ``robustness=true``): the model scored on each test lens
    (:mod:`airfisheye_bench.evaluation.cross_lens`).
    """
    primary = get_task(task).primary_metric
    record = {
        "version": RESULTS_VERSION,
        "task": task,
        "split": split,
        "primary_metric": primary,
        "metrics": json_safe(metrics),
        "breakdown": json_safe(breakdown or {}),
        "dataset": json_safe(dataset or {}),
        "model": json_safe(model or {}),
        "config": json_safe(config or {}),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }
    if sparse_coverage is not None:
        record["sparse_coverage"] = json_safe(sparse_coverage)
    if sources:
        record["sources"] = json_safe(sources)
    if cross_lens:
        record["cross_lens"] = json_safe(cross_lens)
    path = Path(path)
    atomic_write_text(path, json.dumps(record, indent=2, sort_keys=False) + "\n")
    return path


def evaluated_label(model: Mapping[str, Any]) -> str:
    """What a ``results.json`` measured, from its ``model`` record: the source, its precision and TTA.

    Example:
        >>> evaluated_label({"source": "checkpoint", "checkpoint": "run/checkpoints/epoch_003.ckpt"})
        'checkpoint epoch_003'
        >>> evaluated_label({"source": "checkpoint", "checkpoint": "r/checkpoints/last.ckpt", "stage": "training"})
        'checkpoint last (training test)'
        >>> evaluated_label({"source": "onnx", "precision": "int8", "tta": "flip"})
        'ONNX int8, flip TTA'
        >>> evaluated_label({"source": "onnx", "onnx": "model.int8.onnx"})  # written before "precision" existed
        'ONNX int8'
        >>> evaluated_label({"source": "predictions"}), evaluated_label({})
        ('predictions', '')
        >>> evaluated_label({"source": "onnx", "scored_on": {"source": "tiny", "of": "tiny + other"}})
        'ONNX, its tiny frames (of tiny + other)'
    """
    source = model.get("source")
    checkpoint = model.get("checkpoint")
    if source is None and checkpoint:  # train.py wrote no source before it recorded the stage
        source = "checkpoint"
    if source == "checkpoint":
        label = f"checkpoint {Path(str(checkpoint)).stem}" if checkpoint else "checkpoint"
        if model.get("stage") == "training" or "source" not in model:
            label += " (training test)"
    elif source == "onnx":
        precision = model.get("precision")
        if precision is None and str(model.get("onnx", "")).endswith(".int8.onnx"):
            precision = "int8"
        label = f"ONNX {precision}" if precision else "ONNX"
    else:
        label = str(source or "")
    if model.get("tta"):
        label += f", {model['tta']} TTA"
    scored_on = model.get("scored_on")
    if isinstance(scored_on, Mapping):  # one source's frames of a run on several (source_records)
        label += f", its {scored_on.get('source')} frames (of {scored_on.get('of')})"
    return label


def dataset_identity(root: str | Path, name: str) -> dict[str, Any]:
    """Which data a result was measured on: name, root, the SHA-256 of its ``manifest.json`` when present, and
    ``content_sha256``, the identity of what its files hold (:func:`~airfisheye_bench.io.content.content_identity`:
    the same on every installation that generates the same data, unlike the manifest's file checksums)."""
    root = Path(root)
    identity: dict[str, Any] = {"root": str(root), "name": name}
    manifest = root / "manifest.json"
    if manifest.is_file():
        identity["manifest_sha256"] = hashlib.sha256(manifest.read_bytes()).hexdigest()
        identity["content_sha256"] = content_identity(root)["content_sha256"]
    return identity


def portable_identity(root: str | Path, name: str) -> dict[str, Any]:
    """:func:`dataset_identity` less the root: what a committed record names (a path of one machine's cache means
    nothing on another's)."""
    return {key: value for key, value in dataset_identity(root, name).items() if key != "root"}


def source_records(record: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The records a ``results.json`` stands for: itself, and for a run of several sources (``sources``) one more
    per source, holding that source's dataset identity, metrics and breakdown; its ``model.scored_on`` says which
    source of which mixture (:func:`evaluated_label` shows it). The leaderboard ranks each with its own dataset.

    Example:
        >>> record = {"task": "seg", "dataset": {"name": "a + b"}, "metrics": {"mIoU": 0.4}, "model": {},
        ...           "sources": {"a": {"dataset": {"name": "A"}, "metrics": {"mIoU": 0.5}},
        ...                       "b": {"dataset": {"name": "B"}, "metrics": {"mIoU": 0.3}}}}
        >>> [(r["dataset"]["name"], r["metrics"]["mIoU"], r["model"].get("scored_on")) for r in source_records(record)]
        [('a + b', 0.4, None), ('A', 0.5, {'source': 'a', 'of': 'a + b'}), ('B', 0.3, {'source': 'b', 'of': 'a + b'})]
    """
    pooled = {key: value for key, value in record.items() if key != "sources"}
    sources = record.get("sources") or {}
    if not isinstance(sources, Mapping):
        raise ValueError("'sources' must be an object: {source name: {dataset, metrics, breakdown}}")
    mixture = (pooled.get("dataset") or {}).get("name")
    records = [pooled]
    for name, part in sources.items():
        if not isinstance(part, Mapping):
            raise ValueError(f"sources.{name} must be an object with dataset, metrics and breakdown")
        model = {**(pooled.get("model") or {}), "scored_on": {"source": str(name), "of": mixture}}
        config = dict(pooled.get("config") or {})
        camera = (part.get("dataset") or {}).get("camera")
        if isinstance(camera, Mapping):  # the source's own served lens
            config["camera"] = camera
        records.append(
            {
                **pooled,
                "dataset": part.get("dataset") or {"name": str(name)},
                "metrics": part.get("metrics") or {},
                "breakdown": part.get("breakdown") or {},
                "model": model,
                "config": config,
            }
        )
    return records


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


def format_results_table(
    task: str, metrics: Mapping[str, Any], breakdown: Mapping[str, Any], primary: str
) -> str:
    """A plain-text table of the metrics and of the primary metric per ring and range (for the terminal).

    Example:
        >>> print(format_results_table("depth", {"rmse": 2.5}, {"ring_0-30/rmse": 2.0, "ring_0-30/mae": 1.0}, "rmse"))
        depth metrics
        ------------------------------------
        rmse                        2.5000
        <BLANKLINE>
        rmse by incidence-angle ring (deg)
        ------------------------------------
        ring_0-30                   2.0000
    """
    lines = [f"{task} metrics", "-" * 36]
    lines += [f"{key:<28}{_fmt(value)}" for key, value in metrics.items() if not key.startswith("IoU/")]
    per_class = {k[4:]: v for k, v in metrics.items() if k.startswith("IoU/")}
    if per_class:
        lines += ["", "IoU per class", "-" * 36]
        lines += [f"{name:<28}{_fmt(value)}" for name, value in per_class.items()]
    bins = {k.split("/")[0]: v for k, v in breakdown.items() if k.endswith(f"/{primary}")}
    if bins:
        kinds = "incidence-angle ring (deg)" + (
            " and depth range (m)" if any(k.startswith("range_") for k in bins) else ""
        )
        lines += ["", f"{primary} by {kinds}", "-" * 36]
        lines += [f"{name:<28}{_fmt(value)}" for name, value in bins.items()]
    return "\n".join(lines)


def _fmt(value: float | None) -> str:
    if value is None or value != value:
        return "-"
    return f"{value:.4f}"
