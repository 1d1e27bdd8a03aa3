"""The leaderboard as one self-contained HTML page: sortable tables per task and a detail view per entry.

The page renders a :class:`~airfisheye_bench.evaluation.leaderboard.Leaderboard` -- the same groups, ranks and row
labels (what was evaluated, which run) as ``leaderboard.md`` (results of different datasets or splits are never
ranked together) -- and reads each entry's
``results.json`` again for its detail view: identity and checksums, every metric, the IoU of each class, the
primary metric by incidence-angle ring and by depth range (matplotlib, inline SVG), a few qualitative panels
(the evaluation's ``panels/*.png``, downscaled JPEG data URIs) and the configuration.

Nothing is fetched when the page is opened: CSS, script and images are inline, and a Content-Security-Policy
forbids every other source (the one script is allowed by its hash). Every string from ``results.json`` is
HTML-escaped, so a run name such as ``<script>`` shows as text.

Example:
    >>> from airfisheye_bench.evaluation.leaderboard import build_leaderboard
    >>> page = render_html(build_leaderboard([], paper=True))
    >>> page.startswith("<!doctype html>") and "DeepLabV3+ / ResNet50" in page
    True
"""

from __future__ import annotations

import base64
import contextlib
import dataclasses
import hashlib
import io
import json
import re
from collections.abc import Mapping, Sequence
from html import escape
from importlib import resources
from pathlib import Path
from typing import Any

from PIL import Image

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.evaluation.leaderboard.board import Leaderboard
from airfisheye_bench.evaluation.leaderboard.charts import bar_chart, binned_chart
from airfisheye_bench.evaluation.leaderboard.collect import LeaderboardEntry
from airfisheye_bench.evaluation.leaderboard.columns import (
    MISSING,
    breakdown_bins,
    format_value,
    higher_is_better,
    is_percent,
    metric_label,
    rim_label,
)
from airfisheye_bench.evaluation.leaderboard.lens_matrix import lens_matrix_html
from airfisheye_bench.evaluation.leaderboard.paths import ShownPaths
from airfisheye_bench.evaluation.leaderboard.rank import GROUPING, TaskTable
from airfisheye_bench.runs.results import load_results

__all__ = ["render_html", "short_override", "write_html"]

_ASSETS = resources.files("airfisheye_bench.evaluation.leaderboard") / "assets"
#: ``model`` keys of ``results.json`` that say which file was evaluated (see the evaluation's predictors).
_IDENTITY_KEYS = ("checkpoint", "onnx", "source_checkpoint", "predictions", "sha256")
_RING_AXIS = "incidence angle ring (°)"
_RANGE_AXIS = "ground-truth depth range (m)"


def write_html(
    board: Leaderboard,
    path: str | Path,
    panels: int = 3,
    panel_width: int = 720,
    runs_root: str | Path | None = None,
) -> Path:
    """Write :func:`render_html` of ``board`` to ``path`` atomically.

    Example:
        >>> import tempfile, pathlib
        >>> from airfisheye_bench.evaluation.leaderboard import build_leaderboard
        >>> out = write_html(build_leaderboard([]), pathlib.Path(tempfile.mkdtemp()) / "board.html")
        >>> out.read_text().count("<table")
        3
    """
    path = Path(path)
    atomic_write_text(path, render_html(board, panels=panels, panel_width=panel_width, runs_root=runs_root))
    return path


