"""``scripts/bench_lightning.py`` (:mod:`airfisheye_bench.studies.lightning_overhead`) runs end to end on a tiny configuration (structure only, no timing thresholds)."""

from __future__ import annotations

import math
from types import ModuleType

import pytest

from airfisheye_bench.studies import lightning_overhead


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return lightning_overhead


@pytest.mark.integration
def test_main_tiny(bench: ModuleType, capsys: pytest.CaptureFixture[str]) -> None:
    steps, repeats = 3, 2
    argv = ["--tasks", "seg", "--size", "32", "--batch", "2", "--warmup", "2", "--steps", str(steps)]
    results = bench.main([*argv, "--repeats", str(repeats)])
    assert [r.task for r in results] == ["seg"]
    result = results[0]
    for clock in bench.CLOCKS:
        for variant in bench.VARIANTS:
            times = result.steps_ms[clock][variant]
            assert len(times) == steps * repeats
            assert all(math.isfinite(t) and t > 0 for t in times)
            assert len(result.rep_medians[clock][variant]) == repeats
        for variant in ("trainer", "trainer_csv"):
            assert math.isfinite(result.overhead_pct(variant, clock))
            lo, hi = result.overhead_range_pct(variant, clock)
            assert lo <= hi
    table = capsys.readouterr().out
    assert table.count("| seg |") == len(bench.CLOCKS)
