"""Multiruns: Optuna searches (``hparams_search=<task>_optuna``), the submitit launcher (``hydra/launcher=slurm``,
run here through its local executor) and the sweep folder that ``airfisheye-leaderboard`` ranks.

The configurations are checked by composing them; the slow tests run real sweeps of tiny runs as commands.
Skipped when the extras are not installed (``pip install -e ".[sweep,slurm]"``).
"""

from __future__ import annotations

import contextlib
import csv
import importlib.util
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml
from hydra import compose, initialize_config_dir
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.cli.commands import leaderboard
from airfisheye_bench.constants import config_dir
from airfisheye_bench.evaluation.command import _sweep_overrides as evaluation_sweep_overrides
from airfisheye_bench.runs import SWEEP_NAME_ENV, register_resolvers, run_started
from airfisheye_bench.specs import get_task, task_names
from airfisheye_bench.sweeps import job_sweep_overrides, run_sweep_overrides
from tests.helpers.runs import tiny_run_overrides

ROOT = Path(__file__).resolve().parents[2]
needs_optuna = pytest.mark.skipif(
    importlib.util.find_spec("hydra_plugins.hydra_optuna_sweeper") is None,
    reason='the sweep extra: pip install -e ".[sweep]"',
)
needs_submitit = pytest.mark.skipif(
    importlib.util.find_spec("hydra_plugins.hydra_submitit_launcher") is None,
    reason='the slurm extra: pip install -e ".[slurm]"',
)


def _compose(overrides: list[str]) -> DictConfig:
    register_resolvers()
    with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3"):
        return compose(config_name="train", overrides=overrides, return_hydra_config=True)


def _train(args: list[str], cwd: Path, timeout: int = 600) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", SWEEP_NAME_ENV)}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    done = subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *args], cwd=cwd, env=env, capture_output=True, text=True,
        timeout=timeout,
    )  # fmt: skip
    assert done.returncode == 0, f"{args}:\n{done.stdout[-3000:]}\n{done.stderr[-4000:]}"
    return done


def _sweep_overrides(task: str, dataset: Path) -> list[str]:
    """A tiny run's overrides, less the batch size that the search space sets."""
    return [o for o in tiny_run_overrides(task, dataset) if not o.startswith("data.batch_size=")]


def _best_val(run_dir: Path, key: str, higher_is_better: bool) -> float:
    with (run_dir / "metrics.csv").open() as f:
        values = [float(row[key]) for row in csv.DictReader(f) if row.get(key)]
    return max(values) if higher_is_better else min(values)


# ------------------------------------------------------------------------------------------- configurations
@needs_optuna
@pytest.mark.parametrize("task", task_names())
def test_each_task_has_a_search_in_its_primary_metric_direction(task: str) -> None:
    cfg = _compose([f"hparams_search={task}_optuna"])
    spec = get_task(task)
    primary = spec.column(spec.primary_metric)
    assert cfg.task.name == task and cfg.hydra.mode.name == "MULTIRUN"
    assert cfg.optimized_metric == cfg.callbacks.model_checkpoint.monitor == f"val/{spec.primary_metric}"
    assert cfg.hydra.sweeper.direction == ("maximize" if primary.higher_is_better else "minimize")
    assert "OptunaSweeper" in cfg.hydra.sweeper._target_
    params = cfg.hydra.sweeper.params
    assert {"task.module.optimizer.lr", "data.batch_size"} <= set(params)
    for key in params:  # every searched key is one the configuration has (no misspelt key adds a new one)
        assert OmegaConf.select(cfg, key, default="<absent>") != "<absent>", key


@needs_optuna
def test_a_redirected_search_logs_optuna_and_not_alembic_through_the_command() -> None:
    """Not a terminal (captured here): Optuna's messages go through the command's logging (its own handler would
    write colour codes), and alembic's "setup plugin" lines, imported with Optuna, are below the level shown."""
    import optuna  # the sweep extra (checked above)

    from airfisheye_bench.sweeps import BestTrialReport

    cfg = _compose(["hparams_search=seg_optuna"])
    assert "best_trial" in cfg.hydra.callbacks and "run_dir" in cfg.hydra.callbacks
    for logging_config in (cfg.hydra.hydra_logging, cfg.hydra.job_logging):
        assert logging_config.loggers.alembic.level == "WARNING"
    library = optuna.logging._get_library_root_logger()
    try:
        BestTrialReport().on_multirun_start(cfg)
        assert library.propagate and not library.handlers
    finally:
        optuna.logging.enable_default_handler()
        optuna.logging.disable_propagation()


