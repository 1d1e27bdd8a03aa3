"""The Chamfer probe's records, summarised: each loss setting over its seeds, and each against training without the term.

``scripts/depth_probe.py ... json=<folder>/<setting>_seed<s>.json`` writes one record per run (every printed step's
numbers, with commit, command and dataset identity). A setting's seeds share the cached batches and differ in the
network's initialisation, and seed ``s`` of every setting starts from the same weights, so the per-seed difference
against the reference setting (``w0``: no Chamfer term) is paired (:mod:`~airfisheye_bench.studies.paired`).
``scripts/depth_probe_summary.py`` is the command.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from airfisheye_bench.studies.paired import paired_differences

__all__ = ["METRICS", "load_runs", "run_metrics", "summarize"]

#: What each run is scored by, all at its last step on the probe's validation frames.
METRICS = ("rmse", "abs_rel", "delta1", "train_mode_rmse", "eval_train_gap", "centre_median", "pred_over_gt")
_NAME = re.compile(r"^(?P<setting>.+)_seed(?P<seed>\d+)\.json$")


def load_runs(folder: str | Path) -> dict[str, dict[int, dict[str, Any]]]:
    """``{setting: {seed: record}}`` from the ``<setting>_seed<s>.json`` files of ``folder``."""
    runs: dict[str, dict[int, dict[str, Any]]] = {}
    for path in sorted(Path(folder).glob("*_seed*.json")):
        match = _NAME.match(path.name)
        if match:
            record = json.loads(path.read_text(encoding="utf-8"))
            runs.setdefault(match["setting"], {})[int(match["seed"])] = record
    return runs


def run_metrics(record: Mapping[str, Any]) -> dict[str, float]:
    """A run's numbers at its last step: eval-mode RMSE, AbsRel, δ1; train-mode (batch-statistics) RMSE and the gap
    between the two; the median bin centre and the predicted over the true mean depth of the last batch.

    Example:
        >>> last = {"val_eval": {"rmse": 20.0, "abs_rel": 0.3, "delta1": 0.5}, "val_train": {"rmse": 18.0},
        ...         "centre_median": 40.0, "pred_mean": 45.0, "gt_mean": 36.0}
        >>> m = run_metrics({"steps": [last]})
        >>> m["eval_train_gap"], m["pred_over_gt"]
        (2.0, 1.25)
    """
    last = record["steps"][-1]
    if "val_eval" not in last:
        raise ValueError("the run's last printed step has no validation scores (it did not finish)")
    return {
        "rmse": last["val_eval"]["rmse"],
        "abs_rel": last["val_eval"]["abs_rel"],
        "delta1": last["val_eval"]["delta1"],
        "train_mode_rmse": last["val_train"]["rmse"],
        "eval_train_gap": last["val_eval"]["rmse"] - last["val_train"]["rmse"],
        "centre_median": last["centre_median"],
        "pred_over_gt": last["pred_mean"] / last["gt_mean"],
    }


def summarize(runs: Mapping[str, Mapping[int, Mapping[str, Any]]], reference: str = "w0") -> dict[str, Any]:
    """Per setting, its seeds' numbers and whether each beat the trivial baseline; per setting, the paired
    difference against ``reference`` with its 95 % t-interval over seeds."""
    values = {s: {seed: run_metrics(r) for seed, r in by_seed.items()} for s, by_seed in runs.items()}
    settings: dict[str, Any] = {}
    for setting, by_seed in runs.items():
        settings[setting] = {
            "command": {str(seed): r["command"] for seed, r in sorted(by_seed.items())},
            "seeds": {str(seed): values[setting][seed] for seed in sorted(by_seed)},
            "beats_baseline": {
                str(seed): values[setting][seed]["rmse"] < r["baseline"]["rmse"]
                for seed, r in sorted(by_seed.items())
            },
        }
    commits = sorted({r["commit"] for by_seed in runs.values() for r in by_seed.values()})
    datasets = sorted({r["dataset"]["content_sha256"] for by_seed in runs.values() for r in by_seed.values()})
    baselines = {
        json.dumps(r["baseline"], sort_keys=True) for by_seed in runs.values() for r in by_seed.values()
    }
    if len(datasets) != 1 or len(baselines) != 1:
        raise ValueError(f"the runs were made on different data: {datasets}")
    return {
        "commits": commits,
        "dataset": datasets[0],
        "baseline": json.loads(baselines.pop()),
        "settings": settings,
        "paired_vs_" + reference: paired_differences(values, reference) if reference in values else {},
    }
