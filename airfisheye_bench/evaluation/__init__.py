"""Evaluation: prediction sources, submissions, ``results.json`` and the leaderboard.

The evaluation command itself is :func:`airfisheye_bench.evaluation.command.evaluate` (``scripts/evaluate.py``).
"""

from airfisheye_bench.evaluation.leaderboard import (
    PAPER_BASELINES,
    Leaderboard,
    LeaderboardEntry,
    LeaderboardError,
    build_leaderboard,
    collect_results,
    find_results,
    load_entries,
    load_entry,
)
from airfisheye_bench.evaluation.results import (
    PRIMARY_METRIC,
    RESULTS_VERSION,
    dataset_identity,
    load_results,
    write_results,
)
from airfisheye_bench.evaluation.submission import (
    SubmissionError,
    SubmissionWriter,
    read_prediction,
    validate_submission,
    write_prediction,
    write_submission,
)

__all__ = [
    "PAPER_BASELINES",
    "PRIMARY_METRIC",
    "RESULTS_VERSION",
    "Leaderboard",
    "LeaderboardEntry",
    "LeaderboardError",
    "SubmissionError",
    "SubmissionWriter",
    "build_leaderboard",
    "collect_results",
    "dataset_identity",
    "find_results",
    "load_entries",
    "load_entry",
    "load_results",
    "read_prediction",
    "validate_submission",
    "write_prediction",
    "write_results",
    "write_submission",
]
