"""``airfisheye-train`` and ``airfisheye-evaluate``: the Hydra applications over ``configs/train.yaml`` and
``configs/evaluate.yaml`` (:func:`airfisheye_bench.constants.config_dir`, so they run from any folder, installed
from a wheel too). ``python train.py`` and ``python scripts/evaluate.py`` are the same functions.
"""

from __future__ import annotations

import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from airfisheye_bench.cli.overrides import check_overrides
from airfisheye_bench.cli.run_dir import takes_back_run_dir
from airfisheye_bench.config_checks import check_common_values, check_train_config
from airfisheye_bench.constants import config_dir
from airfisheye_bench.errors import report_user_errors
from airfisheye_bench.runs import register_resolvers, resume_config, run_log

register_resolvers()  # ${run_name:} in hydra.run.dir, ${sweep_name:} in hydra.sweep.dir


@report_user_errors  # an unknown key: one line on stderr, exit status 2 (docs/troubleshooting.md)
def train() -> float | None:
    """``airfisheye-train task=seg|depth|completion [group=option ...] [key=value ...]``; the primary metric."""
    check_overrides("train", sys.argv[1:])  # before Hydra, whose answer to an unknown key is a "+key" hint
    return _train()


@report_user_errors
def evaluate() -> None:
    """``airfisheye-evaluate ckpt_path=... | onnx_path=... | task=... predictions=DIR [split=test]``."""
    check_overrides("evaluate", sys.argv[1:])
    _evaluate()


@hydra.main(version_base="1.3", config_path=str(config_dir()), config_name="train")
@report_user_errors  # a user error: one line on stderr, exit status 2 (docs/troubleshooting.md)
@takes_back_run_dir  # refused or failed: the run directory Hydra made for it is removed while empty
def _train(cfg: DictConfig) -> float | None:
    """The objective of a sweep: the test primary metric, or with ``optimized_metric=val/<metric>`` the best
    validation score."""
    # `ckpt_path=last hydra.run.dir=<run> [key=value ...]`: the run's saved configuration, the keys given on top.
    cfg = resume_config(cfg, HydraConfig.get().overrides.task)
    # A missing optional package or a mistyped value is answered at once, before the seconds of importing Lightning;
    # this is the config's one check (train_checked does not repeat it).
    check_train_config(cfg)
    from airfisheye_bench.training import train_checked  # Lightning: seconds to import, not needed by --help

    results = train_checked(cfg)
    if cfg.get("optimized_metric"):  # a sweep's objective: the best validation score (hparams_search)
        metric = results.get("best_val", {}).get(cfg.optimized_metric)
    else:
        metric = results.get("metrics", {}).get(cfg.task.primary_metric) if results else None
    return float(metric) if metric is not None else None


@hydra.main(version_base="1.3", config_path=str(config_dir()), config_name="evaluate")
@report_user_errors  # a user error: one line on stderr, exit status 2
@takes_back_run_dir
def _evaluate(cfg: DictConfig) -> None:
    # A mistyped value is answered before the imports below. The data group is checked by the command, once, when it
    # knows which one it serves (a checkpoint's or ONNX model's own, command-line data.* on top).
    check_common_values(cfg, skip=("data",))
    from airfisheye_bench.evaluation.command import evaluate as score  # Lightning and ONNX Runtime: seconds

    overrides = [o.lstrip("+") for o in HydraConfig.get().overrides.task if o.lstrip("+").startswith("data.")]
    with run_log(Path(cfg.output_dir)) as open_log:  # evaluate.log: written with the results, not before
        score(cfg, data_overrides=overrides, before_writing=open_log)