@needs_submitit
def test_the_slurm_launcher_submits_multi_node_ddp_jobs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``hydra/launcher=slurm`` with ``trainer=ddp``: the sbatch script asks for nodes x devices tasks, one GPU each.

    The script is the one submitit writes for these parameters, built the way the Hydra plugin passes them on
    (nothing is submitted: there is no SLURM here; submitit only looks for an ``srun`` on the PATH)."""
    fake = tmp_path / "bin" / "srun"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake.parent}{os.pathsep}{os.environ.get('PATH', '')}")
    import submitit  # the slurm extra (checked above)
    from hydra_plugins.hydra_submitit_launcher.config import BaseQueueConf

    overrides = ["hydra/launcher=slurm", "trainer=ddp", "trainer.devices=4", "trainer.num_nodes=2"]
    cfg = _compose([*overrides, "hydra.launcher.partition=gpu", "hydra.launcher.timeout_min=720"])
    launcher = OmegaConf.to_container(cfg.hydra.launcher, resolve=False)
    assert launcher["_target_"].endswith("SlurmLauncher")
    params = {k: OmegaConf.select(cfg, f"hydra.launcher.{k}") for k in launcher if k != "_target_"}
    assert params["nodes"] == 2 and params["tasks_per_node"] == params["gpus_per_node"] == 4
    assert cfg.trainer.strategy == "ddp" and cfg.trainer.num_nodes == 2

    params.pop("submitit_folder")
    executor = submitit.AutoExecutor(
        cluster="slurm", folder=tmp_path, slurm_max_num_timeout=params.pop("max_num_timeout")
    )
    base = set(OmegaConf.structured(BaseQueueConf).keys())  # as the plugin's launch(): the rest gets slurm_
    executor.update_parameters(**{k if k in base else f"slurm_{k}": v for k, v in params.items()})
    script = executor._executor._make_submission_file_text("python -u -m submitit.core._submit", "uid")
    for line in ("--nodes=2", "--ntasks-per-node=4", "--gpus-per-node=4", "--partition=gpu", "--time=720"):
        assert f"#SBATCH {line}" in script, script


# ------------------------------------------------------------------------------------ what a sweep chose
@contextlib.contextmanager
def _job(cfg: DictConfig) -> Iterator[None]:
    """``cfg`` (composed with its ``hydra`` node) as the running Hydra job's configuration."""
    instance = HydraConfig.instance()
    saved = instance.cfg
    instance.set_config(cfg)
    try:
        yield
    finally:
        instance.cfg = saved


def test_a_job_of_a_multirun_records_the_values_its_sweep_chose(tmp_path: Path) -> None:
    """A command's sweeps (``a,b``) are read from ``<sweep>/multirun.yaml``; its other overrides are every job's."""
    command = ["task=seg", "task.module.optimizer.lr=0.01,0.02", "data.batch_size=4,8", "trainer=debug"]
    (tmp_path / "multirun.yaml").write_text(yaml.safe_dump({"hydra": {"overrides": {"task": command}}}))
    job = ["task=seg", "task.module.optimizer.lr=0.02", "data.batch_size=4", "trainer=debug"]
    cfg = _compose([*job, "hydra.mode=MULTIRUN", f"hydra.sweep.dir={tmp_path}"])
    with _job(cfg):
        assert job_sweep_overrides() == ["task.module.optimizer.lr=0.02", "data.batch_size=4"]
    with _job(_compose(job)):  # a single run: nothing was swept
        assert job_sweep_overrides() == []
    assert job_sweep_overrides() == []  # outside a Hydra application


@needs_optuna
def test_a_trial_of_an_optuna_search_records_its_searched_values(tmp_path: Path) -> None:
    """The Optuna sweeper writes no multirun.yaml: its choices are the keys of its search space."""
    trial = ["task.module.optimizer.lr=0.0123", "model.encoder_output_stride=8", "hparams_search=seg_optuna"]
    cfg = _compose([*trial, f"hydra.sweep.dir={tmp_path}"])
    with _job(cfg):
        assert job_sweep_overrides() == trial[:2]


def test_an_evaluation_of_a_trial_carries_what_its_sweep_chose(tmp_path: Path) -> None:
    """``model.sweep_overrides`` of the run's own results.json travels to the evaluation of its weights."""
    run = tmp_path / "sweep" / "3"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.yaml").write_text("task: {name: seg}\n")
    (run / "checkpoints" / "last.ckpt").write_bytes(b"")
    chosen = ["task.module.optimizer.lr=0.01", "data.batch_size=8"]
    (run / "results.json").write_text(json.dumps({"model": {"sweep_overrides": chosen}}))
    assert run_sweep_overrides(run) == chosen
    assert evaluation_sweep_overrides({"checkpoint": str(run / "checkpoints" / "last.ckpt")}) == chosen
    assert evaluation_sweep_overrides({"source_checkpoint": str(run / "checkpoints" / "last.ckpt")}) == chosen
    assert evaluation_sweep_overrides({"onnx": str(tmp_path / "model.onnx")}) == []


