"""The leaderboard: every ``results.json`` of a task ranked by its primary metric, next to the paper's baselines.

Results are grouped by dataset (name + content hash prefix, or the manifest's for results without one) and split,
and ranked within their group only: numbers measured on different data are not comparable, and the paper's baselines were measured on the real
AirFisheye test split, which no synthetic run reproduces. Each task's table shows the headline metrics of the
design contract plus the outermost incidence-angle ring (the fisheye rim, ``ring_80-95/<primary>`` by default),
where fisheye distortion hurts most.

Each row says what was evaluated (``evaluated``: a checkpoint, ``ONNX fp32`` / ``ONNX int8``, a prediction
folder, with ``flip TTA`` when used; :func:`~airfisheye_bench.io.results.evaluated_label`) and the run it
comes from (``run``: the training run of the weights, or the ``name=`` given to the evaluation), so an ONNX export
and its checkpoint are two rows of one run. Rows share a rank when their primary metric prints the same
(competition ranking: 1, 2, 2, 4; :func:`competition_ranks`), the markdown, CSV and HTML alike.

Command line (:func:`airfisheye_bench.cli.commands.leaderboard`; ``--help`` lists the options)::

    airfisheye-leaderboard runs=logs/ | runs=[logs/,more/,a/results.json] [out=leaderboard] [paper=true] \
        [skip_invalid=false] [html=leaderboard.html]

It writes ``<out>/leaderboard.md`` and ``<out>/leaderboard.csv`` (atomically) and prints the markdown; ``html=``
also writes the same tables as one self-contained, sortable HTML page with a detail view per entry
(:mod:`airfisheye_bench.evaluation.leaderboard_html`).

Example:
    >>> board = build_leaderboard([], paper=True)   # the paper's baselines alone
    >>> [table.task for table in board.tables]
    ['seg', 'depth', 'completion']
    >>> print(board.to_markdown().splitlines()[0])
    # AirFisheye-bench leaderboard
"""

from __future__ import annotations

import csv
import io
import math
import re
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.errors import MissingFileError, UserError
from airfisheye_bench.io.calibration_files import camera_label
from airfisheye_bench.io.results import RESULTS_VERSION, evaluated_label, load_results
from airfisheye_bench.runs import checkpoint_run_name
from airfisheye_bench.specs import MetricColumn, UnknownTaskError, all_tasks, get_task

__all__ = [
    "Leaderboard",
    "LeaderboardEntry",
    "LeaderboardError",
    "LeaderboardGroup",
    "TaskTable",
    "breakdown_bins",
    "build_leaderboard",
    "collect_results",
    "competition_ranks",
    "csv_columns",
    "find_results",
    "format_value",
    "higher_is_better",
    "is_percent",
    "load_entries",
    "load_entry",
    "metric_column",
    "metric_label",
    "paper_baselines",
    "rim_label",
]

_IDENTITY_COLUMNS = (
    "task",
    "rank",
    "model",
    "evaluated",
    "source",
    "split",
    "camera",
    "dataset",
    "manifest_sha256",
    "run",
    "primary_metric",
)
_BIN = re.compile(r"^(?P<kind>ring|range)_(?P<lo>\d+(?:\.\d+)?)-(?P<hi>\d+(?:\.\d+)?)/(?P<metric>.+)$")
_TEXT_COLUMNS = frozenset(
    {"model", "evaluated", "source", "split", "camera", "run"}
)  # left-aligned; numbers are right-aligned
MISSING = "–"
PAPER_SOURCE = "paper (real AirFisheye)"
PAPER_DATASET = "AirFisheye (real)"


class LeaderboardError(UserError, ValueError):
    """Invalid ``results.json`` files; ``problems`` holds one ``"<path>: <what is wrong>"`` per file."""

    def __init__(self, problems: Sequence[str]) -> None:
        self.problems = list(problems)
        lines = "\n".join(f"  {p}" for p in self.problems)
        super().__init__(f"{len(self.problems)} invalid results.json file(s):\n{lines}")


