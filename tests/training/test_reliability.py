"""Slow end-to-end runs through ``python train.py``: exact resume after SIGKILL, DDP on 2 and 3 gloo ranks, and a job of
two SLURM nodes on this machine (its sampling, its metrics, its resume)."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[2]

#: A seconds-long run with last.ckpt after every step: 3 epochs of 2 steps (debug trainer), a 1.7M-parameter model.
RESUMABLE_RUN = [
    "task=seg",
    "trainer=debug",
    "trainer.max_epochs=3",
    "model.encoder_name=timm-mobilenetv3_small_minimal_100",
    "test=false",
    "callbacks.last_checkpoint.every_n_train_steps=1",
]


def run_train(
    run_dir: Path,
    dataset: Path | None,
    *overrides: str,
    kill: tuple[str, int] | None = None,
    check: bool = True,
) -> subprocess.CompletedProcess:
    """``python train.py`` (through ``tests.helpers.killer`` when ``kill`` is ``(hook, step)``); ``dataset=None``
    passes no data or run overrides (a resume re-using the run's configuration)."""
    base = tiny_overrides(dataset) if dataset is not None else []
    launcher = (
        [str(ROOT / "train.py")] if kill is None else ["-m", "tests.helpers.killer", kill[0], str(kill[1])]
    )
    cmd = [sys.executable, *launcher, *base, f"hydra.run.dir={run_dir}", *overrides]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=900, env=env)
    if check and proc.returncode != 0:
        raise AssertionError(
            f"train.py failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
        )
    return proc


def tiny_overrides(dataset: Path) -> list[str]:
    """A seconds-long run on ``dataset`` at 64², batches of 2, loaded in the main process, deterministic."""
    return [
        f"data.root={dataset}",
        "data.camera.size=64",
        "data.batch_size=2",
        "data.num_workers=0",
        "data.persistent_workers=false",
        "callbacks.rich_progress_bar=null",
        "trainer.deterministic=true",
        "trainer.log_every_n_steps=1",
    ]


def last_checkpoint(run_dir: Path) -> dict:
    return torch.load(run_dir / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=True)


def kill_and_check(
    run_dir: Path, dataset: Path | None, kill: tuple[str, int], *overrides: str
) -> dict[str, int]:
    """Run until ``kill``, check it died of SIGKILL, return where its last.ckpt stands."""
    proc = run_train(run_dir, dataset, *overrides, kill=kill, check=False)
    assert proc.returncode == -9, proc.stderr[-3000:]
    return last_checkpoint(run_dir)["AirFisheyeDataModule"]


