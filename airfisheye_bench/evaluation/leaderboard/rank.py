"""Ranking: each task's rows grouped by dataset and split, ranked by the task's primary metric as printed."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from airfisheye_bench.evaluation.leaderboard.collect import LeaderboardEntry
from airfisheye_bench.evaluation.leaderboard.columns import (
    BIN_KEY,
    format_value,
    higher_is_better,
    is_percent,
)
from airfisheye_bench.specs import get_task

__all__ = ["GROUPING", "LeaderboardGroup", "TaskTable", "competition_ranks", "task_table"]

#: Which hash groups the rows, as the markdown and the page say it (backticks mark code).
GROUPING = (
    "Ranks restart for every dataset and split: a dataset is its name and its content hash (`content_sha256` of "
    "`results.json`, a SHA-256 of its decoded data, the same on every installation; a table's title shows its "
    "first 8 hex digits, `content 1a2b3c4d`), or its manifest hash (`manifest_sha256`, `manifest 1a2b3c4d`) for "
    "results written before the content hash existed. Results measured on different data are not comparable."
)


@dataclass(frozen=True)
class LeaderboardGroup:
    """Rows measured on the same dataset and split, best first; ``rank`` is ``None`` without a primary value."""

    title: str
    rows: tuple[tuple[int | None, LeaderboardEntry], ...]


@dataclass(frozen=True)
class TaskTable:
    """One task's section: its metric columns, the rim ring column (if any result has one) and its groups."""

    task: str
    primary: str
    columns: tuple[str, ...]
    rim_key: str | None
    groups: tuple[LeaderboardGroup, ...]

    @property
    def title(self) -> str:
        """The task's human-readable name (``Semantic segmentation``)."""
        return get_task(self.task).title

    @property
    def higher_is_better(self) -> bool:
        return higher_is_better(self.primary)


def _rim_key(entries: Iterable[LeaderboardEntry], primary: str) -> str | None:
    """The outermost incidence-angle ring reported for the primary metric (``ring_80-95/<primary>``)."""
    rings = []
    for entry in entries:
        for key in entry.breakdown:
            match = BIN_KEY.match(key)
            if match and match["kind"] == "ring" and match["metric"] == primary:
                rings.append((float(match["hi"]), float(match["lo"]), key))
    return max(rings)[2] if rings else None


def competition_ranks(metric: str, values: Sequence[float | None]) -> list[int | None]:
    """Rank of each value, best first, equal values sharing a rank (1, 2, 2, 4); ``None`` for missing values.

    Values are compared as printed (:func:`format_value`): two rows that read the same are not ranked apart by
    digits nobody sees.

    Args:
        metric: The ranked metric (its direction and printed precision).
        values: One value per row, in any order.

    Returns:
        The rank of each value, in the order given.

    Example:
        >>> competition_ranks("rmse", [4.2001, 4.2004, 3.9, None, 5.0])  # 4.200 and 4.200 tie
        [2, 2, 1, None, 4]
        >>> competition_ranks("mIoU", [0.5123, 0.5118, 0.49])  # 51.2 % twice
        [1, 1, 3]
    """
    printed = [None if v is None else _printed(metric, v) for v in values]
    present = sorted((v for v in printed if v is not None), reverse=higher_is_better(metric))
    first = {}
    for position, value in enumerate(present, start=1):
        first.setdefault(value, position)
    return [None if v is None else first[v] for v in printed]


def _printed(metric: str, value: float) -> float:
    """``value`` rounded as :func:`format_value` prints it (percent metrics stay fractions)."""
    return float(format_value(metric, value)) / (100.0 if is_percent(metric) else 1.0)


def _rank(
    entries: Sequence[LeaderboardEntry], primary: str
) -> tuple[tuple[int | None, LeaderboardEntry], ...]:
    ranks = competition_ranks(primary, [e.metrics.get(primary) for e in entries])
    # Best first, rows without a primary value last; rows of one rank in a stable, readable order.
    ranked = sorted(
        zip(ranks, entries, strict=True),
        key=lambda r: (r[0] is None, r[0] or 0, r[1].run, r[1].evaluated, r[1].path or ""),
    )
    return tuple(ranked)


def task_table(task: str, entries: Sequence[LeaderboardEntry]) -> TaskTable:
    """``task``'s table of ``entries`` (all of that task): groups of one dataset and split, each ranked."""
    spec = get_task(task)
    primary = spec.primary_metric
    groups: dict[tuple, list[LeaderboardEntry]] = {}
    for entry in entries:
        groups.setdefault(entry.group_key, []).append(entry)
    return TaskTable(
        task=task,
        primary=primary,
        columns=spec.metric_keys,
        rim_key=_rim_key(entries, primary),
        groups=tuple(
            LeaderboardGroup(rows[0].group_title, _rank(rows, primary))
            for _, rows in sorted(groups.items(), key=lambda item: item[0])
        ),
    )