# ---------------------------------------------------------------------------------------------- real sweeps
@needs_optuna
@pytest.mark.slow
def test_an_optuna_search_runs_three_trials_and_reports_the_best(tiny_dataset: Path, tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    args = ["hparams_search=seg_optuna", *_sweep_overrides("seg", tiny_dataset), "hydra.sweeper.n_trials=3"]
    _train([*args, f"hydra.sweep.dir={sweep}"], tmp_path)

    trials = sorted(p for p in sweep.iterdir() if p.is_dir() and not p.name.startswith("."))
    assert [p.name for p in trials] == ["0", "1", "2"]
    for trial in trials:  # each an ordinary run directory, its searched values in its config
        assert {"config.yaml", "results.json", "metrics.csv", "checkpoints"} <= {
            p.name for p in trial.iterdir()
        }
    configs = [OmegaConf.load(t / "config.yaml") for t in trials]
    assert len({c.task.module.optimizer.lr for c in configs}) == 3
    searched = set(_compose(["hparams_search=seg_optuna"]).hydra.sweeper.params)
    for trial, config in zip(trials, configs, strict=True):  # each trial's results.json: what Optuna chose
        chosen = dict(
            o.split("=", 1)
            for o in json.loads((trial / "results.json").read_text())["model"]["sweep_overrides"]
        )
        assert set(chosen) == searched
        assert float(chosen["task.module.optimizer.lr"]) == pytest.approx(config.task.module.optimizer.lr)
    assert all(c.data.batch_size in (4, 8) for c in configs)

    # The best trial: the highest best-validation mIoU of the three, reported with its run directory.
    scores = {t: _best_val(t, "val/mIoU", higher_is_better=True) for t in trials}
    best = yaml.safe_load((sweep / "best_trial.yaml").read_text())
    optimization = yaml.safe_load((sweep / "optimization_results.yaml").read_text())
    assert best["value"] == pytest.approx(max(scores.values())) == pytest.approx(optimization["best_value"])
    assert scores[Path(best["run_dir"])] == pytest.approx(best["value"])
    assert best["params"] == optimization["best_params"] and best["optimized_metric"] == "val/mIoU"
    chosen = OmegaConf.load(Path(best["run_dir"]) / "config.yaml")
    assert chosen.task.module.optimizer.lr == pytest.approx(best["params"]["task.module.optimizer.lr"])


@needs_submitit
@pytest.mark.slow
def test_a_submitit_multirun_writes_one_sweep_folder_that_the_leaderboard_ranks(
    tiny_dataset: Path, tmp_path: Path
) -> None:
    """Two jobs run as processes of submitit's local executor; each resolves the sweep folder in its own process,
    and both land in the one folder of the command (``${sweep_name:}``)."""
    logs = tmp_path / "logs"
    args = ["-m", "hydra/launcher=submitit_local", *tiny_run_overrides("seg", tiny_dataset), "seed=1,2"]
    _train([*args, f"paths.log_dir={logs}"], tmp_path)

    (sweep,) = (logs / "seg" / "multiruns").iterdir()
    jobs = sorted(p.name for p in sweep.iterdir() if p.is_dir() and not p.name.startswith("."))
    assert jobs == ["0", "1"]
    assert not (logs / "seg" / "runs").exists()
    for job, seed in zip(jobs, (1, 2), strict=True):
        assert OmegaConf.load(sweep / job / "config.yaml").seed == seed
        record = json.loads((sweep / job / "results.json").read_text())
        assert record["model"]["run_name"] == f"{sweep.name}/{job}"
        assert record["model"]["sweep_overrides"] == [
            f"seed={seed}"
        ]  # the sweep's value, not the command's rest
    assert len(list((sweep / ".submitit").glob("*/*_result.pkl"))) == 2  # really run by the executor

    out = tmp_path / "board"
    assert leaderboard([f"runs={sweep}", f"out={out}", "paper=false", "include_debug=true"]) == 0
    with (out / "leaderboard.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert sorted(row["run"] for row in rows) == [f"{sweep.name}/0", f"{sweep.name}/1"]
    assert sorted(row["overrides"] for row in rows) == ["seed=1", "seed=2"]
    job = f"seg · deeplabv3plus · {run_started(f'{sweep.name}/0')} (seed=1) [trainer=debug]"
    assert f"| {job} |" in (out / "leaderboard.md").read_text()
    ranks = [int(row["rank"]) for row in rows]
    assert sorted(ranks) in ([1, 2], [1, 1])  # ranked against each other (a tie shares its rank)
