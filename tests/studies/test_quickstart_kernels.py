"""``scripts/quickstart_kernels.py``: limited-kernel runs pair with the record's seeds; the committed files agree."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from airfisheye_bench.studies.quickstart_kernels import kernel_runs, kernel_spread, load_records

REPO = Path(__file__).resolve().parents[2]
AVX2 = {"ATEN_CPU_CAPABILITY": "avx2", "MKL_CBWR": "AVX2"}


def _record(task: str, seeds: dict[str, float], switches: dict | None = None) -> dict:
    runs = {s: {"metrics": {"rmse": v}, "commit": "c" * 40} for s, v in seeds.items()}
    for run in runs.values():
        if switches:
            run["cpu_kernels"] = switches
    return {"tasks": {task: {"seeds": runs}}}


def test_limited_runs_pair_by_seed_and_reruns_on_the_records_kernels_are_left_out() -> None:
    record = _record("depth", {"0": 15.0, "1": 16.0, "2": 15.5})
    others = [
        _record("depth", {"0": 14.0, "2": 14.5}, AVX2),
        _record("depth", {"0": 15.0}),  # a re-run on the record's own kernels: the record holds that path
    ]
    runs = kernel_runs(record, others)
    assert set(runs["depth"]) == {"record", "avx2"}
    out = kernel_spread(runs, {"depth": ["rmse"]})["depth"]
    paired = out["paired"]["avx2"]["rmse"]
    assert paired["seeds"] == [0, 2] and paired["diffs"] == [-1.0, -1.0] and paired["ci95"] == [-1.0, -1.0]
    assert out["paths"]["record"]["rmse"]["std"] == pytest.approx(0.5)
    assert out["paths"]["avx2"]["cpu_kernels"] == [AVX2]


def test_the_committed_kernel_runs_are_on_the_records_data() -> None:
    record, others = load_records(
        REPO / "docs" / "quickstart_results.json", REPO / "docs" / "figures" / "quickstart_kernels"
    )
    assert others, "no kernel records"
    for other in others:
        assert other["dataset"]["content_sha256"] == record["dataset"]["content_sha256"]
    summary = json.loads((REPO / "docs" / "figures" / "quickstart_kernels" / "summary.json").read_text())
    fresh = kernel_spread(
        kernel_runs(record, others), {t: ["rmse"] for t in ("depth", "completion")} | {"seg": ["mIoU"]}
    )
    for task in fresh:
        for path, spread in fresh[task]["paths"].items():
            key = "mIoU" if task == "seg" else "rmse"
            assert summary[task]["paths"][path][key]["mean"] == pytest.approx(spread[key]["mean"])


def test_a_metric_missing_from_the_test_metrics_is_read_from_the_breakdown() -> None:
    record = _record("depth", {"0": 15.0})
    record["tasks"]["depth"]["seeds"]["0"]["breakdown"] = {"range_80-120/rmse": 31.0}
    other = _record("depth", {"0": 14.0}, AVX2)
    other["tasks"]["depth"]["seeds"]["0"]["breakdown"] = {"range_80-120/rmse": 26.0}
    out = kernel_spread(kernel_runs(record, [other]), {"depth": ["rmse", "range_80-120/rmse"]})["depth"]
    assert out["paired"]["avx2"]["range_80-120/rmse"]["diffs"] == [-5.0]


def test_cross_evaluation_refuses_a_folder_that_is_no_quick_start_run(tmp_path, capsys) -> None:
    spec = importlib.util.spec_from_file_location(
        "quickstart_kernels_script", REPO / "scripts" / "quickstart_kernels.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    assert script.main(["--cross-evaluate", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path) in err and "benchmark.json" in err
