"""``train(cfg)``: compose data, task, trainer, callbacks and loggers from a Hydra config; fit, test, write results.

The run directory (``hydra.run.dir``) ends up holding ``config.yaml`` (resolved), ``checkpoints/`` (best and
last), ``metrics.csv``, ``panels/`` and the test ``results.json`` in the leaderboard format.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import hydra
import lightning as L
import torch
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.evaluation.results import dataset_identity, write_results
from models import list_models, model_task

log = logging.getLogger(__name__)


def check_config(cfg: DictConfig) -> None:
    """Stop before any work on an inconsistent configuration, saying what to write instead."""
    task = cfg.task.name
    name = cfg.model.get("name")
    if name not in list_models():
        raise ValueError(f"model.name={name!r} is not a registered model; choose one of {list_models()}")
    if model_task(name) != task:
        raise ValueError(
            f"model={name} solves task={model_task(name)}, not task={task}; use one of "
            f"{', '.join('model=' + m for m in _model_configs(task))} or task={model_task(name)}"
        )
    if cfg.data.get("root") is None and cfg.data.get("preset") is None:
        raise ValueError(
            "data.root is unset and data.preset is null: give data.root=/path or data.preset=quickstart"
        )


def _model_configs(task: str) -> list[str]:
    folder = Path(__file__).resolve().parents[1] / "configs" / "model"
    names = [p.stem for p in sorted(folder.glob("*.yaml"))]
    return [n for n in names if (OmegaConf.load(folder / f"{n}.yaml").get("name") in list_models(task))]


def build(cfg: DictConfig) -> tuple[L.LightningDataModule, L.LightningModule]:
    """Instantiate the datamodule (data prepared and set up) and the task module."""
    datamodule = hydra.utils.instantiate(cfg.data)
    datamodule.prepare_data()
    datamodule.setup("fit")
    model_cfg = OmegaConf.to_container(cfg.model, resolve=True)
    extra: dict[str, Any] = {}
    if cfg.task.name == "seg":
        extra = {
            "class_names": datamodule.class_names,
            "palette": datamodule.palette[: datamodule.num_classes].tolist(),
        }
    module = hydra.utils.instantiate(cfg.task.module, model=model_cfg, **extra, _convert_="partial")
    if cfg.get("compile"):
        module.net = torch.compile(module.net)
    return datamodule, module


def train(cfg: DictConfig) -> dict[str, Any]:
    """Train, validate and test as configured; returns the test metrics (empty when ``test=false``)."""
    check_config(cfg)
    L.seed_everything(cfg.seed, workers=True)
    output_dir = Path(cfg.paths.output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    (output_dir / "config.yaml").write_text(OmegaConf.to_yaml(cfg, resolve=True))

    datamodule, module = build(cfg)
    # A group entry set to null (callbacks.rich_progress_bar=null) switches that callback or logger off.
    callbacks = [hydra.utils.instantiate(c) for c in (cfg.get("callbacks") or {}).values() if c is not None]
    loggers = [hydra.utils.instantiate(c) for c in (cfg.get("logger") or {}).values() if c is not None]
    trainer: L.Trainer = hydra.utils.instantiate(cfg.trainer, callbacks=callbacks, logger=loggers or False)

    ckpt_path = cfg.get("ckpt_path")
    if ckpt_path == "last":
        ckpt_path = str(output_dir / "checkpoints" / "last.ckpt")
    if cfg.get("train", True):
        trainer.fit(module, datamodule=datamodule, ckpt_path=ckpt_path)

    results: dict[str, Any] = {}
    if cfg.get("test", True):
        best = trainer.checkpoint_callback.best_model_path if trainer.checkpoint_callback else ""
        if not best:
            log.warning("no best checkpoint: testing the current weights")
        trainer.test(module, datamodule=datamodule, ckpt_path=best or None)
        results = module.test_results
        if trainer.is_global_zero:
            path = write_results(
                output_dir / "results.json",
                task=cfg.task.name,
                split=datamodule.split_names[2],
                metrics=results["metrics"],
                breakdown=results["breakdown"],
                dataset=dataset_identity(
                    datamodule.dataset_root(), datamodule.split_dataset("test").spec.name
                ),
                model={
                    "name": cfg.model.name,
                    "checkpoint": best or None,
                    "config": OmegaConf.to_container(cfg.model, resolve=True),
                    "weights": module.hparams.get("weights"),  # what training started from
                },
                config=OmegaConf.to_container(cfg, resolve=True),
            )
            log.info("test results written to %s", path)
    return results
