"""The leaderboard's cross-lens matrix: each model (row) scored on each test lens (column) by ``airfisheye-evaluate
lenses=[...]`` (:mod:`airfisheye_bench.evaluation.cross_lens`), as a heat map in HTML and a table in markdown.

A cell is the task's primary metric on that lens; a lens the model was trained on is marked ``★``; the last column
is the robustness row's largest change of the primary metric (the trained lens with its intrinsics perturbed as
one lens varies across units), where the evaluation measured it. The colour runs from the table's worst value
(none) to its best (full), in the metric's own direction.

Example:
    >>> record = {"cross_lens": {"lenses": [{"name": "trained", "seen": True, "metrics": {"rmse": 10.0},
    ...           "gap": {"rmse": 0.0}}], "robustness": {"largest_change": {"rmse": 0.3}}}}
    >>> scores, change = lens_scores(record)
    >>> scores[0].name, scores[0].seen, scores[0].metrics["rmse"], change["rmse"]
    ('trained', True, 10.0, 0.3)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from html import escape
from typing import Any

from airfisheye_bench.evaluation.leaderboard.columns import (
    MISSING,
    format_value,
    higher_is_better,
    metric_label,
)

__all__ = ["LensScore", "lens_matrix_html", "lens_matrix_markdown", "lens_scores"]

#: The marker of a test lens the model was trained on.
SEEN = "★"


@dataclass(frozen=True)
class LensScore:
    """A model's score on one test lens (``results.json``: ``cross_lens.lenses[i]``)."""

    name: str
    seen: bool
    metrics: Mapping[str, float | None] = field(default_factory=dict)
    gap: Mapping[str, float | None] = field(default_factory=dict)


def lens_scores(record: Mapping[str, Any]) -> tuple[tuple[LensScore, ...], dict[str, float | None]]:
    """``(scores on each test lens, robustness row's largest change per metric)`` of a ``results.json`` record:
    empty without ``cross_lens``."""
    block = record.get("cross_lens")
    if not isinstance(block, Mapping):
        return (), {}
    scores = []
    for row in block.get("lenses") or []:
        if isinstance(row, Mapping) and isinstance(row.get("name"), str):
            scores.append(
                LensScore(
                    row["name"], bool(row.get("seen")), _floats(row.get("metrics")), _floats(row.get("gap"))
                )
            )
    robustness = block.get("robustness")
    change = _floats(robustness.get("largest_change")) if isinstance(robustness, Mapping) else {}
    return tuple(scores), change


def _floats(values: Any) -> dict[str, float | None]:
    if not isinstance(values, Mapping):
        return {}
    out: dict[str, float | None] = {}
    for key, value in values.items():
        number = value if isinstance(value, (int, float)) and not isinstance(value, bool) else None
        out[str(key)] = float(number) if number is not None and math.isfinite(number) else None
    return out


def _columns(rows: Sequence[tuple[str, Sequence[LensScore], Mapping[str, float | None]]]) -> list[str]:
    return list(dict.fromkeys(score.name for _, scores, _ in rows for score in scores))


def _rows(entries: Sequence[Any]) -> list[tuple[str, Sequence[LensScore], Mapping[str, float | None]]]:
    return [(f"{e.model} · {e.run_title}", e.lenses, e.lens_robustness) for e in entries if e.lenses]


def lens_matrix_markdown(primary: str, entries: Sequence[Any]) -> list[str]:
    """The matrix as markdown lines (none when no entry was scored across lenses)."""
    rows = _rows(entries)
    if not rows:
        return []
    columns = _columns(rows)
    robust = any(change for _, _, change in rows)
    headers = ["model · run", *columns] + (
        [f"robustness: largest Δ {metric_label(primary)}"] if robust else []
    )
    lines = [
        "",
        f"#### Across lenses ({metric_label(primary)}; {SEEN} a training lens)",
        "",
        "| " + " | ".join(headers) + " |",
        "|---|" + "|".join("---:" for _ in headers[1:]) + "|",
    ]
    for label, scores, change in rows:
        by_name = {s.name: s for s in scores}
        cells = [label]
        for name in columns:
            score = by_name.get(name)
            value = None if score is None else score.metrics.get(primary)
            cells.append(
                format_value(primary, value) + (f" {SEEN}" if score is not None and score.seen else "")
            )
        if robust:
            cells.append(format_value(primary, change.get(primary)) if change else MISSING)
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return lines


def lens_matrix_html(primary: str, entries: Sequence[Any], anchor: str) -> str:
    """The matrix as an HTML heat map (empty when no entry was scored across lenses)."""
    rows = _rows(entries)
    if not rows:
        return ""
    columns = _columns(rows)
    robust = any(change for _, _, change in rows)
    values = [s.metrics.get(primary) for _, scores, _ in rows for s in scores]
    finite = [v for v in values if v is not None]
    low, high = (min(finite), max(finite)) if finite else (0.0, 0.0)
    higher = higher_is_better(primary)
    label = escape(metric_label(primary))
    out = [
        f'<div class="group lenses" id="{anchor}"><div class="scroll"><table class="lens-matrix">',
        f"<caption><span>Across lenses: {label} of each model on each test lens ({SEEN} a lens it was trained "
        "on; darker is better)</span></caption>",
        "<thead><tr><th>model · run</th>"
        + "".join(f"<th>{escape(name)}</th>" for name in columns)
        + (f"<th>robustness: largest Δ {label}</th>" if robust else "")
        + "</tr></thead><tbody>",
    ]
    for row_label, scores, change in rows:
        by_name = {s.name: s for s in scores}
        cells = [f"<th>{escape(row_label)}</th>"]
        for name in columns:
            cells.append(_cell(primary, by_name.get(name), low, high, higher))
        if robust:
            value = change.get(primary) if change else None
            cells.append(f'<td class="num">{escape(format_value(primary, value))}</td>')
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table></div></div>")
    return "\n".join(out)


def _cell(primary: str, score: LensScore | None, low: float, high: float, higher: bool) -> str:
    value = None if score is None else score.metrics.get(primary)
    if value is None:
        return f'<td class="num">{MISSING}</td>'
    share = 0.5 if high == low else (value - low) / (high - low)
    strength = share if higher else 1.0 - share
    gap = score.gap.get(primary)
    title = f"gap {100 * gap:+.1f} % against its own lens(es)" if gap is not None else ""
    marker = f" {SEEN}" if score.seen else ""
    classes = "num seen" if score.seen else "num"
    return (
        f'<td class="{classes}" style="background: rgba(10, 95, 163, {0.08 + 0.5 * strength:.2f})" '
        f'title="{escape(title)}">{escape(format_value(primary, value))}{marker}</td>'
    )
