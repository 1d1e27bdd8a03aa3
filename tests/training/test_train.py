"""Every task trains, validates and tests through ``train(cfg)`` on the tiny synthetic preset."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest
from omegaconf import OmegaConf, open_dict

from airfisheye_bench.errors import MissingFileError
from airfisheye_bench.runs import resolve_checkpoint
from airfisheye_bench.training import train
from tests.helpers.configs import compose_train
from tests.helpers.runs import DONE, tiny_run_overrides

pytestmark = pytest.mark.integration  # trains, evaluates or exports: seconds per test


@pytest.fixture(scope="module", params=["seg", "depth", "completion"])
def task_run(request: pytest.FixtureRequest, tiny_runs) -> tuple[str, Path]:
    """``(task, run folder)``: the session's tiny run of each task, trained as set-up on first use."""
    return request.param, tiny_runs(request.param)


def test_fast_dev_run(task_run: tuple[str, Path]) -> None:
    """The session's tiny run of each task (``tests.helpers.runs.shared_run``: ``train(cfg)`` on the debug trainer)."""
    task, run = task_run
    results = json.loads((run / DONE).read_text())  # what train(cfg) returned
    primary = OmegaConf.load(run / "config.yaml").task.primary_metric
    assert primary in results["metrics"]
    record = json.loads((run / "results.json").read_text())
    assert record["task"] == task and record["split"] == "test" and record["primary_metric"] == primary
    assert record["metrics"][primary] == pytest.approx(results["metrics"][primary], nan_ok=True)
    assert any(k.startswith("ring_") for k in record["breakdown"])
    assert record["dataset"]["manifest_sha256"]
    if task == "completion":  # how densely the sparse input covered the test split's ground truth, by ring
        coverage = record["sparse_coverage"]
        assert set(coverage) == {"ring_0-30", "ring_30-60", "ring_60-80", "ring_80-95"}
        assert all(0 < value <= 1 for value in coverage.values())
    else:
        assert "sparse_coverage" not in record
    assert (run / "checkpoints" / "last.ckpt").is_file()
    assert (run / "config.yaml").is_file() and (run / "metrics.csv").is_file()
    assert list((run / "panels").glob("epoch_*.png"))


def test_a_run_keeps_its_best_as_epoch_nnn_and_checkpoints_best_names_it(tiny_runs) -> None:
    """What README and docs/training.md say a run writes: ``epoch_NNN.ckpt`` (the best) and ``last.ckpt``; the
    commands' ``ckpt_path=<run>/checkpoints/best`` (no such file) is the best one, as the run directory is."""
    run = tiny_runs("seg")
    best = Path(json.loads((run / "results.json").read_text())["model"]["checkpoint"])
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["epoch_000.ckpt", "last.ckpt"]
    assert best == run / "checkpoints" / "epoch_000.ckpt"
    for given in ("best", "best.ckpt"):
        assert resolve_checkpoint(run / "checkpoints" / given) == best == resolve_checkpoint(run)
    with pytest.raises(MissingFileError, match="does not exist"):
        resolve_checkpoint(run / "checkpoints" / "worst")


def test_a_lens_wider_than_190_degrees_is_scored_out_to_its_rim(tiny_dataset: Path, tmp_path: Path) -> None:
    """The default rings end at 95 deg; a 220 deg lens gets one more ring, so its rim pixels land in a ring.

    The rings are the task's base class's (every task alike): seg, whose warm-up the module's other runs share, on
    one training batch (the test's breakdown is what is checked)."""
    overrides = ["data.source=cubemap", "data.camera.fov_deg=220", "trainer.limit_train_batches=1"]
    cfg = compose_train([*tiny_run_overrides("seg", tiny_dataset), *overrides])
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    train(cfg)
    breakdown = json.loads((tmp_path / "results.json").read_text())["breakdown"]
    # The 190 deg default: ring_edges_for's example.
    assert {"ring_80-95/mIoU", "ring_95-110/mIoU"} <= set(breakdown)


def test_the_test_summary_is_compact_unless_the_breakdown_is_asked_for() -> None:
    from airfisheye_bench.training import summarise_test

    results = {
        "metrics": {"mIoU": 0.25, "pixel_acc": 0.6, "IoU/road": 0.5},
        "breakdown": {"ring_0-30/mIoU": 0.3, "ring_0-30/IoU/road": 0.55, "ring_30-60/mIoU": 0.2},
    }
    cfg = compose_train(["task=seg"])
    compact = summarise_test(cfg, results)
    assert "mIoU" in compact and "road" in compact and "ring_0-30" in compact
    assert "ring_0-30/IoU/road" not in compact and "print_breakdown=true" in compact
    with open_dict(cfg):
        cfg.print_breakdown = True
    assert "ring_0-30/IoU/road" in summarise_test(cfg, results)


def test_progress_lines_every_epoch_and_every_n_steps(
    tiny_dataset: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    overrides = ["trainer.max_epochs=2", "callbacks.progress.every_n_steps=1", "test=false", "logger=csv"]
    cfg = compose_train([*tiny_run_overrides("seg", tiny_dataset), *overrides])
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    with caplog.at_level(logging.INFO, logger="airfisheye_bench.progress"):
        train(cfg)
    lines = [r.getMessage() for r in caplog.records if r.name == "airfisheye_bench.progress"]
    steps = [line for line in lines if " (step " in line]
    epochs = [line for line in lines if line.startswith(("epoch 1/2: ", "epoch 2/2: "))]
    assert len(epochs) == 2 and all("train/loss" in e and "val/loss" in e and "val/mIoU" in e for e in epochs)
    assert steps and all("train/loss" in s for s in steps), lines
    assert steps[0].startswith("epoch 1/2 batch 1/")