@dataclass(frozen=True)
class LeaderboardEntry:
    """One row: a model evaluated on one split of one dataset.

    Attributes:
        task: ``seg``, ``depth`` or ``completion``.
        split: The evaluated split (``test``, ``val``, ...).
        model: Model name with its encoder, e.g. ``deeplabv3plus / resnet18``.
        run: The run's name: ``model.run_name`` of the results (the training run of the evaluated weights, or
            the evaluation's ``name=``); for files written before it existed, the run of the evaluated
            checkpoint, else the ``results.json`` folder name.
        dataset_name: ``dataset.name`` of the results (``dataset.yaml`` name).
        manifest_sha256: SHA-256 of the dataset's ``manifest.json``, when it had one.
        content_sha256: The dataset's content identity (decoded arrays, the same on every installation), when
            the results record it; it groups rows in place of the manifest.
        metrics: Metric values (fractions or metres); ``None`` for missing or non-finite.
        breakdown: Ring/range breakdown values, same rules.
        paper: True for the paper's published baselines.
        path: The ``results.json`` the row came from (``None`` for the paper's rows).
        predictor: What produced the predictions: ``checkpoint``, ``onnx`` or ``predictions`` (``model.source``
            of the results; empty when unknown or for the paper's rows).
        evaluated: The row's label of what was evaluated, e.g. ``checkpoint epoch_003``, ``ONNX int8, flip TTA``
            or ``predictions`` (:func:`~airfisheye_bench.io.results.evaluated_label`; empty when unknown).
        camera: The served camera, ``<model> <W>x<H>`` (``config.camera`` of the results; empty when unknown or
            for the paper's rows).
    """

    task: str
    split: str
    model: str
    run: str
    dataset_name: str
    manifest_sha256: str | None = None
    content_sha256: str | None = None
    metrics: Mapping[str, float | None] = field(default_factory=dict)
    breakdown: Mapping[str, float | None] = field(default_factory=dict)
    paper: bool = False
    path: str | None = None
    predictor: str = ""
    evaluated: str = ""
    camera: str = ""

    @property
    def source(self) -> str:
        """``paper (real AirFisheye)`` or ``ours (<dataset name>)``."""
        return PAPER_SOURCE if self.paper else f"ours ({self.dataset_name})"

    @property
    def group_key(self) -> tuple[bool, str, str, str]:
        """Rows with the same key were measured on the same data and may be ranked together."""
        return (not self.paper, self.dataset_name, self._identity(), self.split)

    def _identity(self) -> str:
        """``content <8 hex>`` when known (it survives a re-encoding of the files), else ``manifest <8 hex>``."""
        if self.content_sha256:
            return f"content {self.content_sha256[:8]}"
        return f"manifest {self.manifest_sha256[:8]}" if self.manifest_sha256 else ""

    @property
    def group_title(self) -> str:
        """Human-readable dataset identity of :attr:`group_key`."""
        if self.paper:
            return f"{PAPER_DATASET}, {self.split} split — the paper's published baselines (not re-run here)"
        label = self._identity() or "no manifest"
        return f"{self.dataset_name} ({label}), {self.split} split"


def paper_baselines() -> tuple[LeaderboardEntry, ...]:
    """The paper's baselines of every registered task (``TaskSpec.baselines``, docs/design.md "Paper baselines").

    They were measured on the real dataset's test split; metrics the paper does not report are absent ("–").

    Example:
        >>> [(e.task, e.run) for e in paper_baselines()][:2]
        [('seg', 'paper IV-A'), ('depth', 'paper Table II')]
    """
    return tuple(
        LeaderboardEntry(
            spec.name, "test", b.model, b.source, PAPER_DATASET, metrics=dict(b.metrics), paper=True
        )
        for spec in all_tasks()
        for b in spec.baselines
    )


def metric_column(metric: str) -> MetricColumn | None:
    """How the leaderboard shows ``metric``: the first registered task with a headline column of that key."""
    return next((c for spec in all_tasks() if (c := spec.column(metric)) is not None), None)


def metric_label(metric: str) -> str:
    """Column title of a metric (``rmse`` -> ``RMSE (m)``); metrics no task heads show their key."""
    column = metric_column(metric)
    return column.label if column is not None else metric


