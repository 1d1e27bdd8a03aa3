"""``scripts/bench_evaluate.py`` (:mod:`airfisheye_bench.studies.evaluation_speed`) runs end to end on the tiny dataset (structure only, no timing thresholds)."""

from __future__ import annotations

import math
from pathlib import Path
from types import ModuleType

import pytest

from airfisheye_bench.studies import evaluation_speed


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return evaluation_speed


def test_main_tiny(
    bench: ModuleType, tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    frames, repeat = 14, 2  # more than the 12 distinct frames: the second repetition reuses them
    argv = ["--root", str(tiny_dataset), "--data", str(tmp_path), "--size", "64", "--frames", str(frames)]
    argv += ["--repeat", str(repeat), "--parts-frames", "4", "--batch-size", "4"]
    results = bench.main(argv)
    assert [r.task for r in results] == ["seg", "depth"]
    for r in results:
        assert r.frames == frames and r.distinct_frames == 12 and r.size == 64
        assert len(r.loop_s) == len(r.validate_s) == len(r.loop_cpu_s) == repeat
        assert all(math.isfinite(t) and t > 0 for t in [*r.loop_s, *r.validate_s])
        expected = {"gt", "prediction", "metric", "rings"} | ({"ranges"} if r.task == "depth" else set())
        assert set(r.parts_ms) == expected
        assert all(math.isfinite(ms) and ms >= 0 for ms in r.parts_ms.values())
        assert r.frames_per_s == pytest.approx(frames / min(r.loop_s))
        assert any(k.startswith("ring_") for k in r.breakdown)
        assert any(k.startswith("range_") for k in r.breakdown) == (r.task == "depth")
    seg, depth = results
    assert 0.0 < seg.metrics["mIoU"] < 1.0 and seg.metrics["pixel_acc"] > 0.5  # ~10% relabelled
    assert 0.0 < depth.metrics["abs_rel"] < 0.3  # log-normal noise of sigma 0.1
    out = capsys.readouterr().out
    assert out.count("| seg |") == 1 and out.count("| depth |") == 1
    # One prediction file per repeated frame, each under its own id.
    files = sorted((tmp_path / f"preds-{tiny_dataset.name}-seg-png-64px-{frames}f").rglob("*.png"))
    assert len(files) == frames
    assert {f.parent.parent.name for f in files} == {"rep0000", "rep0001"}


def test_repeated_frames_ids(bench: ModuleType, tiny_dataset: Path) -> None:
    dataset = bench.evaluation_set(tiny_dataset, "depth", 64, 30)
    assert len(dataset) == 30 and len(set(dataset.sample_ids)) == 30
    sample = dataset[13]
    assert sample["sample_id"] == dataset.sample_ids[13] and sample["sample_id"].startswith("rep0001/")
    env, traj, frame = dataset.base_id(13).split("/")
    assert sample["sample_id"] == f"rep0001/{env}_{traj}/{frame}"
    assert (sample["depth"] == dataset[1]["depth"]).all()  # frame 13 repeats frame 1


@pytest.mark.parametrize("task", ["seg", "depth"])
def test_scoring_in_workers_matches_main_process(
    bench: ModuleType, tiny_dataset: Path, tmp_path: Path, task: str
) -> None:
    """File predictions scored in the loader workers (states merged) give the main process's numbers."""
    import torch

    from airfisheye_bench.evaluation.evaluator import _can_score_in_workers

    dataset = bench.evaluation_set(tiny_dataset, task, 64, 20)
    folder = bench.ensure_predictions(tmp_path / "preds", dataset, task, "png")
    theta = torch.rad2deg(dataset.camera.theta_grid()).float()
    assert _can_score_in_workers(bench.make_scorer(task, dataset), theta)
    threads = torch.get_num_threads()
    results = [
        bench.evaluate_predictions(
            bench.FilePredictor(folder, task, dataset.sample_ids, (64, 64)),
            dataset,
            bench.make_scorer(task, dataset),
            theta,
            batch_size=3,  # a last, partial batch
            num_workers=workers,
            num_panels=0,
        )
        for workers in (0, 2)
    ]
    assert torch.get_num_threads() == threads  # the loop's thread limit is undone
    main, workers = results
    assert main.num_frames == workers.num_frames == 20
    for a, b in ((main.metrics, workers.metrics), (main.breakdown, workers.breakdown)):
        assert a.keys() == b.keys()
        for key, value in a.items():
            assert b[key] == pytest.approx(value, rel=1e-12, abs=1e-12, nan_ok=True), key
