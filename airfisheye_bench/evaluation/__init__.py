"""Evaluation: prediction sources, submissions and the leaderboard; ``results.json`` is
:mod:`airfisheye_bench.runs.results` (training writes it too), re-exported here with the leaderboard that reads it.

The evaluation command itself is :func:`airfisheye_bench.evaluation.command.evaluate` (``scripts/evaluate.py``).
"""

from airfisheye_bench.evaluation.leaderboard import (
    Leaderboard,
    LeaderboardEntry,
    LeaderboardError,
    build_leaderboard,
    collect_results,
    find_results,
    load_entries,
    load_entry,
    paper_baselines,
)
from airfisheye_bench.evaluation.submission import (
    SubmissionError,
    SubmissionWriter,
    read_prediction,
    validate_submission,
    write_prediction,
    write_submission,
)
from airfisheye_bench.runs.results import (
    RESULTS_VERSION,
    dataset_identity,
    load_results,
    write_results,
)

__all__ = [
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
    "paper_baselines",
    "read_prediction",
    "validate_submission",
    "write_prediction",
    "write_results",
    "write_submission",
]