def higher_is_better(metric: str) -> bool:
    """Whether a larger ``metric`` is better (unknown metrics rank ascending, like errors)."""
    column = metric_column(metric)
    return column is not None and column.higher_is_better


def is_percent(metric: str) -> bool:
    """Whether ``metric`` prints as a percentage (its task column says so; files keep fractions)."""
    column = metric_column(metric)
    return column is not None and column.percent


def csv_columns() -> tuple[str, ...]:
    """Header of ``leaderboard.csv``: identity columns, every task's headline metrics (fractions, metres), the rim."""
    return (*_IDENTITY_COLUMNS, *_csv_metrics(), "rim_key", "rim_value", "path")


def _csv_metrics() -> tuple[str, ...]:
    return tuple(dict.fromkeys(key for spec in all_tasks() for key in spec.metric_keys))


# ----------------------------------------------------------------------------------------------- collecting


def find_results(paths: Iterable[str | Path]) -> list[Path]:
    """Expand files and directories (searched recursively for ``results.json``) into a sorted, unique list.

    Args:
        paths: ``results.json`` files (any name is accepted when given directly) or directories.

    Returns:
        The files found, each once.

    Raises:
        FileNotFoundError: A path does not exist, or nothing was found at all.

    Example:
        >>> import tempfile, pathlib
        >>> from airfisheye_bench.evaluation import write_results
        >>> root = pathlib.Path(tempfile.mkdtemp())
        >>> _ = write_results(root / "run_a" / "results.json", "seg", "test", {"mIoU": 0.4})
        >>> [p.parent.name for p in find_results([root])]
        ['run_a']
    """
    found: dict[Path, Path] = {}  # resolved -> as given: a file reached through two paths counts once
    searched = []
    for raw in paths:
        path = Path(raw).expanduser()
        if path.is_file():
            hits = [path]
        elif path.is_dir():
            searched.append(str(path))
            hits = [hit for hit in path.rglob("results.json") if hit.is_file()]
        else:
            raise MissingFileError(f"{path}: no such file or directory")
        for hit in hits:
            found.setdefault(hit.resolve(), hit)
    if not found:
        raise MissingFileError(f"no results.json found under {', '.join(searched) or '(no paths given)'}")
    return sorted(found.values())


