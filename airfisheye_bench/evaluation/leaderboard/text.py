"""The leaderboard as text: markdown (one section per task, one table per dataset and split) and a wide CSV."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence

from airfisheye_bench.evaluation.leaderboard.collect import LeaderboardEntry
from airfisheye_bench.evaluation.leaderboard.columns import MISSING, format_value, metric_label, rim_label
from airfisheye_bench.evaluation.leaderboard.lens_matrix import lens_matrix_markdown
from airfisheye_bench.evaluation.leaderboard.paths import ShownPaths
from airfisheye_bench.evaluation.leaderboard.rank import GROUPING, TaskTable
from airfisheye_bench.specs import all_tasks

__all__ = ["csv_columns", "render_csv", "render_markdown"]

_IDENTITY_COLUMNS = (
    "task",
    "rank",
    "model",
    "evaluated",
    "source",
    "split",
    "camera",
    "dataset",
    "content_sha256",
    "manifest_sha256",
    "run",
    "overrides",
    "primary_metric",
)
_TEXT_COLUMNS = frozenset(
    {"model", "evaluated", "source", "split", "camera", "run"}
)  # left-aligned; numbers are right-aligned


def csv_columns() -> tuple[str, ...]:
    """Header of ``leaderboard.csv``: identity columns, every task's headline metrics (fractions, metres), the rim."""
    return (*_IDENTITY_COLUMNS, *_csv_metrics(), "rim_key", "rim_value", "path")


def _csv_metrics() -> tuple[str, ...]:
    return tuple(dict.fromkeys(key for spec in all_tasks() for key in spec.metric_keys))


def render_markdown(tables: Sequence[TaskTable], files: int, paper: bool, invalid: Sequence[str]) -> str:
    """The leaderboard as markdown (:meth:`Leaderboard.to_markdown`): one section per task, one table per dataset and
    split, then the invalid files."""
    with_paper = " plus the paper's baselines" if paper else ""
    lines = [
        "# AirFisheye-bench leaderboard",
        "",
        f"{files} result(s){with_paper}. {GROUPING} Values are fractions and metres "
        f"(columns marked (%) printed in %); {MISSING} = not reported.",
    ]
    for table in tables:
        lines += ["", *_table_markdown(table)]
    if invalid:
        lines += ["", "## Invalid results.json (not ranked)", ""]
        lines += [f"- {_cell(problem)}" for problem in invalid]
    return "\n".join(lines) + "\n"


def _table_markdown(table: TaskTable) -> list[str]:
    order = "higher is better" if table.higher_is_better else "lower is better"
    headers = ["rank", "model", "evaluated", "source", "split", "camera"]
    headers += [metric_label(c) for c in table.columns]
    headers += [rim_label(table.rim_key)] if table.rim_key else []
    headers += ["run"]
    lines = [
        f"## {table.title} ({table.task})",
        "",
        f"Sorted by {metric_label(table.primary)}, {order}; rows that print the same share a rank. Rows: "
        "each evaluated model on one split (evaluated: checkpoint, ONNX fp32/int8, prediction folder, TTA; "
        "camera: the served lens model and image size; run: the training run (task, model and start time) or the "
        "evaluation's name, with what a sweep chose for it in parentheses; the run's folder: leaderboard.csv); the rim column is the outermost incidence-angle ring, where fisheye "
        "distortion is strongest.",
    ]
    for group in table.groups:
        lines += ["", f"### {group.title}", ""]
        lines.append("| " + " | ".join(headers) + " |")
        lines.append("|" + "|".join("---" if h in _TEXT_COLUMNS else "---:" for h in headers) + "|")
        for rank, entry in group.rows:
            evaluated = "paper" if entry.paper else entry.evaluated or MISSING
            cells = [
                MISSING if rank is None else str(rank),
                entry.model,
                evaluated,
                entry.source,
                entry.split,
                entry.camera or MISSING,
            ]
            cells += [format_value(c, entry.metrics.get(c)) for c in table.columns]
            if table.rim_key:
                cells.append(format_value(table.primary, entry.breakdown.get(table.rim_key)))
            cells.append(entry.run_title)
            lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    entries = [e for group in table.groups for _, e in group.rows if not e.paper]
    lines += lens_matrix_markdown(table.primary, entries)
    return lines


def render_csv(tables: Sequence[TaskTable], shown: ShownPaths | None = None) -> str:
    """The leaderboard as wide CSV (:meth:`Leaderboard.to_csv`): one row per result, raw values; ``path`` as
    ``shown`` shows it (default: as found)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(csv_columns())
    for table in tables:
        for group in table.groups:
            for rank, e in group.rows:
                writer.writerow(_csv_row(table, rank, e, shown))
    return buffer.getvalue()


def _csv_row(
    table: TaskTable, rank: int | None, e: LeaderboardEntry, shown: ShownPaths | None
) -> list[object]:
    rim = e.breakdown.get(table.rim_key) if table.rim_key else None
    evaluated = "paper" if e.paper else e.evaluated
    head = [
        e.task,
        "" if rank is None else rank,
        e.model,
        evaluated,
        e.source,
        e.split,
        e.camera,
        e.dataset_name,
    ]
    head += [e.content_sha256 or "", e.manifest_sha256 or "", e.run, " ".join(e.overrides), table.primary]
    return [
        *head,
        *(_raw(e.metrics.get(m)) for m in _csv_metrics()),
        table.rim_key or "",
        _raw(rim),
        (shown(e.path) if shown else e.path) or "",
    ]


def _raw(value: float | None) -> str:
    return "" if value is None else repr(value)  # repr: the CSV reads back to the same float


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")
