"""Evaluation outputs: the ``results.json`` format shared by training, evaluation and the leaderboard."""

from airfisheye_bench.evaluation.results import RESULTS_VERSION, load_results, write_results

__all__ = ["RESULTS_VERSION", "load_results", "write_results"]
