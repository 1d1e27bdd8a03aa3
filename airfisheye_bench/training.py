"""``train(cfg)``: compose data, task, trainer, callbacks and loggers from a Hydra config; fit, test, write results.

The run directory (``hydra.run.dir``) ends up holding ``config.yaml`` (resolved), ``checkpoints/`` (best and
last), ``metrics.csv``, ``panels/`` and the test ``results.json`` in the leaderboard format.

Resuming (``ckpt_path=last``) continues the run exactly (see README, "Resume and DDP"): its configuration must be
the run's (:func:`airfisheye_bench.runs.check_resume`), ``metrics.csv`` is cut back to the rows the checkpoint
covers and appended to, and the data loader restarts at the checkpoint's batch.
"""

from __future__ import annotations

import logging
import os
import warnings
from pathlib import Path
from typing import Any

import hydra
import lightning as L
import torch
from hydra.errors import InstantiationException
from lightning.pytorch.utilities import rank_zero_only
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.atomic import atomic_write_text, remove_stale_temporaries
from airfisheye_bench.checkpointing import METRIC_ROWS_KEY, AtomicCheckpointIO
from airfisheye_bench.config_checks import check_common_values
from airfisheye_bench.constants import config_dir
from airfisheye_bench.errors import ConfigError, MissingFileError, UserError
from airfisheye_bench.evaluation.results import dataset_identity, write_results
from airfisheye_bench.metrics import DEFAULT_RING_EDGES_DEG, ring_edges_for
from airfisheye_bench.runs import check_resume, keep_metric_rows, numbered_sibling, read_checkpoint
from airfisheye_bench.specs import UnknownTaskError, get_task
from models import list_models, model_task
from models.weights import pretrained_weights_disabled

log = logging.getLogger(__name__)

# The datamodule, not the DataLoader, restores the position in the epoch (AirFisheyeDataModule.load_state_dict).
warnings.filterwarnings(
    "ignore", message="You're resuming from a checkpoint that ended before the epoch ended"
)
# Lightning's own code builds a torch pytree LeafSpec, which this torch deprecates: nothing a user can change.
warnings.filterwarnings(
    "ignore", message=r"`isinstance\(treespec, LeafSpec\)` is deprecated", category=FutureWarning
)


