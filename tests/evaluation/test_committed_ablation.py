"""The committed occlusion ablation agrees with itself: ``summary.json`` is what its committed run records give, and
``docs/results.md`` section 4.0 shows the summary's per-run table (so a record added without regenerating the
summary, or a summary regenerated without the report, fails here rather than in a reader's hands)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from airfisheye_bench.benchmarks import ablation_records

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


def test_the_report_shows_the_summary_runs(summary: dict) -> None:
    report = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    assert ablation_records.runs_table(summary["runs"]).strip() in report
    assert summary["provenance"]["commit"] in report  # the report names the summary it quotes
