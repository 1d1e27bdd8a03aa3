"""Run-directory bookkeeping in process: last.ckpt, atomic writes, resume configuration, metrics.csv, run names,
and the refusal of a run in which a process would get no training batch."""

from __future__ import annotations

import datetime
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import torch
import torchvision
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf, open_dict

from airfisheye_bench.checkpointing import AtomicCheckpointIO, RunCSVLogger, share_file
from airfisheye_bench.config_checks import check_train_config
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.runs import (
    check_resume,
    config_differences,
    register_resolvers,
    resume_change,
    resume_config,
    run_name_for,
)
from airfisheye_bench.training import build, prepare_run_dir, train
from tests.helpers.configs import CONFIG_DIR, compose_train
from tests.helpers.runs import tiny_run_overrides


def tiny_cfg(root: Path, out: Path, *overrides: str):
    cfg = compose_train([*tiny_run_overrides("seg", root), "logger=csv", "test=false", *overrides])
    with open_dict(cfg):
        cfg.paths.output_dir = str(out)
    return cfg


@pytest.mark.integration
def test_last_checkpoint_holds_the_final_state(tiny_dataset: Path, tmp_path: Path) -> None:
    # The monitored metric need not improve: last.ckpt is rewritten at every epoch end regardless.
    cfg = tiny_cfg(tiny_dataset, tmp_path, "trainer.max_epochs=3", "trainer.limit_train_batches=1")
    train(cfg)
    saved = torch.load(tmp_path / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=True)
    assert (saved["epoch"], saved["global_step"]) == (2, 3)
    assert saved["AirFisheyeDataModule"] == {"train_epoch": 3, "train_batches_done": 0}
    rows = (tmp_path / "metrics.csv").read_text().splitlines()
    assert saved["metrics_csv_rows"] == len(rows) - 1  # the checkpoint covers every row logged
    assert not list(tmp_path.rglob("*.tmp"))
    # The best checkpoint is the last.ckpt written at its step (one file for both when that is the last step).
    (best,) = (tmp_path / "checkpoints").glob("epoch_*.ckpt")
    state = torch.load(best, map_location="cpu", weights_only=True)
    assert "metrics_csv_rows" in state
    last = tmp_path / "checkpoints" / "last.ckpt"
    assert (best.stat().st_ino == last.stat().st_ino) == (state["global_step"] == 3)


@pytest.fixture(scope="module")
def seg_run(tiny_runs) -> Path:
    """The session's tiny seg run (read-only)."""
    return tiny_runs("seg")


@pytest.mark.integration
def test_a_one_epoch_run_stores_its_weights_once(seg_run: Path) -> None:
    """``trainer=debug``: the best checkpoint is the last one (the same step), one file under two names."""
    folder = seg_run / "checkpoints"
    best, last = folder / "epoch_000.ckpt", folder / "last.ckpt"
    assert best.stat().st_ino == last.stat().st_ino and last.stat().st_nlink == 2


def test_a_shared_file_keeps_its_bytes_when_the_other_name_is_rewritten(tmp_path: Path) -> None:
    last, best = tmp_path / "last.ckpt", tmp_path / "epoch_000.ckpt"
    io = AtomicCheckpointIO()
    io.save_checkpoint({"step": torch.tensor(1), "rows": 2}, last)
    io.save_checkpoint({"step": torch.tensor(1)}, best)
    share_file(last, best)
    assert best.stat().st_ino == last.stat().st_ino
    assert torch.load(best, weights_only=True)["rows"] == 2
    io.save_checkpoint({"step": torch.tensor(2)}, last)  # a rename: best keeps the bytes of step 1
    assert best.stat().st_ino != last.stat().st_ino
    assert torch.load(best, weights_only=True)["step"] == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["epoch_000.ckpt", "last.ckpt"]