def _number(value: Any, where: str) -> float | None:
    """A metric value as float, ``None`` for null/NaN/inf; anything else is invalid."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{where} is {value!r}, not a number or null")
    value = float(value)
    return value if math.isfinite(value) else None


def _numbers(record: Mapping[str, Any], key: str) -> dict[str, float | None]:
    values = record.get(key, {})
    if not isinstance(values, Mapping):
        raise ValueError(f"'{key}' is {type(values).__name__}, not an object")
    return {str(k): _number(v, f"{key}.{k}") for k, v in values.items()}


def _model_label(model: Mapping[str, Any]) -> str:
    config = model.get("config") if isinstance(model.get("config"), Mapping) else {}
    name = str(model.get("name") or config.get("name") or "unknown model")
    if config.get("arch"):  # smp: the architecture is what distinguishes the rows
        name = f"{name}-{config['arch']}"
    encoder = config.get("encoder_name") or config.get("encoder")
    return f"{name} / {encoder}" if encoder else name


def load_entry(path: str | Path) -> LeaderboardEntry:
    """Read and validate one ``results.json`` as a leaderboard row.

    Args:
        path: The file.

    Returns:
        The row; non-finite and null metric values become ``None``.

    Raises:
        ValueError: The file is unreadable or not a valid ``results.json``; the message starts with the path.

    Example:
        >>> import tempfile, pathlib
        >>> from airfisheye_bench.evaluation import write_results
        >>> p = write_results(pathlib.Path(tempfile.mkdtemp()) / "r1" / "results.json", "depth", "test",
        ...                   {"rmse": 4.2, "abs_rel": float("nan")}, dataset={"name": "tiny"},
        ...                   model={"name": "adabins", "config": {"encoder_name": "resnet18"}})
        >>> e = load_entry(p)
        >>> e.model, e.run, e.source, e.metrics["rmse"], e.metrics["abs_rel"]
        ('adabins / resnet18', 'r1', 'ours (tiny)', 4.2, None)
        >>> p = write_results(p, "depth", "test", {"rmse": 4.2}, model={"source": "onnx", "precision": "int8",
        ...                   "run_name": "adabins-r18"})
        >>> load_entry(p).run, load_entry(p).evaluated
        ('adabins-r18', 'ONNX int8')
    """
    path = Path(path)
    try:
        record = load_results(path)
    except TypeError as err:  # load_results assumes a JSON object
        raise ValueError(f"{path}: not a results.json object ({err})") from err
    try:
        return _entry(record, path)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err


def _entry(record: Mapping[str, Any], path: Path) -> LeaderboardEntry:
    version = record["version"]
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= RESULTS_VERSION:
        raise ValueError(f"unsupported version {version!r} (this reader knows 1..{RESULTS_VERSION})")
    task = record["task"]
    try:
        get_task(task)
    except UnknownTaskError as err:
        raise ValueError(str(err)) from None
    if not isinstance(record["split"], str) or not record["split"]:
        raise ValueError(f"split is {record['split']!r}, not a name")
    dataset, model = record.get("dataset") or {}, record.get("model") or {}
    if not isinstance(dataset, Mapping) or not isinstance(model, Mapping):
        raise ValueError("'dataset' and 'model' must be objects")
    manifest = dataset.get("manifest_sha256")
    return LeaderboardEntry(
        task=task,
        split=record["split"],
        model=_model_label(model),
        run=_run_name(model, path),
        dataset_name=str(dataset.get("name") or "unknown dataset"),
        manifest_sha256=str(manifest) if manifest else None,
        content_sha256=str(dataset["content_sha256"]) if dataset.get("content_sha256") else None,
        metrics=_numbers(record, "metrics"),
        breakdown=_numbers(record, "breakdown"),
        path=str(path),
        predictor=str(model.get("source") or ("checkpoint" if model.get("checkpoint") else "")),
        evaluated=evaluated_label(model),
        camera=_camera(record),
    )


def _camera(record: Mapping[str, Any]) -> str:
    """The served camera's label from ``config.camera`` (written by training and evaluation), else empty."""
    config = record.get("config")
    camera = config.get("camera") if isinstance(config, Mapping) else None
    return camera_label(camera) if isinstance(camera, Mapping) else ""


def _run_name(model: Mapping[str, Any], path: Path) -> str:
    """``model.run_name``; for files written before it, the run of the checkpoint, else the file's folder."""
    if model.get("run_name"):
        return str(model["run_name"])
    checkpoint = model.get("checkpoint") or model.get("source_checkpoint")
    return checkpoint_run_name(str(checkpoint)) if checkpoint else path.resolve().parent.name


def load_entries(files: Iterable[str | Path]) -> tuple[list[LeaderboardEntry], list[str]]:
    """Load every file, collecting problems instead of stopping at the first.

    Args:
        files: ``results.json`` paths.

    Returns:
        ``(entries, problems)``: the valid rows, and ``"<path>: <what is wrong>"`` for each invalid file.

    Example:
        >>> import tempfile, pathlib
        >>> bad = pathlib.Path(tempfile.mkdtemp()) / "results.json"
        >>> _ = bad.write_text("{")
        >>> entries, problems = load_entries([bad])
        >>> entries, problems[0].startswith(str(bad))
        ([], True)
    """
    entries, problems = [], []
    for path in files:
        try:
            entries.append(load_entry(path))
        except ValueError as err:
            problems.append(str(err))
    return entries, problems


