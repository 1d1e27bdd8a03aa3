"""The generation cost record: what it measures on a preset, and the table of docs/datasets.md generated from it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from airfisheye_bench.studies import generation_cost
from airfisheye_bench.studies.generated_blocks import block_in
from airfisheye_bench.synth.presets import get_preset

ROOT = Path(__file__).resolve().parents[2]
RECORD = ROOT / "docs" / "figures" / "generation_cost.json"


@pytest.mark.integration
def test_a_preset_is_timed_with_the_load_and_the_frames_it_wrote() -> None:
    first, again = (generation_cost.measure(["tiny"], frames=1)[0] for _ in range(2))
    cfg = get_preset("tiny")
    assert first["frames_timed"] == 1 and first["frame_s"] > 0 and first["build_s"] > 0
    assert (
        0 < first["frame_cpu_s"] < 2 * first["frame_s"]
    )  # one thread: CPU time does not exceed the wall's much
    assert len(first["load_average_before"]) == len(first["load_average_after"]) == 3
    seconds = cfg.total_frames * first["frame_cpu_s"] + cfg.num_trajectories * first["build_s"]
    assert first["core_hours"] == pytest.approx(seconds / 3600, rel=1e-2)  # the record rounds the seconds
    # The identity is of what was written, not of when: the same frames again give the same one.
    assert first["content_sha256"] == again["content_sha256"] and len(first["content_sha256"]) == 64


def test_the_docs_table_is_the_committed_records() -> None:
    record = json.loads(RECORD.read_text())
    docs = (ROOT / "docs" / "datasets.md").read_text()
    assert block_in(docs, generation_cost.BEGIN, generation_cost.END) == generation_cost.cost_table(record)
    assert "paper" in {row["preset"] for row in record["presets"]}
    assert all(row["frames_timed"] <= 2 for row in record["presets"])
