"""Slow end-to-end runs through ``python train.py``: resume after SIGKILL, and 2-process DDP on gloo."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[2]


def run_train(
    run_dir: Path, dataset: Path, *overrides: str, check: bool = True
) -> subprocess.CompletedProcess:
    cmd = [
        sys.executable,
        str(ROOT / "train.py"),
        "task=seg",
        f"data.root={dataset}",
        "data.camera.size=64",
        "data.batch_size=2",
        "data.num_workers=0",
        "data.persistent_workers=false",
        "callbacks.rich_progress_bar=null",
        "trainer.deterministic=true",
        "trainer.log_every_n_steps=1",
        f"hydra.run.dir={run_dir}",
        *overrides,
    ]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=900)
    if check and proc.returncode != 0:
        raise AssertionError(
            f"train.py failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
        )
    return proc


def final_state(run_dir: Path) -> dict[str, torch.Tensor]:
    return torch.load(run_dir / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=True)[
        "state_dict"
    ]


@pytest.mark.slow
def test_a_killed_run_resumes_to_the_same_weights_and_metrics(tiny_dataset: Path, tmp_path: Path) -> None:
    epochs = ["trainer.max_epochs=3"]
    straight = tmp_path / "straight"
    run_train(straight, tiny_dataset, *epochs)

    killed = tmp_path / "killed"
    # SIGKILL in the middle of the second epoch (3 steps per epoch): nothing is flushed or saved.
    proc = run_train(
        killed,
        tiny_dataset,
        *epochs,
        "+callbacks.kill._target_=tests.training.killer.KillAtStep",
        "+callbacks.kill.step=4",
        check=False,
    )
    assert proc.returncode == -9
    saved = torch.load(killed / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=True)
    assert saved["epoch"] == 0 and not (killed / "results.json").exists()

    run_train(killed, tiny_dataset, *epochs, "ckpt_path=last")
    a, b = final_state(straight), final_state(killed)
    assert a.keys() == b.keys()
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=0, msg=key)
    ra = json.loads((straight / "results.json").read_text())["metrics"]
    rb = json.loads((killed / "results.json").read_text())["metrics"]
    assert ra == rb


@pytest.mark.slow
def test_ddp_on_two_processes_matches_a_single_process_evaluation(tiny_dataset: Path, tmp_path: Path) -> None:
    run_dir = tmp_path / "ddp"
    run_train(
        run_dir,
        tiny_dataset,
        "trainer=ddp",
        "trainer.accelerator=cpu",
        "trainer.devices=2",
        "trainer.max_epochs=1",
        "trainer.sync_batchnorm=false",
    )
    ddp = json.loads((run_dir / "results.json").read_text())
    # The same checkpoint evaluated by one process gives the same pooled metrics.
    import lightning as L

    from airfisheye_bench.tasks import SegmentationTask
    from datamodules import AirFisheyeDataModule

    ckpt = ddp["model"]["checkpoint"] or str(run_dir / "checkpoints" / "last.ckpt")
    module = SegmentationTask.load_from_checkpoint(ckpt, map_location="cpu", weights_only=True)
    dm = AirFisheyeDataModule("seg", root=tiny_dataset, camera={"size": 64}, eval_batch_size=1)
    trainer = L.Trainer(
        accelerator="cpu", devices=1, logger=False, enable_checkpointing=False, enable_progress_bar=False
    )
    trainer.test(module, datamodule=dm)
    single = module.test_results["metrics"]
    for key, value in ddp["metrics"].items():
        if value is None:
            assert single[key] != single[key]  # NaN in both
        else:
            assert single[key] == pytest.approx(value, abs=1e-6), key
