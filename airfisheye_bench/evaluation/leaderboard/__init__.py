"""The leaderboard: every ``results.json`` of a task ranked by its primary metric, next to the paper's baselines.

Results are grouped by dataset (its name and content hash, ``dataset.content_sha256`` of ``results.json``; the
manifest hash, ``manifest_sha256``, for results written before it) and split, and ranked within their group only:
numbers measured on different data are not comparable, and the paper's baselines were measured on the real
AirFisheye test split, which no synthetic run reproduces. Each task's table shows the headline metrics of the
design contract plus the outermost incidence-angle ring (the fisheye rim, ``ring_80-95/<primary>`` by default),
where fisheye distortion hurts most.

Each row says what was evaluated (``evaluated``: a checkpoint, ``ONNX fp32`` / ``ONNX int8``, a prediction
folder, with ``flip TTA`` when used; :func:`~airfisheye_bench.runs.results.evaluated_label`) and the run it
comes from (``run``: the training run of the weights, or the ``name=`` given to the evaluation), so an ONNX export
and its checkpoint are two rows of one run. Rows share a rank when their primary metric prints the same
(competition ranking: 1, 2, 2, 4; :func:`competition_ranks`), the markdown, CSV and HTML alike.

Command line (:func:`airfisheye_bench.cli.commands.leaderboard`; ``--help`` lists the options)::

    airfisheye-leaderboard runs=logs/ | runs=[logs/,more/,a/results.json] [out=leaderboard] [paper=true] \
        [skip_invalid=false] [html=leaderboard.html]

It writes ``<out>/leaderboard.md`` and ``<out>/leaderboard.csv`` (atomically) and prints the markdown; ``html=``
also writes the same tables as one self-contained, sortable HTML page with a detail view per entry
(:mod:`airfisheye_bench.evaluation.leaderboard.html`).

Modules: :mod:`~.collect` (rows from ``results.json`` files and the paper), :mod:`~.columns` (how a metric is
shown), :mod:`~.rank` (groups and ranks), :mod:`~.text` (markdown, CSV), :mod:`~.board` (the
:class:`Leaderboard` of every task), :mod:`~.paths` (paths as shown: relative to ``runs=``, datasets by name and
content hash), :mod:`~.html` and :mod:`~.charts` (the HTML page). The public names are re-exported here.

Example:
    >>> board = build_leaderboard([], paper=True)   # the paper's baselines alone
    >>> [table.task for table in board.tables]
    ['seg', 'depth', 'completion']
    >>> print(board.to_markdown().splitlines()[0])
    # AirFisheye-bench leaderboard
"""

from airfisheye_bench.evaluation.leaderboard.board import Leaderboard, build_leaderboard
from airfisheye_bench.evaluation.leaderboard.collect import (
    PAPER_DATASET,
    PAPER_SOURCE,
    LeaderboardEntry,
    LeaderboardError,
    collect_results,
    find_results,
    load_entries,
    load_entry,
    paper_baselines,
)
from airfisheye_bench.evaluation.leaderboard.columns import (
    MISSING,
    breakdown_bins,
    format_value,
    higher_is_better,
    is_percent,
    metric_column,
    metric_label,
    rim_label,
)
from airfisheye_bench.evaluation.leaderboard.rank import (
    GROUPING,
    LeaderboardGroup,
    TaskTable,
    competition_ranks,
)
from airfisheye_bench.evaluation.leaderboard.text import csv_columns

__all__ = [
    "GROUPING",
    "MISSING",
    "PAPER_DATASET",
    "PAPER_SOURCE",
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
