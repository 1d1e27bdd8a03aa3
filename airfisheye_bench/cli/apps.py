"""``airfisheye-train`` and ``airfisheye-evaluate``: the Hydra applications over ``configs/train.yaml`` and
``configs/evaluate.yaml`` (:func:`airfisheye_bench.constants.config_dir`, so they run from any folder, installed
from a wheel too). ``python train.py`` and ``python scripts/evaluate.py`` are the same functions.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Sequence
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from airfisheye_bench.cli.overrides import check_overrides
from airfisheye_bench.cli.run_dir import remove_new_run_dir, takes_back_run_dir
from airfisheye_bench.config_checks import check_common_values, check_train_config
from airfisheye_bench.constants import config_dir
from airfisheye_bench.errors import ConfigError, report_user_errors
from airfisheye_bench.runs import register_resolvers, resume_config, run_log

register_resolvers()  # ${run_name:} in hydra.run.dir, ${sweep_name:} in hydra.sweep.dir

log = logging.getLogger(__name__)


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
    given = HydraConfig.get().overrides.task
    check_output_folder(cfg, given)
    check_common_values(cfg, skip=("data",))
    from airfisheye_bench.evaluation.command import evaluate as score  # Lightning and ONNX Runtime: seconds

    overrides = [o.lstrip("+") for o in given if o.lstrip("+").startswith("data.")]
    with run_log(Path(cfg.output_dir)) as open_log:  # evaluate.log: written with the results, not before
        score(cfg, data_overrides=overrides, before_writing=open_log)
    if Path(cfg.output_dir).absolute() != Path(HydraConfig.get().runtime.output_dir).absolute():
        remove_new_run_dir()  # out= elsewhere: the logs/eval/runs/<name> Hydra made stays empty


def check_output_folder(cfg: DictConfig, overrides: Sequence[str]) -> None:
    """``out=`` names evaluate's output folder, as it does export's, predict's and the leaderboard's; ``output_dir=``,
    its former name, still does (``output_dir: ${out}`` in ``configs/evaluate.yaml``), with a warning.

    Raises:
        ConfigError: both given, naming different folders.
    """
    keys = {o.lstrip("+~").partition("=")[0] for o in overrides}
    if "output_dir" not in keys:
        return
    if "out" in keys and Path(str(cfg.out)).absolute() != Path(str(cfg.output_dir)).absolute():
        raise ConfigError(
            f"out={cfg.out} and output_dir={cfg.output_dir} name different folders; output_dir is the former "
            "name of out: give out= alone"
        )
    log.warning("output_dir= is deprecated: it is now out=%s (the same folder)", cfg.output_dir)
