"""docs/training.md's estimate of what a reproduction costs: the arithmetic, and that the committed block is what the
committed records give."""

from __future__ import annotations

from pathlib import Path

import pytest

from airfisheye_bench.studies import reproduction_cost
from airfisheye_bench.studies.generated_blocks import block_in

ROOT = Path(__file__).resolve().parents[2]


def _campaign(ceiling: float, worker: float | None, device: float | None) -> dict:
    summary = {"ceiling_images_per_s": ceiling}
    summary |= {} if worker is None else {"fed_worker_images_per_s": worker}
    summary |= {} if device is None else {"fed_device_images_per_s": device}
    recipe = {"experiment": "paper/completion", "batch": 6, "size": 512}
    return {"tasks": {"completion": {"recipe": recipe, "summary": summary}}}


def test_hours_are_the_images_of_the_epochs_over_the_measured_rate() -> None:
    hours = reproduction_cost.training_hours(_campaign(50.0, 40.0, 45.0), frames=26000, epochs=25)[
        "completion"
    ]
    assert hours["hours_ceiling"] == pytest.approx(26000 * 25 / 50.0 / 3600)
    assert hours["fed_site"] == "device" and hours["hours_fed"] == pytest.approx(26000 * 25 / 45.0 / 3600)
    unfed = reproduction_cost.training_hours(_campaign(50.0, None, None), frames=10)["completion"]
    assert unfed["fed_site"] is None and unfed["hours_fed"] is None  # not measured: not estimated


def test_generation_cost_is_cpu_seconds_per_frame_times_frames() -> None:
    row = {"preset": "paper", "frame_cpu_s": 6.0, "frame_s": 15.0, "load_average_before": [1.0] * 3}
    cost = reproduction_cost.generation_cost(
        {"presets": [{"preset": "tiny"}, {**row, "load_average_after": [2.0] * 3}]}, 26000
    )
    assert cost["core_hours"] == pytest.approx(26000 * 6.0 / 3600) and cost["wall_s_per_frame"] == 15.0


def test_the_training_docs_hold_the_estimate_the_records_give() -> None:
    text = (ROOT / "docs" / "training.md").read_text(encoding="utf-8")
    shown = block_in(text, reproduction_cost.BEGIN, reproduction_cost.END)
    assert shown == reproduction_cost.committed_block(ROOT), "regenerate: python scripts/reproduction_cost.py"
    assert "not a measured reproduction" in shown
