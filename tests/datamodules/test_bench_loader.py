"""``scripts/bench_loader.py`` (:mod:`airfisheye_bench.benchmarks.loader_speed`) runs end to end on the tiny dataset (structure only, no timing thresholds)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from airfisheye_bench.benchmarks import loader_speed


@pytest.mark.integration
def test_main_tiny(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bench = loader_speed
    argv = ["--root", str(tiny_dataset), "--size", "32", "--samples", "3", "--repeats", "2"]
    results = bench.main([*argv, "--tasks", "seg", "completion"])
    assert [(r["task"], r["source"]) for r in results] == [
        ("seg", "cubemap"),
        ("seg", "fisheye"),
        ("completion", "cubemap"),
        ("completion", "fisheye"),
    ]
    for r in results:
        assert 0 < r["cpu_min"] <= r["cpu_median"] and math.isfinite(r["cpu_median"])
        assert r["decode"] >= 0 and math.isfinite(r["rss_growth"])
    rows = [
        line
        for line in capsys.readouterr().out.splitlines()
        if line.startswith("| seg") or line.startswith("| completion")
    ]
    assert len(rows) == 4