def collect_results(paths: Iterable[str | Path], skip_invalid: bool = False) -> list[LeaderboardEntry]:
    """Find, load and validate ``results.json`` files under ``paths``.

    Args:
        paths: Files or directories (searched recursively).
        skip_invalid: Leave invalid files out with a warning instead of raising.

    Returns:
        The valid rows.

    Raises:
        FileNotFoundError: A path is missing or no ``results.json`` was found.
        LeaderboardError: Some files are invalid (all of them listed) and ``skip_invalid`` is false.

    Example:
        >>> import tempfile, pathlib
        >>> from airfisheye_bench.evaluation import write_results
        >>> root = pathlib.Path(tempfile.mkdtemp())
        >>> _ = write_results(root / "a" / "results.json", "seg", "test", {"mIoU": 0.3})
        >>> [e.metrics["mIoU"] for e in collect_results([root])]
        [0.3]
    """
    entries, problems = load_entries(find_results(paths))
    if problems and not skip_invalid:
        raise LeaderboardError(problems)
    for problem in problems:
        warnings.warn(f"skipped invalid results.json: {problem}", stacklevel=2)
    return entries


# ------------------------------------------------------------------------------------------------- ranking


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


def breakdown_bins(
    breakdown: Mapping[str, float | None], kind: str, metric: str
) -> list[tuple[float, float, float | None]]:
    """``(lo, hi, value)`` of ``metric`` in each ``ring`` (incidence angle) or ``range`` (depth) bin, in order.

    Example:
        >>> breakdown_bins({"ring_30-60/rmse": 5.0, "ring_0-30/rmse": 4.0, "range_0-10/rmse": 1.0}, "ring", "rmse")
        [(0.0, 30.0, 4.0), (30.0, 60.0, 5.0)]
    """
    bins = []
    for key, value in breakdown.items():
        match = _BIN.match(key)
        if match and match["kind"] == kind and match["metric"] == metric:
            bins.append((float(match["lo"]), float(match["hi"]), value))
    return sorted(bins, key=lambda b: (b[0], b[1]))


def _rim_key(entries: Iterable[LeaderboardEntry], primary: str) -> str | None:
    """The outermost incidence-angle ring reported for the primary metric (``ring_80-95/<primary>``)."""
    rings = []
    for entry in entries:
        for key in entry.breakdown:
            match = _BIN.match(key)
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


def _task_table(task: str, entries: Sequence[LeaderboardEntry]) -> TaskTable:
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


def build_leaderboard(
    entries: Iterable[LeaderboardEntry], paper: bool = True, invalid: Sequence[str] = ()
) -> Leaderboard:
    """Rank rows per task, within groups of the same dataset and split.

    Args:
        entries: Rows, e.g. from :func:`collect_results`.
        paper: Add :func:`paper_baselines` (in their own group: the real dataset's test split).
        invalid: ``"<path>: <reason>"`` of the files that failed validation (:func:`load_entries`); the
            renderings list them under the tables rather than dropping them silently.

    Returns:
        The leaderboard; tasks without any row are left out.

    Example:
        >>> mine = LeaderboardEntry("seg", "test", "deeplabv3plus / resnet18", "run1", "tiny",
        ...                         metrics={"mIoU": 0.3})
        >>> board = build_leaderboard([mine], paper=True)
        >>> [[(r, e.run) for r, e in g.rows] for g in board.tables[0].groups]
        [[(1, 'paper IV-A')], [(1, 'run1')]]
    """
    rows = list(entries) + (list(paper_baselines()) if paper else [])
    tables = tuple(
        _task_table(spec.name, [e for e in rows if e.task == spec.name])
        for spec in all_tasks()
        if any(e.task == spec.name for e in rows)
    )
    return Leaderboard(
        tables=tables, files=sum(not e.paper for e in rows), paper=paper, invalid=tuple(invalid)
    )


# ------------------------------------------------------------------------------------------------ rendering


def format_value(metric: str, value: float | None) -> str:
    """A metric value as the tables print it: percent where the task's column says so, the paper's decimals.

    Example:
        >>> format_value("mIoU", 0.512), format_value("abs_rel", 0.0834), format_value("rmse", None)
        ('51.2', '0.0834', '–')
    """
    if value is None:
        return MISSING
    if is_percent(metric):
        return f"{100.0 * value:.1f}"
    column = metric_column(metric)
    return f"{value:.{column.decimals if column is not None else 3}f}"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def rim_label(rim_key: str) -> str:
    """The column title of a rim ring key, e.g. ``ring_80-95/rmse`` -> ``rim 80-95° RMSE (m)``."""
    match = _BIN.match(rim_key)
    assert match is not None
    return f"rim {match['lo']}-{match['hi']}° {metric_label(match['metric'])}"


