"""``scripts/bench_lightning.py`` (:mod:`airfisheye_bench.studies.lightning_overhead`) runs end to end on a tiny configuration (structure only, no timing thresholds)."""

from __future__ import annotations

import math
from pathlib import Path
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


def test_update_docs_inserts_then_rewrites_only_its_block(bench: ModuleType, tmp_path: Path) -> None:
    """The first write adds the section before ``## Models``; later ones rewrite the table's block alone, so the
    record's citation and the judgement written under it stay."""
    doc = tmp_path / "benchmarks.md"
    doc.write_text("# Benchmarks\n\n## Metrics\n\nm\n\n## Models\n\nx\n")
    bench.update_docs("first", doc)
    doc.write_text(doc.read_text().replace(f"{bench.END}\n", f"{bench.END}\n\nRecord: r. Judged: j.\n"))
    bench.update_docs("second", doc)
    assert doc.read_text() == (
        f"# Benchmarks\n\n## Metrics\n\nm\n\n{bench.SECTION}\n\n{bench.BEGIN}\nsecond\n{bench.END}\n\n"
        "Record: r. Judged: j.\n\n## Models\n\nx\n"
    )