def render_html(
    board: Leaderboard, panels: int = 3, panel_width: int = 720, runs_root: str | Path | None = None
) -> str:
    """The page as a string.

    Args:
        board: The ranked leaderboard (:func:`~airfisheye_bench.evaluation.leaderboard.build_leaderboard`).
        panels: Qualitative panels shown per entry (the first ones of its ``panels/`` folder).
        panel_width: Panels wider than this (pixels) are downscaled, to keep the page small.
        runs_root: The folder the results were collected from (default: the board's ``root``): paths under it
            are shown relative to it, a dataset's as its name and content hash, the home folder as ``~``
            (:mod:`~airfisheye_bench.evaluation.leaderboard.paths`), so a shared page shows no one's local layout.

    Returns:
        A complete HTML document.
    """
    script = (_ASSETS / "leaderboard.js").read_text()
    style = (_ASSETS / "leaderboard.css").read_text()
    digest = base64.b64encode(hashlib.sha256(script.encode()).digest()).decode()
    policy = (
        "default-src 'none'; img-src data:; style-src 'unsafe-inline'; "
        f"script-src 'sha256-{digest}'; base-uri 'none'; form-action 'none'"
    )
    paper = " plus the paper's baselines" if board.paper else ""
    nav = "".join(f'<li><a href="#task-{t.task}">{escape(t.title)}</a></li>' for t in board.tables)
    if board.invalid:
        nav += '<li><a href="#invalid">Invalid results</a></li>'
    body = [
        "<header>",
        "<h1>AirFisheye-bench leaderboard</h1>",
        f"<p>{board.files} result(s){paper}. {_code(GROUPING)} Click a column header to sort; click a model for its "
        "detail view.</p>",
        f'<nav aria-label="Tasks"><ul>{nav}</ul></nav>',
        "</header>",
        "<main>",
    ]
    shown = board.shown_paths(runs_root)
    body += [_task_section(table, panels, panel_width, shown) for table in board.tables]
    if board.invalid:
        items = "".join(f"<li><code>{escape(shown.text(problem))}</code></li>" for problem in board.invalid)
        body.append(
            '<section id="invalid"><h2>Invalid results.json (not ranked)</h2>'
            f'<ul class="invalid">{items}</ul></section>'
        )
    body.append("</main>")
    return "\n".join(
        [
            "<!doctype html>",
            '<html lang="en">',
            "<head>",
            '<meta charset="utf-8">',
            f'<meta http-equiv="Content-Security-Policy" content="{policy}">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            '<meta name="color-scheme" content="light dark">',
            "<title>AirFisheye-bench leaderboard</title>",
            f"<style>\n{style}</style>",
            "</head>",
            "<body>",
            *body,
            f"<script>{script}</script>",
            "</body>",
            "</html>",
            "",
        ]
    )


# ------------------------------------------------------------------------------------------------- tables


def _task_section(table: TaskTable, panels: int, panel_width: int, shown: ShownPaths) -> str:
    task = table.task
    order = "higher is better" if table.higher_is_better else "lower is better"
    entries = [e for group in table.groups for _, e in group.rows]
    columns = _metric_columns(table, entries)
    out = [
        f'<section id="task-{task}" aria-labelledby="title-{task}">',
        f'<h2 id="title-{task}">{escape(table.title)} ({task})</h2>',
        f"<p>Ranked by {escape(metric_label(table.primary))}, {order}; the rim column is the outermost "
        "incidence-angle ring, where fisheye distortion is strongest. Paper rows were measured on the real "
        f"AirFisheye test split and are not re-run here. Values are fractions and metres (mIoU and pixel "
        f"accuracy in %); {MISSING} = not reported.</p>",
    ]
    details = []
    for g, group in enumerate(table.groups):
        out.append(f'<div class="group"><div class="scroll"><table class="board" id="table-{task}-{g}">')
        out.append(f"<caption><span>{escape(group.title)}</span></caption>")
        out.append(_header(table, columns))
        out.append("<tbody>")
        for rank, entry in group.rows:
            anchor = None if entry.paper else f"entry-{task}-{len(details)}"
            out.append(_row(table, columns, rank, entry, anchor))
            if anchor:
                details.append(_detail(table, entry, anchor, panels, panel_width, shown))
        out.append("</tbody></table></div>")
        out.append(_group_chart(table, group.rows, f"{task}-{g}"))
        out.append("</div>")
    out.append(lens_matrix_html(table.primary, [e for e in entries if not e.paper], f"lenses-{task}"))
    if details:
        out += [f'<h3 id="entries-{task}">Entries</h3>', *details]
    out.append("</section>")
    return "\n".join(out)


def _metric_columns(table: TaskTable, entries: Sequence[LeaderboardEntry]) -> list[str]:
    """The task's headline metrics, then any other overall metric of its entries (per-class values excluded)."""
    extra = sorted({k for e in entries for k in e.metrics if "/" not in k} - set(table.columns))
    return [*table.columns, *extra]


def _header(table: TaskTable, columns: Sequence[str]) -> str:
    def th(label: str, kind: str, first: str = "ascending", sorted_: bool = False) -> str:
        sort = ' aria-sort="ascending"' if sorted_ else ""
        return (
            f'<th scope="col" data-type="{kind}" data-first="{first}"{sort}>'
            f'<button type="button">{escape(label)}</button></th>'
        )

    def first(metric: str) -> str:  # the first click puts the best value on top
        return "descending" if higher_is_better(metric) else "ascending"

    cells = [
        th("rank", "number", sorted_=True),
        th("run", "text"),  # second and, with rank, kept in view when a wide table scrolls (CSS: sticky)
        th("model", "text"),
        th("evaluated", "text"),
        th("split", "text"),
    ]
    cells += [th(metric_label(c), "number", first(c)) for c in columns]
    if table.rim_key:
        cells.append(th(rim_label(table.rim_key), "number", first(table.primary)))
    return f"<thead><tr>{''.join(cells)}</tr></thead>"