class _NoAdvert(logging.Filter):
    """Drops Lightning's "💡 Tip:" advertisement of its cloud logger, printed at the start of every run."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith("💡 Tip:")


_NO_ADVERT = _NoAdvert()


def log_lightning_once() -> None:
    """Let Lightning's messages reach the console once, through the command's logging (Hydra's handlers).

    Importing ``lightning`` gives the ``lightning`` logger a console handler of its own (``INFO: <message>``); the
    messages also propagate to the root logger, where Hydra prints them and writes them to ``train.log``, so each
    was printed twice. With logging set up (root has handlers) that handler is removed; otherwise (a library
    caller) Lightning keeps its own console output.
    """
    logging.getLogger("lightning.pytorch.utilities.rank_zero").addFilter(_NO_ADVERT)
    if not logging.getLogger().handlers:
        return
    for name in ("lightning", "lightning.pytorch", "lightning.fabric"):
        logger = logging.getLogger(name)
        for handler in list(logger.handlers):
            if type(handler) is logging.StreamHandler:  # Lightning's console handler, not a file or capture
                logger.removeHandler(handler)
                logger.propagate = True  # lightning.pytorch and .fabric stop propagating when they add one


def check_config(cfg: DictConfig) -> None:
    """Stop before any work on an inconsistent configuration, saying what to write instead.

    Raises:
        ConfigError: the key, the value given and what to write instead (a ``ValueError``).
    """
    check_common_values(cfg)  # types, ranges, choices (model.name among them), files
    task = cfg.task.name
    try:
        spec = get_task(task)
    except UnknownTaskError as err:
        raise ConfigError(f"task.name: {err}") from None
    monitored = spec.column(cfg.task.get("primary_metric"))
    if monitored is not None and cfg.task.get("mode") != ("max" if monitored.higher_is_better else "min"):
        raise ConfigError(
            f"task.mode={cfg.task.get('mode')} but a higher {monitored.key} is "
            f"{'better' if monitored.higher_is_better else 'worse'}; write task.mode="
            f"{'max' if monitored.higher_is_better else 'min'}"
        )
    name = cfg.model.get("name")
    if name not in list_models():
        raise ConfigError(f"model.name={name!r} is not a registered model; choose one of {list_models()}")
    if model_task(name) != task:
        raise ConfigError(
            f"model={name} solves task={model_task(name)}, not task={task}; use one of "
            f"{', '.join('model=' + m for m in _model_configs(task))} or task={model_task(name)}"
        )
    model_checkpoint = (cfg.get("callbacks") or {}).get("model_checkpoint") or {}
    if model_checkpoint.get("save_last"):
        raise ConfigError(
            "callbacks.model_checkpoint.save_last=true is unsupported: last.ckpt belongs to callbacks.last_checkpoint, "
            "which rewrites it at every epoch end (ModelCheckpoint's would be another state)"
        )
    if model_checkpoint.get("every_n_train_steps"):
        raise ConfigError(
            "callbacks.model_checkpoint.every_n_train_steps is unsupported (that callback keeps the best checkpoints "
            "by a validation metric); use callbacks.last_checkpoint.every_n_train_steps to save last.ckpt every N steps"
        )
    if cfg.data.get("root") is None and cfg.data.get("preset") is None:
        raise ConfigError(
            "data.root is unset and data.preset is null: give data.root=/path or data.preset=quickstart"
        )


def _model_configs(task: str) -> list[str]:
    folder = config_dir() / "model"
    names = [p.stem for p in sorted(folder.glob("*.yaml"))]
    return [n for n in names if (OmegaConf.load(folder / f"{n}.yaml").get("name") in list_models(task))]


def build(cfg: DictConfig, resume_from: str | None = None) -> tuple[L.LightningDataModule, L.LightningModule]:
    """Instantiate the datamodule (data prepared and set up) and the task module.

    With ``resume_from`` (a checkpoint) the model is built without reading or fetching its initial weights
    (``encoder_weights``: the checkpoint restores every weight, and a resume must work offline); the record of
    what the run started from is taken over from the checkpoint.
    """
    try:
        datamodule = hydra.utils.instantiate(cfg.data)
    except InstantiationException as err:  # Hydra wraps the datamodule's own error: a user error stays one
        if isinstance(err.__cause__, UserError):
            raise err.__cause__ from None
        raise
    datamodule.prepare_data()
    datamodule.setup("fit")
    model_cfg = OmegaConf.to_container(cfg.model, resolve=True)
    # The incidence-angle rings reach the served lens's rim (one more ring beyond 95 deg for a wider lens).
    rings = cfg.task.module.get("ring_edges_deg") or DEFAULT_RING_EDGES_DEG
    extra: dict[str, Any] = {"ring_edges_deg": ring_edges_for(datamodule.camera.coverage_deg, rings)}
    if get_task(cfg.task.name).uses_classes:
        extra |= {
            "class_names": datamodule.class_names,
            "palette": datamodule.palette[: datamodule.num_classes].tolist(),
        }
    if resume_from is None:
        module = hydra.utils.instantiate(cfg.task.module, model=model_cfg, **extra, _convert_="partial")
    else:
        hparams = read_checkpoint(resume_from, mmap=True).get("hyper_parameters")
        extra["weights"] = (hparams or {}).get("weights")
        with pretrained_weights_disabled():
            module = hydra.utils.instantiate(cfg.task.module, model=model_cfg, **extra, _convert_="partial")
    if cfg.get("compile"):
        module.net = torch.compile(module.net)
    return datamodule, module


def check_fresh_run_dir(output_dir: Path) -> None:
    """Refuse to start a new run in a directory that holds one: it would overwrite its configuration, metrics and
    checkpoints (``hydra.run.dir=<an earlier run>`` without ``ckpt_path``, or a torchrun/srun launch id reused).

    Raises:
        ConfigError: names the directory and the two ways on.
    """
    saved = [name for name in ("metrics.csv", "checkpoints/last.ckpt") if (output_dir / name).is_file()]
    if (output_dir / "checkpoints").is_dir():
        saved += [
            f"checkpoints/{p.name}" for p in sorted((output_dir / "checkpoints").glob("epoch_*.ckpt"))[:1]
        ]
    if saved:
        raise ConfigError(
            f"hydra.run.dir={output_dir} already holds a run ({', '.join(saved)}); resume it with ckpt_path=last, "
            "or start the new run in another directory (leave hydra.run.dir unset for a fresh one)"
        )


def prepare_run_dir(cfg: DictConfig, output_dir: Path) -> str | None:
    """Set up the run directory for a new run or a resume; return the checkpoint to resume from, if any.

    A new run writes ``config.yaml`` and starts ``metrics.csv`` afresh. A resume checks the configuration against
    the run's and cuts ``metrics.csv`` back to the rows its checkpoint covers (rows a killed process logged after
    it are logged again). A checkpoint that does not record its rows (a best ``epoch_*.ckpt``: the history after
    it is rewritten) moves ``metrics.csv`` aside to ``metrics.<n>.csv`` and starts a new one. Files are written by
    the first process only (DDP starts one per device).
    """
    first = rank_zero_only.rank == 0
    output_dir.mkdir(parents=True, exist_ok=True)
    ckpt_path = cfg.get("ckpt_path")
    if ckpt_path is None:
        if first:
            check_fresh_run_dir(output_dir)
            atomic_write_text(output_dir / "config.yaml", OmegaConf.to_yaml(cfg, resolve=True))
            (output_dir / "metrics.csv").unlink(missing_ok=True)
        return None
    if ckpt_path == "last":
        ckpt_path = str(output_dir / "checkpoints" / "last.ckpt")
    if not Path(ckpt_path).is_file():
        raise MissingFileError(
            f"ckpt_path: no checkpoint at {ckpt_path}. ckpt_path=last resumes the run directory given by "
            "hydra.run.dir=<run> (it has checkpoints/last.ckpt once its first epoch ended, or every "
            "callbacks.last_checkpoint.every_n_train_steps steps); otherwise start the run without ckpt_path"
        )
    check_resume(cfg, output_dir, write=first)
    rows = read_checkpoint(ckpt_path, mmap=True).get(METRIC_ROWS_KEY)
    if first:
        remove_stale_temporaries(output_dir / "checkpoints")  # left by a kill during a checkpoint write
        metrics = output_dir / "metrics.csv"
        if rows is not None:
            keep_metric_rows(metrics, rows)
        elif metrics.is_file():
            aside = numbered_sibling(metrics)
            os.replace(metrics, aside)
            log.warning(
                "%s does not record its metrics.csv rows: the earlier rows are kept in %s", ckpt_path, aside
            )
    return ckpt_path


def check_training_batches(trainer: L.Trainer, datamodule: L.LightningDataModule) -> None:
    """Refuse to start when a process would get no training batch (it would train nothing, then test)."""
    world = trainer.num_devices * trainer.num_nodes
    if datamodule.train_batches_per_rank(world) > 0:
        return
    frames = len(datamodule.split_dataset("train"))
    per_rank = -(-frames // world)
    raise ConfigError(
        f"no training batch: the {frames} training frames split over {world} process(es) give each "
        f"{per_rank} frame(s), fewer than data.batch_size={datamodule.batch_size} (incomplete batches are dropped); "
        f"lower data.batch_size to at most {per_rank}"
        + (", use fewer processes (trainer.devices)" if world > 1 else "")
        + ", or train on a larger dataset (data.preset=quickstart or data.root=...)"
    )


def train(cfg: DictConfig) -> dict[str, Any]:
    """Train, validate and test as configured; returns the test metrics (empty when ``test=false``)."""
    check_config(cfg)
    log_lightning_once()
    L.seed_everything(cfg.seed, workers=True)
    output_dir = Path(cfg.paths.output_dir)
    ckpt_path = prepare_run_dir(cfg, output_dir)

    datamodule, module = build(cfg, resume_from=ckpt_path)
    # A group entry set to null (callbacks.rich_progress_bar=null) switches that callback or logger off.
    callbacks = [hydra.utils.instantiate(c) for c in (cfg.get("callbacks") or {}).values() if c is not None]
    loggers = [hydra.utils.instantiate(c) for c in (cfg.get("logger") or {}).values() if c is not None]
    trainer: L.Trainer = hydra.utils.instantiate(
        cfg.trainer, callbacks=callbacks, logger=loggers or False, plugins=[AtomicCheckpointIO()]
    )

    if cfg.get("train", True):
        check_training_batches(trainer, datamodule)
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
                    "source": "checkpoint",
                    "stage": "training",  # the leaderboard tells this row from evaluate.py's of the same weights
                    "run_name": output_dir.name,
                    "name": cfg.model.name,
                    "checkpoint": best or None,
                    "config": OmegaConf.to_container(cfg.model, resolve=True),
                    "weights": module.hparams.get("weights"),  # what training started from
                },
                # The served camera, as evaluation records it (the leaderboard shows it).
                config={**OmegaConf.to_container(cfg, resolve=True), "camera": datamodule.camera.to_dict()},
            )
            log.info("test results written to %s", path)
    return results
