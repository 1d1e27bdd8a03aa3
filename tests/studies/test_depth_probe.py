"""The Chamfer probe's summary: paired per seed against training without the term, on one dataset only."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from airfisheye_bench.studies import depth_probe


def _record(rmse: float, data: str = "abc") -> dict:
    last = {
        "val_eval": {"rmse": rmse, "abs_rel": 0.3, "delta1": 0.5},
        "val_train": {"rmse": rmse - 1.0},
        "centre_median": 40.0,
        "pred_mean": 40.0,
        "gt_mean": 40.0,
    }
    return {
        "commit": "c" * 40,
        "command": "python scripts/depth_probe.py",
        "dataset": {"content_sha256": data},
        "baseline": {"rmse": 24.0, "abs_rel": 0.31, "delta1": 0.35},
        "steps": [{"step": 0}, last],
    }


def _write(folder: Path, runs: dict[str, dict]) -> None:
    for name, record in runs.items():
        (folder / f"{name}.json").write_text(json.dumps(record))


def test_settings_are_paired_per_seed_against_no_chamfer_term(tmp_path: Path) -> None:
    _write(
        tmp_path,
        {
            "w0_seed0": _record(20.0),
            "w0_seed1": _record(22.0),
            "w0.1_range10_seed0": _record(21.0),
            "w0.1_range10_seed1": _record(25.0),  # worse than the baseline (24 m)
        },
    )
    summary = depth_probe.summarize(depth_probe.load_runs(tmp_path))
    assert summary["settings"]["w0.1_range10"]["beats_baseline"] == {"0": True, "1": False}
    diff = summary["paired_vs_w0"]["w0.1_range10"]["rmse"]
    assert diff["seeds"] == [0, 1] and diff["diffs"] == [1.0, 3.0] and diff["mean"] == 2.0
    assert summary["settings"]["w0"]["seeds"]["0"]["eval_train_gap"] == 1.0


def test_runs_on_different_data_are_refused(tmp_path: Path) -> None:
    _write(tmp_path, {"w0_seed0": _record(20.0), "w0.1_seed0": _record(21.0, data="def")})
    with pytest.raises(ValueError, match="different data"):
        depth_probe.summarize(depth_probe.load_runs(tmp_path))


def test_an_unfinished_run_says_so() -> None:
    with pytest.raises(ValueError, match="did not finish"):
        depth_probe.run_metrics({"steps": [{"step": 0}]})