@pytest.mark.slow
def test_runs_killed_at_random_points_resume_to_the_same_weights_and_metrics(
    tiny_dataset: Path, tmp_path: Path
) -> None:
    seed = random.randrange(2**32)
    rng = random.Random(seed)
    why = f"kill points drawn with random.Random({seed})"
    straight, killed = tmp_path / "straight", tmp_path / "killed"
    run_train(straight, tiny_dataset, *RESUMABLE_RUN)

    # Steps are numbered 1..6, epoch e trains steps 2e+1 and 2e+2. First a kill that leaves a mid-epoch last.ckpt
    # (after step 1 or 3): inside the epoch's second step, or in the validation that follows it.
    mid = rng.choice([1, 3])
    hook, step = rng.choice(
        [
            ("on_train_batch_start", mid),
            ("on_before_optimizer_step", mid),
            ("on_validation_batch_end", mid + 1),
        ]
    )
    position = kill_and_check(killed, tiny_dataset, (hook, step), *RESUMABLE_RUN)
    assert position == {"train_epoch": mid // 2, "train_batches_done": 1}, why

    # The resume (only ckpt_path=last and the run directory: the run's own configuration) is killed again, leaving
    # an end-of-epoch last.ckpt: at the next epoch's start, in its first step, or right after it.
    epoch = rng.choice([e for e in (1, 2) if 2 * e > mid])
    hook, step = rng.choice(
        [
            ("on_train_epoch_start", 2 * epoch),
            ("on_before_optimizer_step", 2 * epoch),
            ("on_train_batch_end", 2 * epoch + 1),
        ]
    )
    position = kill_and_check(killed, None, (hook, step), "ckpt_path=last")
    assert position == {"train_epoch": epoch, "train_batches_done": 0}, why

    run_train(killed, None, "ckpt_path=last")
    a, b = last_checkpoint(straight), last_checkpoint(killed)
    assert (a["epoch"], a["global_step"]) == (b["epoch"], b["global_step"]) == (2, 6), why
    assert a["state_dict"].keys() == b["state_dict"].keys()
    for key in a["state_dict"]:
        torch.testing.assert_close(
            a["state_dict"][key], b["state_dict"][key], rtol=0, atol=0, msg=f"{key}; {why}"
        )
    # Every row logged, bit for bit (the killed runs' rows after their checkpoint were logged again, once).
    assert (killed / "metrics.csv").read_text() == (straight / "metrics.csv").read_text(), why
    assert (killed / "config.yaml").read_text() == (straight / "config.yaml").read_text().replace(
        str(straight), str(killed)
    )


@pytest.mark.slow
@pytest.mark.parametrize("devices", [2, 3])
def test_ddp_matches_a_single_process_evaluation(devices: int, tiny_dataset: Path, tmp_path: Path) -> None:
    # The tiny preset's 8 training frames give each of 2 or 3 ranks 1 batch of 2; its 2 test frames leave the
    # third rank none: that rank evaluates nothing and the synced metrics are the one-process ones.
    run_dir = tmp_path / "ddp"
    run_train(
        run_dir,
        tiny_dataset,
        "task=seg",
        "trainer=ddp",
        "trainer.accelerator=cpu",
        f"trainer.devices={devices}",
        "trainer.max_epochs=1",
        "trainer.sync_batchnorm=false",
        "model.encoder_name=timm-mobilenetv3_small_minimal_100",
    )
    ddp = json.loads((run_dir / "results.json").read_text())
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
    assert ddp["metrics"].keys() == single.keys()
    for key, value in ddp["metrics"].items():
        if value is None:
            assert single[key] != single[key]  # NaN in both
        else:
            assert single[key] == pytest.approx(value, abs=1e-6), key


#: A job of two nodes with one process each, what `python train.py -m hydra/launcher=slurm trainer=ddp
#: trainer.devices=1 trainer.num_nodes=2` asks SLURM for (docs/tracking.md, "SLURM clusters"): 2 epochs of 2 steps
#: per rank (the tiny preset's 8 training frames in batches of 2 over 2 ranks), last.ckpt after every step.
TWO_NODES = [
    "task=seg",
    "trainer=ddp",
    "trainer.accelerator=cpu",
    "trainer.devices=1",
    "trainer.num_nodes=2",
    "trainer.sync_batchnorm=false",
    "trainer.max_epochs=2",
    "model.encoder_name=timm-mobilenetv3_small_minimal_100",
    "callbacks.last_checkpoint.every_n_train_steps=1",
]


def _batches(record: dict[int, list[dict]], rank: int, epoch: int) -> list[list[str]]:
    return [line["ids"] for line in record[rank] if line.get("epoch") == epoch]


def _assert_close(ddp: dict, single: dict, what: str) -> None:
    for key, value in single.items():
        if value != value:  # NaN: a class absent from the split
            assert ddp[key] != ddp[key], f"{what} {key}"
        else:
            assert ddp[key] == pytest.approx(value, abs=1e-6), f"{what} {key}"


@pytest.mark.slow
def test_a_job_of_two_slurm_nodes_samples_scores_and_resumes_as_one_process_would(
    tiny_dataset: Path, tmp_path: Path
) -> None:
    import csv

    import lightning as L

    from airfisheye_bench.io import DatasetReader
    from airfisheye_bench.tasks import SegmentationTask
    from datamodules import AirFisheyeDataModule
    from tests.helpers import cluster  # Lightning: imported by the slow tests only, not at collection

    straight, killed = tmp_path / "straight", tmp_path / "killed"
    job = [*tiny_overrides(tiny_dataset), *TWO_NODES]
    tasks = cluster.run_job([*job, f"hydra.run.dir={straight}"], tmp_path / "seen")
    assert [t.returncode for t in tasks] == [0, 0], [t.stderr[-3000:] for t in tasks]
    seen = cluster.read_record(tmp_path / "seen")

    # Lightning found the ranks and the rendezvous where SLURM's variables put them: MASTER_ADDR is the node list's
    # first host, the world size the job's tasks, the node rank SLURM_NODEID.
    setups = [line for lines in seen.values() for line in lines if "environment" in line]
    assert {(s["environment"], s["MASTER_ADDR"], s["world_size"]) for s in setups} == {
        ("SLURMEnvironment", "127.0.0.1", 2)
    }
    assert {(s["global_rank"], s["node_rank"], int(s["SLURM_NODEID"])) for s in setups} == {
        (0, 0, 0),
        (1, 1, 1),
    }
    # Every training frame once per epoch across the ranks, two batches each.
    frames = sorted(DatasetReader(tiny_dataset).split("train"))
    for epoch in (0, 1):
        batches = {rank: _batches(seen, rank, epoch) for rank in (0, 1)}
        assert [len(b) for b in batches.values()] == [2, 2], batches
        assert sorted(i for b in batches.values() for ids in b for i in ids) == frames, (epoch, batches)

    # The synced validation and test metrics are those of one process evaluating the same checkpoint.
    trainer = L.Trainer(
        accelerator="cpu", devices=1, logger=False, enable_checkpointing=False, enable_progress_bar=False
    )
    dm = AirFisheyeDataModule("seg", root=tiny_dataset, camera={"size": 64}, eval_batch_size=1, num_workers=0)
    final = SegmentationTask.load_from_checkpoint(
        straight / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=True
    )
    (single_val,) = trainer.validate(final, datamodule=dm)
    with open(straight / "metrics.csv", newline="") as f:
        last_val = [row for row in csv.DictReader(f) if row.get("val/loss")][
            -1
        ]  # the final weights' validation
    logged = {k: float(v) for k, v in last_val.items() if k.startswith("val/") and v}
    assert logged.keys() == single_val.keys()
    _assert_close(logged, single_val, "val")
    results = json.loads((straight / "results.json").read_text())
    tested = SegmentationTask.load_from_checkpoint(
        results["model"]["checkpoint"], map_location="cpu", weights_only=True
    )
    trainer.test(tested, datamodule=dm)
    assert results["metrics"].keys() == tested.test_results["metrics"].keys()
    _assert_close(
        {k: float("nan") if v is None else v for k, v in results["metrics"].items()},
        tested.test_results["metrics"],
        "test",
    )

    # Both nodes killed inside the second epoch, after its first step: the job resumed (with a new job id, as a
    # requeued job gets) continues each rank at its shard's position and ends where the uninterrupted job did.
    tasks = cluster.run_job(
        [*job, f"hydra.run.dir={killed}"], tmp_path / "killed-seen", kill=("on_train_batch_start", 3)
    )
    assert [t.returncode for t in tasks] == [-9, -9], [t.stderr[-3000:] for t in tasks]
    assert last_checkpoint(killed)["AirFisheyeDataModule"] == {"train_epoch": 1, "train_batches_done": 1}
    tasks = cluster.run_job(["ckpt_path=last", f"hydra.run.dir={killed}"], tmp_path / "resumed-seen")
    assert [t.returncode for t in tasks] == [0, 0], [t.stderr[-3000:] for t in tasks]
    resumed = cluster.read_record(tmp_path / "resumed-seen")
    for rank in (0, 1):
        assert _batches(resumed, rank, 1) == _batches(seen, rank, 1)[1:], rank
    a, b = last_checkpoint(straight), last_checkpoint(killed)
    assert (a["epoch"], a["global_step"]) == (b["epoch"], b["global_step"]) == (1, 4)
    assert a["state_dict"].keys() == b["state_dict"].keys()
    for key in a["state_dict"]:
        torch.testing.assert_close(a["state_dict"][key], b["state_dict"][key], rtol=0, atol=0, msg=key)
    assert (killed / "metrics.csv").read_text() == (straight / "metrics.csv").read_text()
    assert json.loads((killed / "results.json").read_text())["metrics"] == results["metrics"]
