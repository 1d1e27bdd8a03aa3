"""Two CPU processes on gloo, each updating part of the batches, give the single-process numbers."""

from __future__ import annotations

import math

import pytest
import torch
import torch.distributed as dist
import torch.multiprocessing as mp

from airfisheye_bench.metrics import BinnedMetrics, CompletionMetrics, DepthMetrics, SegmentationMetrics

WORLD_SIZE = 2
C = 4


def _make_metrics() -> dict[str, torch.nn.Module]:
    return {
        "seg": SegmentationMetrics(C),
        "depth": DepthMetrics(),
        "completion": CompletionMetrics(),
        "rings": BinnedMetrics(DepthMetrics, edges=(0, 30, 60, 95)),
        "seg_ranges": BinnedMetrics(lambda: SegmentationMetrics(C), key="depth"),
    }


def _batches(n=5, b=2, h=12, w=12):
    g = torch.Generator().manual_seed(0)
    theta = torch.rand(h, w, generator=g) * 100.0
    out = []
    for i in range(n):
        gt = torch.rand(b, 1, h, w, generator=g) * 130.0
        gt[torch.rand(b, 1, h, w, generator=g) < 0.2] = 0.0
        if i == 3:
            gt[0] = 0.0  # an image without a valid pixel, on rank 1
        pred = gt * torch.exp(0.3 * torch.randn(b, 1, h, w, generator=g))
        logits = torch.randn(b, C, h, w, generator=g)
        labels = torch.randint(0, C, (b, h, w), generator=g)
        labels[:, 0] = 255
        out.append({"pred": pred, "gt": gt, "logits": logits, "labels": labels, "theta": theta})
    return out


def _update(metrics, batch):
    metrics["seg"].update(batch["logits"], batch["labels"])
    metrics["depth"].update(batch["pred"], batch["gt"])
    metrics["completion"].update(batch["pred"], batch["gt"])
    metrics["rings"].update(batch["pred"], batch["gt"], theta=batch["theta"])
    metrics["seg_ranges"].update(batch["logits"], batch["labels"], depth=batch["gt"])


def _compute(metrics):
    out = {f"{name}/{k}": v for name, m in metrics.items() for k, v in m.compute().items()}
    out["seg/confmat"] = metrics["seg"].confmat.clone()  # after compute(): the local (unsynced) state again
    return out


def _worker(rank: int, init_file: str, batches, results: str) -> None:
    torch.set_num_threads(1)
    dist.init_process_group("gloo", init_method=f"file://{init_file}", rank=rank, world_size=WORLD_SIZE)
    try:
        metrics = _make_metrics()
        for batch in batches[rank::WORLD_SIZE]:  # uneven split: 3 batches on rank 0, 2 on rank 1
            _update(metrics, batch)
        torch.save(_compute(metrics), f"{results}.{rank}")
    finally:
        dist.destroy_process_group()


@pytest.mark.integration
def test_two_gloo_processes_match_one_process(tmp_path):
    batches = _batches()
    single = _make_metrics()
    for batch in batches:
        _update(single, batch)
    expected = _compute(single)

    results = str(tmp_path / "result")
    # Forked, not spawned: the two ranks inherit this process's imports instead of importing torch again (seconds).
    mp.start_processes(
        _worker, args=(str(tmp_path / "init"), batches, results), nprocs=WORLD_SIZE, start_method="fork"
    )
    for rank in range(WORLD_SIZE):
        got = torch.load(f"{results}.{rank}")
        assert got.keys() == expected.keys()
        for key, value in expected.items():
            if key == "seg/confmat":
                continue  # the local state differs per rank by design; checked below
            if value.dtype == torch.int64:
                assert torch.equal(got[key], value), key
            elif math.isnan(value.item()):
                assert math.isnan(got[key].item()), key
            else:
                # float64 sums added in another order: equal up to the last bits
                assert got[key].item() == pytest.approx(value.item(), rel=1e-12, abs=1e-15), key
        assert got["seg/confmat"].sum() < expected["seg/confmat"].sum()  # each rank really saw only part