def test_an_interrupted_checkpoint_write_leaves_the_previous_file(tmp_path: Path, monkeypatch) -> None:
    path = tmp_path / "last.ckpt"
    io = AtomicCheckpointIO()
    io.save_checkpoint({"step": torch.tensor(1)}, path)

    def dies_halfway(obj, f, *args, **kwargs) -> None:
        Path(f).write_bytes(b"half a checkpoint")
        raise KeyboardInterrupt

    monkeypatch.setattr(torch, "save", dies_halfway)
    with pytest.raises(KeyboardInterrupt):
        io.save_checkpoint({"step": torch.tensor(2)}, path)
    monkeypatch.undo()
    assert torch.load(path, weights_only=True)["step"] == 1
    assert [p.name for p in tmp_path.iterdir()] == ["last.ckpt"]


def test_resume_changes_are_judged_key_by_key(tmp_path: Path) -> None:
    run = compose_train(["trainer.max_epochs=5"])
    with open_dict(run):
        run.paths.output_dir = str(tmp_path)
    check_resume(run, tmp_path, write=True)  # a new run records its configuration
    saved = (tmp_path / "config.yaml").read_text()

    # A resume starts from the saved, resolved configuration (the scheduler's total_iters stays the run's).
    same = OmegaConf.create(OmegaConf.to_container(run, resolve=True))
    with open_dict(same):
        same.ckpt_path = "last"
    check_resume(same, tmp_path, write=True)  # resume keys aside, identical: accepted

    unsafe = same.copy()
    with open_dict(unsafe):
        unsafe.trainer.max_epochs = 8
        unsafe.data.batch_size = 3
        unsafe.resume_overrides_ok = True  # no switch makes a change of the data acceptable
    with pytest.raises(ConfigError) as error:
        check_resume(unsafe, tmp_path, write=True)
    message = str(error.value)
    assert "\n" not in message and "data.batch_size (run has 8, now 3)" in message
    assert "max_epochs" not in message  # harmless: not what was refused
    assert (tmp_path / "config.yaml").read_text() == saved and not (tmp_path / "config.1.yaml").exists()

    unsure = same.copy()
    with open_dict(unsure):
        unsure.trainer.max_epochs = 8
        unsure.trainer.limit_train_batches = 0.5
    with pytest.raises(
        ConfigError, match=r"trainer\.limit_train_batches \(run has <absent>, now 0.5\).*resume_overrides_ok"
    ):
        check_resume(unsure, tmp_path, write=True)
    assert (tmp_path / "config.yaml").read_text() == saved

    with open_dict(unsure):
        unsure.resume_overrides_ok = True
    check_resume(unsure, tmp_path, write=True)
    assert (tmp_path / "config.1.yaml").read_text() == saved  # the previous configuration is kept
    assert OmegaConf.load(tmp_path / "config.yaml").trainer.max_epochs == 8

    harmless = unsure.copy()
    with open_dict(harmless):
        harmless.resume_overrides_ok = False
        harmless.trainer.max_epochs = 9
        harmless.data.num_workers = 0
    check_resume(harmless, tmp_path, write=True)  # more epochs, fewer workers: no switch needed
    assert OmegaConf.load(tmp_path / "config.yaml").trainer.max_epochs == 9
    assert (tmp_path / "config.2.yaml").is_file()


@pytest.mark.parametrize(
    ("key", "kind"),
    [
        ("data.preset", "unsafe"),
        ("data.root", "unsafe"),
        ("data.source", "unsafe"),
        ("data.camera.model", "unsafe"),
        ("data.camera.size", "unsafe"),
        ("model.encoder_name", "unsafe"),
        ("task.name", "unsafe"),
        ("task.module.optimizer.lr", "unsafe"),
        ("data.num_workers", "harmless"),
        ("trainer.max_epochs", "harmless"),
        ("logger.tensorboard._target_", "harmless"),
        ("callbacks.progress.every_n_steps", "harmless"),
        ("trainer.limit_train_batches", "changed"),
        ("seed", "changed"),
    ],
)
def test_resume_change_kinds(key: str, kind: str) -> None:
    assert resume_change(key) == kind


