"""docs/benchmarks.md's estimate of whether 16 cores feed one GPU: the arithmetic, the verdict's rules, and that the
committed record is what its inputs give."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
from torch import nn

from airfisheye_bench.studies import gpu_feed

ROOT = Path(__file__).resolve().parents[2]
RECORD = ROOT / "docs" / "figures" / "gpu_feed_estimate.json"


def _loader_row(
    task: str, face: int, rgb: str, depth: str, site: str, per_core: float, size: int = 512
) -> dict:
    return {
        "task": task,
        "size": size,
        "face_size": face,
        "rgb_encoding": rgb,
        "depth_encoding": depth,
        "remap_on": site,
        "samples_per_s_per_core": per_core,
    }


def test_store_rates_are_the_workers_times_the_per_core_rate_of_the_task_at_its_size() -> None:
    loader = {
        "results": [
            _loader_row("seg", 512, "png", "png16", "worker", 10.0),
            _loader_row("seg", 512, "png", "png16", "device", 20.0),
            _loader_row("seg", 1024, "jpg", "npy", "worker", 5.0),
            _loader_row("depth", 512, "png", "png16", "worker", 99.0),  # another task
            _loader_row("seg", 1024, "png", "png16", "worker", 99.0, size=1024),  # served at another size
        ]
    }
    assert gpu_feed.store_rates(loader, "seg", 512, workers=15) == {
        "512^2 PNG": {"face_size": 512, "encoding": "PNG", "worker": 150.0, "device": 300.0},
        "1024^2 JPEG + npy": {"face_size": 1024, "encoding": "JPEG + npy", "worker": 75.0},
    }


def test_the_estimate_scales_the_published_rate_by_flops() -> None:
    assert gpu_feed.a100_estimate(gflop=80.0, resnet50=8.0, rate=1000.0) == pytest.approx(100.0)
    assert gpu_feed.forward_gflop(
        nn.Linear(10, 4, bias=False), {"input": torch.zeros(3, 10)}
    ) == pytest.approx(2 * 3 * 10 * 4 / 1e9)


@pytest.mark.parametrize(
    ("worker", "device", "said"),
    [
        (250.0, 300.0, "**keeps up** from 512^2 PNG faces"),
        (
            150.0,
            250.0,
            "feeds an A100-class GPU from 512^2 PNG faces (1.50x / 2.50x the estimate, worker / device); "
            "a 2x faster one with `remap_on=device`",
        ),
        (
            150.0,
            160.0,
            "feeds an A100-class GPU from 512^2 PNG faces (1.50x / 1.60x the estimate, worker / device); "
            "no measured store feeds a 2x faster one",
        ),
        (90.0, 120.0, "feeds an A100-class GPU from 512^2 PNG faces only with `remap_on=device`"),
        (50.0, 60.0, "**starved from 512^2 PNG faces** (0.50x / 0.60x the A100 estimate)"),
    ],
)
def test_the_verdict_follows_the_rates(worker: float, device: float, said: str) -> None:
    assert gpu_feed.verdict(100.0, {"512^2 PNG": {"worker": worker, "device": device}}, 512).startswith(said)


def test_the_verdict_names_the_stores_that_feed_a_faster_gpu_and_judges_larger_faces() -> None:
    stores = {
        "512^2 PNG": {"worker": 120.0, "device": 150.0},
        "512^2 JPEG + npy": {"worker": 180.0, "device": 210.0},
        "1024^2 JPEG + npy": {"worker": 205.0},
        "1024^2 PNG": {"worker": 170.0, "device": 180.0},
    }
    said = gpu_feed.verdict(100.0, stores, 512).split("; ")
    assert said[1] == (
        "a 2x faster one only from 512^2 JPEG + npy faces with `remap_on=device` (210/s), "
        "1024^2 JPEG + npy faces with `remap_on=worker` (205/s)"
    )
    assert said[2] == (
        "feeds an A100-class GPU from 1024^2 PNG faces (1.70x / 1.80x the estimate, worker / device), "
        "not a 2x faster one"
    )


def test_the_table_has_the_recipe_the_numbers_and_the_verdict() -> None:
    recipe = {"task": "seg", "experiment": "paper/seg", "model": "deeplabv3plus", "encoder": "resnet50"}
    loader = {
        "results": [
            _loader_row("seg", 512, "png", "png16", s, r) for s, r in (("worker", 20), ("device", 30))
        ]
    }
    (row,) = gpu_feed.estimate([recipe | {"batch": 8, "size": 512, "gflop": 73.2}], 8.18, loader)
    lines = gpu_feed.table([row]).splitlines()
    assert lines[0].startswith("| recipe | forward GFLOP at 512^2 | A100 estimate (images/s) |")
    assert lines[2].startswith(
        "| `paper/seg` (DeepLabV3+ R50, batch 8) | 73.2 | 276 | 18.4 / 36.8 | 300 / 450 | – |"
    )


def test_the_committed_record_is_what_its_inputs_give() -> None:
    """The record's table is its rows', and its rows' loader rates are the committed loader record's: a loader
    record measured again leaves this estimate stale until ``scripts/gpu_feed_estimate.py`` runs again."""
    record = json.loads(RECORD.read_text())
    fields = set(gpu_feed.Row.__dataclass_fields__)
    rows = [gpu_feed.Row(**{k: v for k, v in r.items() if k in fields}) for r in record["rows"]]
    assert gpu_feed.table(rows) in record["output"]
    loader_path = ROOT / record["loader_record"]["path"]
    loader = json.loads(loader_path.read_text())
    for row in rows:
        assert row.stores == gpu_feed.store_rates(loader, row.task, row.size), (
            f"{RECORD.name}: {row.task}'s loader rates are not {loader_path.name}'s; run "
            "python scripts/gpu_feed_estimate.py --out docs/figures/gpu_feed_estimate.json again"
        )
    assert [r.task for r in rows] == list(gpu_feed.TASKS)
