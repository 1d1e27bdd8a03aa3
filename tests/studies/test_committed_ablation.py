"""The committed occlusion ablation agrees with itself: ``summary.json`` is what its committed run records give, and
``docs/results.md`` section 4.0 shows the summary's tables (so a record added without regenerating the
summary, or a summary regenerated without the report, fails here rather than in a reader's hands)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from airfisheye_bench.studies import ablation_records
from airfisheye_bench.studies.generated_blocks import block_in

ROOT = Path(__file__).resolve().parents[2]
ABLATION = ROOT / "docs" / "figures" / "occlusion_ablation"


@pytest.fixture(scope="module")
def summary() -> dict:
    return json.loads((ABLATION / "summary.json").read_text(encoding="utf-8"))


def test_the_summary_is_what_the_committed_records_give(summary: dict) -> None:
    records = ablation_records.load_records(ABLATION / "runs")
    assert summary["records"] == sorted(f"{r['method']}_seed{r['seed']}.json" for r in records)
    # Through JSON, as the file was written (tuples become lists; floats round-trip exactly).
    recomputed = json.loads(json.dumps(ablation_records.summarise(records)))
    assert {key: summary[key] for key in recomputed} == recomputed


def test_the_report_shows_the_summary(summary: dict) -> None:
    """Section 4.0's generated block is the summary's (runs, means, paired comparisons), with its commit."""
    report = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    begin, end = ablation_records.REPORT_BEGIN, ablation_records.REPORT_END
    assert report.count(begin) == 1 and report.count(end) == 1
    block = block_in(report, begin, end)
    assert block == ablation_records.report_block(summary, "figures/occlusion_ablation/summary.json")
    assert summary["provenance"]["commit"] in block  # the report names the summary it quotes
