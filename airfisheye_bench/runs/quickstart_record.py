"""A quick start next to its committed record: the one line ``python train.py task=<task>`` prints at its end.

The record (``docs/quickstart_results.json``, the README's quick-start table) holds the test results of
``python train.py task=<task> seed=<s>`` for seeds 0, 1 and 2, written by ``scripts/quickstart_benchmark.py``
(:mod:`airfisheye_bench.studies.quickstart`, which sits above training; the reading training needs is here,
below it). A run compares with it only when it trained as the quick start: its command line changed nothing that
is trained or tested (:func:`is_quick_start`) and its test data hold the record's content. The record lies in the
checkout's ``docs/``: an installed wheel has none, and then nothing is said.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from hydra.core.hydra_config import HydraConfig

__all__ = [
    "RECORD",
    "SAME_RUN_KEYS",
    "is_quick_start",
    "load_record",
    "quick_start_comparison",
    "quick_start_line",
]

#: The committed record, beside the package in a checkout.
RECORD = Path(__file__).resolve().parents[2] / "docs" / "quickstart_results.json"

#: Command-line keys (and the keys under them) that leave a run the quick start: which seed, resuming it, what is
#: logged or printed and how data is loaded; anything else (the data, lens, size, model, epochs, trainer) makes
#: another run than the record's.
SAME_RUN_KEYS = (
    "task",
    "seed",
    "ckpt_path",
    "retest",
    "resume_overrides_ok",
    "print_breakdown",
    "logger",
    "callbacks.progress",
    "callbacks.rich_progress_bar",
    "callbacks.lr_monitor",
    "data.num_workers",
    "data.persistent_workers",
    "data.pin_memory",
    "paths",
)


def is_quick_start(overrides: Iterable[str]) -> bool:
    """Whether a command line (``key=value`` overrides) trains the quick start of its task, as the record did.

    Example:
        >>> is_quick_start(["task=seg", "seed=1", "data.num_workers=0"]), is_quick_start([])
        (True, True)
        >>> is_quick_start(["task=seg", "data.preset=tiny"]), is_quick_start(["trainer=debug"])
        (False, False)
    """
    keys = [o.lstrip("+~").partition("=")[0] for o in overrides]
    return all(any(k == a or k.startswith(a + ".") for a in SAME_RUN_KEYS) for k in keys)


def load_record(path: str | Path = RECORD) -> dict[str, Any] | None:
    """The record, or ``None`` where there is none (an installed wheel) or it cannot be read."""
    try:
        record = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def quick_start_comparison(
    record: Mapping[str, Any],
    task: str,
    metrics: Mapping[str, Any],
    seed: int,
    threads: int,
    content_sha256: str | None,
) -> str | None:
    """One line: the record of ``task`` (mean ± std over its seeds, their range, the same seed's value) and where
    this run's test value of the primary metric (in ``metrics``) falls; ``None`` when the record has no such task,
    is not in the expected shape, or the run has no such value.

    Example:
        >>> record = {"dataset": {"content_sha256": "8cf07d19" + "0" * 56}, "tasks": {"seg": {
        ...     "primary_metric": "mIoU", "higher_is_better": True,
        ...     "summary": {"mIoU": {"mean": 0.244, "std": 0.014}},
        ...     "seeds": {s: {"metrics": {"mIoU": v}, "omp_num_threads": "1"}
        ...               for s, v in (("0", 0.239), ("1", 0.260), ("2", 0.233))}}}}
        >>> print(quick_start_comparison(record, "seg", {"mIoU": 0.232}, 0, 2, "8cf07d19" + "0" * 56))
        quick-start record (README table; seeds 0, 1, 2, 1 thread): mIoU 0.244 ± 0.014, seeds 0.233 to 0.260 (seed 0: 0.239); this run 0.232 (seed 0, 2 threads): below the seeds' range (worse than every seed); see README, "Quick start", and docs/evaluation.md, "Comparing with the quick-start table"
        >>> print(quick_start_comparison(record, "seg", {"mIoU": 0.25}, 3, 1, "ab" * 32))
        quick-start record (README table): not comparable, measured on other data (content 8cf07d19; this run's abababab)
    """
    try:
        entry = record["tasks"][task]
        primary = entry["primary_metric"]
        seeds = {int(s): float(r["metrics"][primary]) for s, r in entry["seeds"].items()}
        summary = entry["summary"][primary]
        mean, std = float(summary["mean"]), summary.get("std")
        higher = bool(entry.get("higher_is_better", True))
        threads_used = {str(r.get("omp_num_threads")) for r in entry["seeds"].values()}
        content = str(record["dataset"]["content_sha256"])
        value = float(metrics[primary])
    except (KeyError, TypeError, ValueError, AttributeError):
        return None
    if not seeds:
        return None
    if content_sha256 != content:
        return (
            f"quick-start record (README table): not comparable, measured on other data (content {content[:8]}; "
            f"this run's {(content_sha256 or 'unknown')[:8]})"
        )
    low, high = min(seeds.values()), max(seeds.values())
    spread = f" ± {float(std):.3f}" if std is not None else ""
    same_seed = f" (seed {seed}: {seeds[seed]:.3f})" if seed in seeds else ""
    if low <= value <= high:
        where = "within the seeds' range"
    else:
        better = (value > high) == higher
        where = (
            f"{'above' if value > high else 'below'} the seeds' range "
            f"({'better' if better else 'worse'} than every seed)"
        )
    recorded_threads = (
        f", {_threads(int(next(iter(threads_used))))}"
        if len(threads_used) == 1 and next(iter(threads_used)).isdigit()
        else ""
    )
    return (
        f"quick-start record (README table; seeds {', '.join(map(str, sorted(seeds)))}{recorded_threads}): "
        f"{primary} {mean:.3f}{spread}, seeds {low:.3f} to {high:.3f}{same_seed}; this run {value:.3f} "
        f'(seed {seed}, {_threads(threads)}): {where}; see README, "Quick start", and docs/evaluation.md, '
        '"Comparing with the quick-start table"'
    )


def quick_start_line(
    task: str, metrics: Mapping[str, Any], seed: int, threads: int, content_sha256: str | None
) -> str | None:
    """:func:`quick_start_comparison` for the running ``train.py`` when its command line trained the quick start and
    a record is there; ``None`` otherwise (a library caller, another configuration, an installed wheel)."""
    if not HydraConfig.initialized() or not is_quick_start(HydraConfig.get().overrides.task):
        return None
    record = load_record(RECORD)
    return quick_start_comparison(record, task, metrics, seed, threads, content_sha256) if record else None


def _threads(n: int) -> str:
    return f"{n} thread{'s' if n != 1 else ''}"