@dataclass(frozen=True)
class Leaderboard:
    """All task tables; render with :meth:`to_markdown` / :meth:`to_csv`, save with :meth:`write`.

    Attributes:
        tables: One per task that has rows, in the order seg, depth, completion.
        files: Number of ``results.json`` rows (paper rows not counted).
        paper: Whether the paper's baselines are included.
        invalid: ``"<path>: <reason>"`` of each ``results.json`` that failed validation (not ranked).
    """

    tables: tuple[TaskTable, ...]
    files: int = 0
    paper: bool = True
    invalid: tuple[str, ...] = ()

    def to_markdown(self) -> str:
        """The leaderboard as markdown: one section per task, one table per dataset and split.

        Example:
            >>> print(build_leaderboard([], paper=True).to_markdown())  # doctest: +ELLIPSIS
            # AirFisheye-bench leaderboard
            ...
            | 1 | DeepLabV3+ / ResNet50 | paper | paper (real AirFisheye) | test | – | 51.2 | – | paper IV-A |
            ...
        """
        paper = " plus the paper's baselines" if self.paper else ""
        lines = [
            "# AirFisheye-bench leaderboard",
            "",
            f"{self.files} result(s){paper}. Ranks restart for every dataset (name + content or manifest hash prefix) and "
            "split: results measured on different data are not comparable. Values are fractions and metres "
            f"(columns marked (%) printed in %); {MISSING} = not reported.",
        ]
        for table in self.tables:
            lines += ["", *self._table_markdown(table)]
        if self.invalid:
            lines += ["", "## Invalid results.json (not ranked)", ""]
            lines += [f"- {_cell(problem)}" for problem in self.invalid]
        return "\n".join(lines) + "\n"

    @staticmethod
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
            "camera: the served lens model and image size; run: the training run or the evaluation's name); the rim column is the outermost incidence-angle "
            "ring, where fisheye distortion is strongest.",
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
                cells.append(entry.run)
                lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
        return lines

    def to_csv(self) -> str:
        """Wide CSV, one row per result, a ``task`` column and raw values (fractions, metres, empty = missing).

        Example:
            >>> print(build_leaderboard([], paper=True).to_csv().splitlines()[1])  # doctest: +ELLIPSIS
            seg,1,DeepLabV3+ / ResNet50,paper,paper (real AirFisheye),test,,AirFisheye (real),,paper IV-A,mIoU,0.512,...
        """
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(csv_columns())
        for table in self.tables:
            for group in table.groups:
                for rank, e in group.rows:
                    writer.writerow(_csv_row(table, rank, e))
        return buffer.getvalue()

    def write(self, out_dir: str | Path) -> tuple[Path, Path]:
        """Write ``leaderboard.md`` and ``leaderboard.csv`` atomically into ``out_dir`` (created if needed).

        Example:
            >>> import tempfile
            >>> md, table = build_leaderboard([]).write(tempfile.mkdtemp())
            >>> md.name, table.name
            ('leaderboard.md', 'leaderboard.csv')
        """
        out_dir = Path(out_dir)
        md, table = out_dir / "leaderboard.md", out_dir / "leaderboard.csv"
        atomic_write_text(md, self.to_markdown())
        atomic_write_text(table, self.to_csv())
        return md, table


def _csv_row(table: TaskTable, rank: int | None, e: LeaderboardEntry) -> list[object]:
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
    head += [e.manifest_sha256 or "", e.run, table.primary]
    return [
        *head,
        *(_raw(e.metrics.get(m)) for m in _csv_metrics()),
        table.rim_key or "",
        _raw(rim),
        e.path or "",
    ]


def _raw(value: float | None) -> str:
    return "" if value is None else repr(value)  # repr: the CSV reads back to the same float
