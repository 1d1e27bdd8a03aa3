"""``scripts/gpu_campaign.py``: the time boxes of its record, and the whole campaign in ``--smoke`` mode on the CPU.

The smoke run checks the record's fields (what a GPU run will fill in), not its numbers. It trains three recipes and
starts loader workers (about a minute of CPU for a script that only a GPU machine runs), so it is in the ``slow``
suite, which CI runs on every landing.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import pytest

from airfisheye_bench.studies import gpu_campaign
from airfisheye_bench.studies.campaign_record import CampaignRecord

TASKS = ("seg", "depth", "completion")


def test_phases_are_time_boxed(tmp_path: Path) -> None:
    """A loop that watches its deadline stops there; one that does not is interrupted; an error is recorded; the file
    is valid JSON after every phase; a phase without enough time left is skipped."""
    path = tmp_path / "record.json"
    record = CampaignRecord(path, budget_s=30.0, data={}, grace_s=0.3, watchdog=False)

    def polite(phase) -> None:
        while not phase.expired("the loop"):
            record.set("count", value=record.data.get("count", 0) + 1)
            time.sleep(0.01)

    def stuck(phase) -> None:
        while True:
            time.sleep(0.01)

    record.run_phase("polite", polite, budget_s=0.2)
    record.run_phase("stuck", stuck, budget_s=0.2)
    record.run_phase("broken", lambda phase: 1 / 0, budget_s=1.0)
    assert json.loads(path.read_text())["phases"]["broken"]["error"].startswith("ZeroDivisionError")
    record.run_phase("late", lambda phase: None, budget_s=1.0, minimum_s=60.0)
    record.finish()
    saved = json.loads(path.read_text())
    statuses = {name: p["status"] for name, p in saved["phases"].items()}
    assert statuses["polite"] == "stopped at the time box: the loop"
    assert statuses["stuck"] == "timeout" and saved["phases"]["stuck"]["wall_s"] < 2.0
    assert statuses["broken"] == "error" and statuses["late"].startswith("skipped")
    assert saved["status"] == "partial" and saved["count"] > 0


@pytest.fixture(scope="module")
def smoke(tmp_path_factory: pytest.TempPathFactory) -> dict:
    folder = tmp_path_factory.mktemp("campaign")
    out = folder / "campaign.json"
    gpu_campaign.main(
        ["--smoke", "--out", str(out), "--data-dir", str(folder / "data"), "--commit", "0" * 40]
    )
    return json.loads(out.read_text())


@pytest.mark.slow
def test_smoke_record(smoke: dict) -> None:
    assert smoke["mode"] == "smoke" and smoke["status"] == "complete", smoke["phases"]
    prov = smoke["provenance"]
    assert prov["commit"] == "0" * 40 and prov["command"].startswith("python scripts/gpu_campaign.py --smoke")
    assert prov["cpu_count"] >= 1 and prov["torch"] and prov["device_name"] == "cpu"
    assert {"cuda", "cudnn", "machine", "tf32"} <= set(prov)
    assert smoke["data"]["frames"]["train"] > 0 and smoke["data"]["served_size"] == 64
    assert len(smoke["data"]["dataset"]["content_sha256"]) == 64  # the data it measured, by content
    assert set(smoke["phases"]) == {"data", "loader", *(f"train:{t}" for t in TASKS)}


@pytest.mark.slow
@pytest.mark.parametrize("task", TASKS)
def test_smoke_task(smoke: dict, task: str) -> None:
    entry = smoke["tasks"][task]
    recipe = entry["recipe"]
    assert recipe["experiment"] == f"paper/{task}" and recipe["precision"] == "16-mixed"
    assert recipe["amp_dtype"] == "bfloat16" and recipe["batch"] == 2  # the CPU's autocast, the smoke batch
    assert recipe["gradient_clip_norm"] == (0.1 if task == "depth" else None)
    for key in ("cached", "cached_fp32"):
        assert entry[key]["steps"] >= 1 and entry[key]["images_per_s"] > 0
    assert "peak_allocated_gib" in entry["cached"]
    parity = entry["amp_parity"]
    assert math.isfinite(parity["loss_fp32"]) and math.isfinite(parity["loss_amp"])
    assert 0 <= parity["loss_rel_diff"] < 0.5
    assert ("prediction_agreement" if task == "seg" else "prediction_rel_diff_median") in parity
    for site in ("worker", "device"):
        fed = entry["fed"][site]
        assert fed["steps"] == 2 and fed["images_per_s"] > 0
        # No workers: every batch is made when asked for, so the first one after the warm-up waits.
        assert fed["drained"] is True and fed["warmup_steps"] == 2
        assert fed["pin_memory"] is False  # the recipe does not pin, and a CPU has no pinned variant
        assert 0 <= fed["host_wait_share"] <= 1 and 0 <= fed["device_idle_share"] <= 1
        assert fed["device_step_ms"] > 0 and fed["device_transfer_and_finish_ms"] >= 0
        assert isinstance(entry["summary"][f"fed_{site}_keeps_up"], bool)
    assert entry["summary"]["ceiling_images_per_s"] == entry["cached"]["images_per_s"]


@pytest.mark.slow
def test_smoke_loader(smoke: dict) -> None:
    rows = {(r["task"], r["workers"], r["remap_on"]): r for r in smoke["loader"]}
    expected = {(t, w, "worker") for t in TASKS for w in (0, 2)} | {(t, 2, "device") for t in TASKS}
    assert set(rows) == expected
    assert all(r["samples"] > 0 and r["samples_per_s"] > 0 and r["startup_s"] >= 0 for r in rows.values())


def test_a_finished_campaign_leaves_its_process_alive(tmp_path: Path) -> None:
    """The watchdog ends a campaign's process only past the budget: one that finished stands it down (main() runs
    inside test workers, which must outlive it)."""
    record = CampaignRecord(tmp_path / "r.json", budget_s=0.2, data={}, grace_s=0.05)
    record.finish()
    time.sleep(0.6)  # past budget + 2 x grace: a live watchdog would have ended this process
    assert json.loads((tmp_path / "r.json").read_text())["status"] == "complete"