def _row(
    table: TaskTable, columns: Sequence[str], rank: int | None, e: LeaderboardEntry, anchor: str | None
) -> str:
    def number(metric: str, value: float | None) -> str:
        raw = "" if value is None else repr(value)  # sorted by the raw value, shown rounded
        return f'<td class="num" data-value="{raw}">{escape(format_value(metric, value))}</td>'

    model = escape(e.model)
    model = f'<a href="#{anchor}">{model}</a>' if anchor else model
    if e.paper:
        model += ' <span class="badge">paper</span>'
    evaluated = "paper" if e.paper else e.evaluated or MISSING
    cells = [
        f'<td class="num" data-value="{"" if rank is None else rank}">{rank or MISSING}</td>',
        # Shown by task, model and start time, the folder's name as its tooltip and sort key (chronological).
        f'<td class="run" data-value="{escape(e.run)}">{_run_title(e)}{_overrides(e)}</td>',
        f'<td class="text">{model}</td>',
        f'<td class="text">{escape(evaluated)}</td>',
        f"<td>{escape(e.split)}</td>",
        *(number(c, e.metrics.get(c)) for c in columns),
    ]
    if table.rim_key:
        cells.append(number(table.primary, e.breakdown.get(table.rim_key)))
    return f"<tr{' class=paper' if e.paper else ''}>{''.join(cells)}</tr>"


def _run_title(e: LeaderboardEntry) -> str:
    """:attr:`~.collect.LeaderboardEntry.run_title` without the overrides (shown below it), with the folder's name
    as its tooltip when it differs; a sweep's job (``<sweep>/<job>``) may wrap before its number."""
    title = dataclasses.replace(e, overrides=()).run_title
    shown = escape(title).replace("/", "/<wbr>")
    return shown if title == e.run else f'<span title="{escape(e.run)}">{shown}</span>'


def _overrides(e: LeaderboardEntry) -> str:
    """What a sweep chose for the entry's run, below its name, each ``key=value`` shortened (:func:`short_override`)
    with the whole override as its tooltip (and in the detail view); empty for a single run."""
    if not e.overrides:
        return ""
    items = " ".join(f'<code title="{escape(o)}">{escape(short_override(o))}</code>' for o in e.overrides)
    return f'<span class="overrides">{items}</span>'


def short_override(override: str) -> str:
    """An override as a table cell shows it: the key's last two parts, a decimal to 4 significant digits.

    Example:
        >>> short_override("task.module.optimizer.lr=0.0072708183450185"), short_override("data.batch_size=8")
        ('optimizer.lr=0.007271', 'data.batch_size=8')
        >>> short_override("model=unet"), short_override("task.module.optimizer.weight_decay=1.2345678e-05")
        ('model=unet', 'optimizer.weight_decay=1.235e-05')
    """
    key, sep, value = override.partition("=")
    key = ".".join(key.lstrip("+~").split(".")[-2:])
    if any(c in value for c in ".eE"):
        with contextlib.suppress(ValueError):  # a word with an e in it stays as it is
            value = f"{float(value):.4g}"
    return f"{key}{sep}{value}"


def _group_chart(table: TaskTable, rows: Sequence[tuple[int | None, LeaderboardEntry]], key: str) -> str:
    """The primary metric by incidence-angle ring for every entry of a group that has the breakdown."""
    series = {}
    for _, e in rows:
        bins = breakdown_bins(e.breakdown, "ring", table.primary)
        if bins:
            name = f"{e.run}: {e.model}, {e.evaluated or 'unknown source'}"  # the row, as the table shows it
            while name in series:  # same model and run name (e.g. one folder given twice under two paths)
                name += "'"
            series[name] = bins
    if not series:
        return ""
    label = f"{metric_label(table.primary)} by incidence-angle ring, every entry of this group"
    return _figure(_binned(series, table.primary, _RING_AXIS, f"group-{key}", label), label)


# --------------------------------------------------------------------------------------------- detail view