def test_a_resume_applies_only_the_keys_given_to_the_run_configuration(tmp_path: Path) -> None:
    run = compose_train(["trainer.max_epochs=5", "task=depth", "data.camera.model=kannala_brandt"])
    with open_dict(run):
        run.paths.output_dir = str(tmp_path)
    check_resume(run, tmp_path, write=True)
    overrides = ["ckpt_path=last"]
    defaults = compose_train(overrides)
    with open_dict(defaults):
        defaults.paths.output_dir = str(tmp_path)
    resumed = resume_config(defaults, overrides)
    assert resumed.trainer.max_epochs == 5 and resumed.task.name == "depth" and resumed.ckpt_path == "last"
    assert config_differences(run, resumed) == []

    overrides = ["ckpt_path=last", "trainer.max_epochs=7", "logger=none", "~callbacks.lr_monitor"]
    composed = compose_train(overrides)
    with open_dict(composed):
        composed.paths.output_dir = str(tmp_path)
    resumed = resume_config(composed, overrides)
    differences = config_differences(run, resumed)
    assert "trainer.max_epochs: run has 5, now 7" in differences
    typed = ("trainer.max_epochs", "logger", "callbacks.lr_monitor.")
    assert {next(t for t in typed if d.startswith(t)) for d in differences} == set(typed), differences
    check_resume(resumed, tmp_path, write=False)  # all harmless


def test_metrics_csv_is_continued_not_replaced(tmp_path: Path) -> None:
    (tmp_path / "metrics.csv").write_text("epoch,step,train/loss\r\n0,0,2.5\r\n")
    logger = RunCSVLogger(save_dir=tmp_path, name="", version="")
    logger.log_metrics({"train/loss": 2.0, "val/loss": 1.0}, step=1)
    logger.save()
    assert (tmp_path / "metrics.csv").read_text().splitlines() == [
        "epoch,step,train/loss,val/loss",
        "0,0,2.5,",
        ",1,2.0,1.0",
    ]


def _run_names(env: dict[str, str], count: int = 2) -> list[str]:
    """``run_name()`` as printed by ``count`` processes started together, children of this one."""
    code = "from airfisheye_bench.runs import run_name; print(run_name())"
    environ = {
        k: v for k, v in os.environ.items() if not k.startswith(("SLURM_", "TORCHELASTIC_", "WORLD_SIZE"))
    }
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env={**environ, **env}
        )
        for _ in range(count)
    ]
    return [p.communicate()[0].strip() for p in procs]


def test_run_directories_of_simultaneous_commands_differ() -> None:
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        cfg = compose(config_name="train", return_hydra_config=True)
    assert OmegaConf.to_container(cfg.hydra.run)["dir"].endswith("/${run_name:}")
    register_resolvers()
    names = _run_names({})
    assert names[0] != names[1] and all(names)


@pytest.mark.parametrize(
    "env",
    [
        {"SLURM_JOB_ID": "4471", "SLURM_STEP_ID": "0", "SLURM_NTASKS": "2", "SLURM_PROCID": "1"},
        {"TORCHELASTIC_RUN_ID": "8f2c/x", "WORLD_SIZE": "2"},
        {"TORCHELASTIC_RUN_ID": "none", "WORLD_SIZE": "2"},  # torchrun's default id: the agent's pid decides
    ],
    ids=["srun", "torchrun-rdzv-id", "torchrun-default-id"],
)
def test_the_ranks_of_one_launch_share_one_run_directory(env: dict[str, str]) -> None:
    """torchrun and srun start every rank as its own command: a per-process name gave each its own folder."""
    names = _run_names(env, count=3)
    assert len(set(names)) == 1 and "/" not in names[0], names
    assert ("slurm-4471.0" if "SLURM_JOB_ID" in env else "torchrun-") in names[0]


def test_a_single_rank_launch_keeps_the_per_process_name() -> None:
    t = datetime.datetime(2026, 11, 24, 9, 30, 5)
    assert run_name_for({"SLURM_JOB_ID": "9", "SLURM_NTASKS": "1"}, t, 5, 1).startswith(
        "2026-11-24_09-30-05_5-"
    )
    assert run_name_for({"TORCHELASTIC_RUN_ID": "a", "WORLD_SIZE": "1"}, t, 5, 1).startswith(
        "2026-11-24_09-30-05"
    )


def test_a_new_run_in_a_finished_run_directory_is_refused(tiny_dataset: Path, tmp_path: Path) -> None:
    """``hydra.run.dir=<an earlier run>`` without ``ckpt_path`` would overwrite its metrics and checkpoints."""
    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "checkpoints" / "last.ckpt").write_bytes(b"state")
    (tmp_path / "metrics.csv").write_text("epoch,step\n0,0\n")
    cfg = tiny_cfg(tiny_dataset, tmp_path)
    with pytest.raises(
        ConfigError, match=r"already holds a run \(metrics.csv, checkpoints/last.ckpt\).*ckpt_path=last"
    ):
        train(cfg)
    assert (tmp_path / "metrics.csv").read_text() == "epoch,step\n0,0\n"


@pytest.mark.parametrize(
    ("overrides", "advice"),
    [
        (["data.batch_size=16"], "lower data.batch_size to at most 8"),
        (
            ["trainer=ddp", "trainer.accelerator=cpu", "trainer.devices=2", "data.batch_size=8"],
            "trainer.devices",
        ),
    ],
)
def test_a_run_where_a_process_gets_no_training_batch_is_refused(
    overrides: list[str], advice: str, tiny_dataset: Path, tmp_path: Path
) -> None:
    cfg = tiny_cfg(tiny_dataset, tmp_path, *overrides)
    with pytest.raises(ValueError, match="no training batch") as error:
        train(cfg)
    assert advice in str(error.value)
    assert not (tmp_path / "checkpoints").exists()


def test_a_moved_run_directory_resumes_where_it_is_now(tmp_path: Path) -> None:
    old, new = tmp_path / "old", tmp_path / "new"
    run = compose_train(["trainer.max_epochs=5"])
    with open_dict(run):
        run.paths.output_dir = str(old)
    old.mkdir()
    check_resume(run, old, write=True)
    shutil.move(old, new)
    moved = run.copy()
    with open_dict(moved):
        moved.paths.output_dir = str(new)
        moved.ckpt_path = "last"
    check_resume(moved, new, write=True)  # the saved paths moved with the run: no difference
    resumed = resume_config(moved, ["ckpt_path=last"])
    assert resumed.paths.output_dir == str(new)
    assert resumed.callbacks.last_checkpoint.dirpath == str(new / "checkpoints")
    assert resumed.trainer.max_epochs == 5


@pytest.mark.parametrize("rows", [None, 2])
def test_a_resume_from_a_best_checkpoint_keeps_metrics_csv_aside(rows: int | None, tmp_path: Path) -> None:
    """A best checkpoint records no rows, or last.ckpt's when it shares its file: the later history is rewritten."""
    run = compose_train([])
    with open_dict(run):
        run.paths.output_dir = str(tmp_path)
    check_resume(run, tmp_path, write=True)
    (tmp_path / "metrics.csv").write_text("epoch,step,val/loss\n0,1,0.5\n1,3,0.4\n")
    (tmp_path / "checkpoints").mkdir()
    best = tmp_path / "checkpoints" / "epoch_000.ckpt"  # a ModelCheckpoint file
    torch.save({"state_dict": {}, "global_step": 1, **({"metrics_csv_rows": rows} if rows else {})}, best)
    stale = tmp_path / "checkpoints" / ".last.ckpt.0123456789ab.tmp"  # left by a kill during a write
    stale.write_bytes(b"half a checkpoint")
    with open_dict(run):
        run.ckpt_path = str(best)
    assert prepare_run_dir(run, tmp_path) == str(best)
    assert not (tmp_path / "metrics.csv").exists()
    assert (tmp_path / "metrics.1.csv").read_text().count("\n") == 3
    assert not stale.exists()