def _detail(
    table: TaskTable, e: LeaderboardEntry, anchor: str, panels: int, panel_width: int, shown: ShownPaths
) -> str:
    record = load_results(e.path) if e.path else {}
    shown = shown.with_dataset(e.dataset_root, e.dataset_label)
    model = record.get("model") or {}
    source = e.evaluated or "unknown source"
    out = [
        f'<details id="{anchor}" class="entry">',
        f"<summary>{escape(e.model)} — {escape(e.run_title)} <span class=muted>({escape(source)}, "
        f"{escape(e.group_title)})</span></summary>",
        '<div class="entry-body">',
        _identity(e, record, model, shown),
        _metrics_table(e),
    ]
    charts = []
    classes = {k.split("/", 1)[1]: v for k, v in e.metrics.items() if k.startswith("IoU/")}
    if classes:
        label = f"IoU per class, {e.run}"
        charts.append(
            _figure(bar_chart(classes, metric="IoU (%)", key=f"{anchor}-iou", label=label, scale=100), label)
        )
    for kind, axis in (("ring", _RING_AXIS), ("range", _RANGE_AXIS)):
        bins = breakdown_bins(e.breakdown, kind, table.primary)
        if bins:
            what = "incidence-angle ring" if kind == "ring" else "depth range"
            label = f"{metric_label(table.primary)} by {what}, {e.run}"
            charts.append(
                _figure(_binned({e.run: bins}, table.primary, axis, f"{anchor}-{kind}", label), label)
            )
    if charts:
        out.append(f'<div class="charts">{"".join(charts)}</div>')
    out.append(_panels(e, panels, panel_width, shown))
    settings = {"model": model, "config": record.get("config", {})}
    out.append(
        "<details><summary>Configuration (model and evaluation settings)</summary>"
        f"<pre>{escape(json.dumps(shown.within(settings), indent=2, sort_keys=True))}</pre></details>"
    )
    out.append("</div></details>")
    return "\n".join(out)


def _identity(
    e: LeaderboardEntry, record: Mapping[str, Any], model: Mapping[str, Any], shown: ShownPaths
) -> str:
    rows = [
        ("model", e.model),
        ("run", e.run),  # the folder's name (or the name given), which the table shows by task, model, time
        ("sweep overrides", " ".join(e.overrides)),
        ("evaluated", e.evaluated or "unknown"),
        *((key.replace("_", " "), shown(model[key])) for key in _IDENTITY_KEYS if model.get(key)),
        ("dataset", e.dataset_label),  # by its name and content hash: where it lay is no one else's business
        ("content sha256", e.content_sha256),
        ("manifest sha256", e.manifest_sha256),
        ("split", e.split),
        ("camera", e.camera or None),
        ("results.json", shown(e.path)),
        ("created", record.get("created")),
    ]
    items = "".join(
        f"<dt>{escape(name)}</dt><dd>{escape(str(value))}</dd>"
        for name, value in rows
        if value not in (None, "")
    )
    return f'<dl class="identity">{items}</dl>'


def _metrics_table(e: LeaderboardEntry) -> str:
    names = [k for k in e.metrics if "/" not in k]
    head = "".join(f'<th scope="col">{escape(metric_label(k))}</th>' for k in names)
    cells = "".join(f'<td class="num">{escape(format_value(k, e.metrics[k]))}</td>' for k in names)
    table = f"<thead><tr>{head}</tr></thead><tbody><tr>{cells}</tr></tbody>"
    return f'<div class="scroll"><table class="metrics">{table}</table></div>'


def _binned(series: Mapping[str, list], metric: str, axis: str, key: str, label: str) -> str:
    percent = is_percent(metric)
    return binned_chart(
        series,
        metric=metric_label(metric),
        axis=axis,
        key=key,
        label=label,
        scale=100 if percent else 1,
    )


def _code(text: str) -> str:
    """``text`` escaped, its backticked parts as ``<code>``."""
    return re.sub(r"`([^`]+)`", r"<code>\1</code>", escape(text))


def _figure(svg: str, caption: str) -> str:
    return f'<figure class="chart">{svg}<figcaption>{escape(caption)}</figcaption></figure>'


def _panels(e: LeaderboardEntry, count: int, width: int, shown: ShownPaths) -> str:
    """The first ``count`` panels next to ``results.json``, as downscaled JPEG data URIs."""
    folder = Path(e.path).parent / "panels" if e.path else None
    files = sorted(folder.glob("*.png"))[:count] if folder and folder.is_dir() and count > 0 else []
    if not files:
        return ""
    images = "".join(_panel(f, width, shown) for f in files)
    return (
        "<h4>Qualitative panels</h4><p class=muted>image | (sparse input) | ground truth | prediction | error"
        f"</p><div class=panels>{images}</div>"
    )


def _panel(path: Path, width: int, shown: ShownPaths) -> str:
    try:
        image = f'<img src="{_data_uri(path, width)}" alt="qualitative panel {escape(path.stem)}">'
    except OSError as err:  # a damaged PNG costs its picture, not the page
        image = f"<p class=muted>unreadable panel: {escape(shown.text(str(err)))}</p>"
    return f'<figure class="panel">{image}<figcaption>{escape(path.stem)}</figcaption></figure>'


def _data_uri(path: Path, width: int) -> str:
    with Image.open(path) as image:
        image = image.convert("RGB")
        if image.width > width:
            image = image.resize((width, round(image.height * width / image.width)), Image.Resampling.LANCZOS)
        buffer = io.BytesIO()
        image.save(buffer, format="JPEG", quality=85, optimize=True)
    return "data:image/jpeg;base64," + base64.b64encode(buffer.getvalue()).decode()