def test_model_checkpoint_may_not_write_last_ckpt() -> None:
    cfg = compose_train(["callbacks.model_checkpoint.save_last=true"])
    with pytest.raises(ValueError, match=r"callbacks\.last_checkpoint"):
        check_train_config(cfg)


@pytest.mark.integration
def test_a_resume_reads_no_initial_weights(tiny_dataset: Path, tmp_path: Path) -> None:
    weights = tmp_path / "resnet18.pth"
    torch.save(torchvision.models.resnet18(weights=None).state_dict(), weights)
    run = tmp_path / "run"
    cfg = tiny_cfg(tiny_dataset, run, "trainer.limit_train_batches=1", f"model.encoder_weights={weights}")
    train(cfg)
    weights.unlink()  # gone (or an ImageNet download offline): the checkpoint holds every weight anyway
    ckpt = run / "checkpoints" / "last.ckpt"
    _, module = build(cfg, resume_from=str(ckpt))
    started_from = torch.load(ckpt, map_location="cpu", weights_only=True)["hyper_parameters"]["weights"]
    assert started_from["encoder_weights"]["file"] == str(weights.resolve())
    assert module.hparams["weights"] == started_from


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.integration
def test_resuming_a_tiny_run_with_more_epochs_changes_nothing_else(
    tiny_dataset: Path, tmp_path: Path
) -> None:
    """The scenario of a new user: a tiny run on another lens, resumed with ``trainer.max_epochs=3`` (each command
    through ``train.py``'s entry function in this process: its argv, output and exit status). One training batch an
    epoch: the epochs, not the steps, are what a resume continues."""
    from tests.helpers.commands import TRAIN, assert_one_line_error
    from tests.helpers.commands import run_in_process as run_command

    run = tmp_path / "run"
    started = run_command(
        TRAIN,
        [
            *tiny_run_overrides("seg", tiny_dataset),
            "data.camera.model=kannala_brandt",
            "trainer.limit_train_batches=1",
            f"hydra.run.dir={run}",
        ],
    )
    assert started.returncode == 0, started.stderr[-3000:]
    original = OmegaConf.load(run / "config.yaml")
    before = _files(run)

    resume = ["ckpt_path=last", f"hydra.run.dir={run}"]
    # A change of what the checkpoint means is refused, whatever the switch, and nothing is written into the run.
    refused = run_command(
        TRAIN, [*resume, "trainer.max_epochs=3", "data.camera.model=equidistant", "resume_overrides_ok=true"]
    )
    message = assert_one_line_error(refused, "data.camera.model", "kannala_brandt", "equidistant")
    assert "max_epochs" not in message
    assert _files(run) == before

    # The run is finished: said in one line, nothing done.
    finished = run_command(TRAIN, resume)
    assert finished.returncode == 0, finished.stderr[-3000:]
    assert "is finished" in finished.stdout and "retest=true" in finished.stdout
    assert _files(run) == before

    continued = run_command(TRAIN, [*resume, "trainer.max_epochs=3"])
    assert continued.returncode == 0, continued.stderr[-3000:]
    resumed = OmegaConf.load(run / "config.yaml")
    assert config_differences(original, resumed) == ["trainer.max_epochs: run has 1, now 3"]
    assert (run / "config.1.yaml").read_bytes() == before["config.yaml"]
    state = torch.load(run / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=True)
    assert state["loops"]["fit_loop"]["epoch_progress"]["current"]["processed"] == 3
    for epoch in (2, 3):  # the console is not a terminal here: a line per epoch, also in train.log
        assert f"epoch {epoch}/3: train/loss" in continued.stdout
        assert f"epoch {epoch}/3: train/loss" in (run / "train.log").read_text()
