"""``train(cfg)``: compose data, task, trainer, callbacks and loggers from a Hydra config; fit, test, write results.

The run directory (``hydra.run.dir``) ends up holding ``config.yaml`` (resolved), ``checkpoints/`` (best and
last), ``metrics.csv``, ``panels/`` and the test ``results.json`` in the leaderboard format; with ``logger=mlflow``
the run is also an MLflow run (:mod:`airfisheye_bench.tracking`), recorded in ``mlflow_run.json``.

Resuming (``ckpt_path=last``) continues the run exactly (see docs/training.md, "Resume and DDP"): its configuration must be
the run's (:func:`airfisheye_bench.runs.check_resume`), ``metrics.csv`` is cut back to the rows the checkpoint
covers and appended to, and the data loader restarts at the checkpoint's batch.
"""

from __future__ import annotations

import difflib
import inspect
import logging
import os
import re
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import hydra
import lightning as L
import torch
from hydra.errors import InstantiationException
from lightning.pytorch.callbacks import ProgressBar
from lightning.pytorch.utilities import rank_zero_only
from lightning.pytorch.utilities.model_summary import get_human_readable_count
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.atomic import atomic_write_text, remove_stale_temporaries
from airfisheye_bench.checkpointing import METRIC_ROWS_KEY, AtomicCheckpointIO
from airfisheye_bench.config_checks import check_train_config
from airfisheye_bench.errors import ConfigError, MissingFileError, UserError
from airfisheye_bench.metrics import DEFAULT_RING_EDGES_DEG, ring_edges_for
from airfisheye_bench.progress import console_is_terminal
from airfisheye_bench.runs import (
    check_resume,
    keep_metric_rows,
    numbered_sibling,
    read_checkpoint,
    resolve_checkpoint,
    run_label,
    run_log,
)
from airfisheye_bench.runs.quickstart_record import quick_start_line
from airfisheye_bench.runs.results import dataset_identity, format_results_table, write_results
from airfisheye_bench.specs import get_task
from airfisheye_bench.sweeps import job_sweep_overrides
from airfisheye_bench.tracking import log_run_outputs, start_tracking
from datamodules.coverage import input_coverage
from datamodules.sources import mixture_identity, resolve_sources
from models.weights import pretrained_weights_disabled

log = logging.getLogger(__name__)

# The datamodule, not the DataLoader, restores the position in the epoch (AirFisheyeDataModule.load_state_dict).
warnings.filterwarnings(
    "ignore", message="You're resuming from a checkpoint that ended before the epoch ended"
)
# A resumed run's checkpoint folder holds its checkpoints: that is what a resume is.
warnings.filterwarnings("ignore", message=r"Checkpoint directory .* exists and is not empty")
# Lightning's own code builds a torch pytree LeafSpec, which this torch deprecates: nothing a user can change.
warnings.filterwarnings(
    "ignore", message=r"`isinstance\(treespec, LeafSpec\)` is deprecated", category=FutureWarning
)
# An epoch shorter than trainer.log_every_n_steps (the tiny preset): metrics.csv still gets the epoch's values and
# the progress log its epoch line, so nothing is missing that the advice would bring back.
warnings.filterwarnings(
    "ignore", message=r"The number of training batches \(\d+\) is smaller than the logging"
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


def check_sources(data: DictConfig) -> None:
    """Resolve ``data.sources`` (a run on several datasets) without reading anything: a wrong name or setting is
    refused before the run directory is written (:func:`datamodules.sources.resolve_sources`).

    Raises:
        ConfigError: one line naming the key.
    """
    if not data.get("sources"):
        return
    values = OmegaConf.to_container(data, resolve=True)
    defaults = {
        key: values.get(key) for key in ("format", "root", "format_options", "preset", "dataset_seed")
    }
    resolve_sources(values["sources"], values.get("source_options"), defaults)


def build(cfg: DictConfig, resume_from: str | None = None) -> tuple[L.LightningDataModule, L.LightningModule]:
    """Instantiate the datamodule (data prepared and set up) and the task module.

    With ``resume_from`` (a checkpoint) the model is built without reading or fetching its initial weights
    (``encoder_weights``: the checkpoint restores every weight, and a resume must work offline); the record of
    what the run started from is taken over from the checkpoint.
    """
    datamodule = _instantiate(cfg.data)
    datamodule.prepare_data()
    datamodule.setup("fit")
    model_cfg = OmegaConf.to_container(cfg.model, resolve=True)
    # The incidence-angle rings reach the served lens's rim (one more ring beyond 95 deg for a wider lens).
    rings = cfg.task.module.get("ring_edges_deg") or DEFAULT_RING_EDGES_DEG
    names = getattr(datamodule, "source_names", [])
    coverage = (
        max(datamodule.camera_of(n).coverage_deg for n in names) if names else datamodule.camera.coverage_deg
    )
    extra: dict[str, Any] = {"ring_edges_deg": ring_edges_for(coverage, rings)}
    if names:
        extra["source_names"] = list(names)
    if get_task(cfg.task.name).uses_classes:
        extra |= {
            "class_names": datamodule.class_names,
            "palette": datamodule.palette[: datamodule.num_classes].tolist(),
        }
    if resume_from is None:
        module = _instantiate(cfg.task.module, model=model_cfg, **extra, _convert_="partial")
    else:
        hparams = read_checkpoint(resume_from, mmap=True).get("hyper_parameters")
        extra["weights"] = (hparams or {}).get("weights")
        with pretrained_weights_disabled():
            module = _instantiate(cfg.task.module, model=model_cfg, **extra, _convert_="partial")
    if cfg.get("compile"):
        module.net = torch.compile(module.net)
    return datamodule, module


def _instantiate(node: DictConfig, **kwargs: Any) -> Any:
    """``hydra.utils.instantiate``; a user error raised by the object's constructor stays one (Hydra wraps it)."""
    try:
        return hydra.utils.instantiate(node, **kwargs)
    except InstantiationException as err:
        if isinstance(err.__cause__, UserError):
            raise err.__cause__ from None
        raise


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


def check_run_dir(cfg: DictConfig, output_dir: Path) -> str | None:
    """Check, writing nothing, that the run directory can be used; return the checkpoint to resume from, if any.

    Raises:
        ConfigError: a new run in a directory that holds one, or a resume changing what the checkpoint means.
        MissingFileError: ``ckpt_path`` names no checkpoint.
    """
    ckpt_path = cfg.get("ckpt_path")
    if ckpt_path is None:
        if rank_zero_only.rank == 0:
            check_fresh_run_dir(output_dir)
        return None
    if ckpt_path == "last":
        ckpt_path = str(output_dir / "checkpoints" / "last.ckpt")
    if not Path(ckpt_path).is_file():
        raise MissingFileError(
            f"ckpt_path: no checkpoint at {ckpt_path}. ckpt_path=last resumes the run directory given by "
            "hydra.run.dir=<run> (it has checkpoints/last.ckpt once its first epoch ended, or every "
            "callbacks.last_checkpoint.every_n_train_steps steps); otherwise start the run without ckpt_path"
        )
    check_resume(cfg, output_dir, write=False)
    return ckpt_path


def finished_run(cfg: DictConfig, output_dir: Path, ckpt_path: str) -> str | None:
    """Why the run has nothing left to do, or ``None``: it has ``results.json`` and trained as configured.

    ``ckpt_path`` holds the epochs and steps trained (Lightning's loop counters); the run is finished when they
    reach ``trainer.max_epochs`` (or ``trainer.max_steps``) of ``cfg``, so a resume with more epochs continues.
    """
    if not (output_dir / "results.json").is_file():
        return None
    state = read_checkpoint(ckpt_path, mmap=True)
    epochs = (
        state.get("loops", {})
        .get("fit_loop", {})
        .get("epoch_progress", {})
        .get("current", {})
        .get("processed")
    )
    steps = state.get("global_step")
    max_epochs, max_steps = cfg.trainer.get("max_epochs"), cfg.trainer.get("max_steps")
    if epochs is not None and max_epochs is not None and max_epochs >= 0 and epochs >= max_epochs:
        done = f"{epochs} of trainer.max_epochs={max_epochs} epochs"
    elif steps is not None and max_steps is not None and max_steps > 0 and steps >= max_steps:
        done = f"{steps} of trainer.max_steps={max_steps} steps"
    else:
        return None
    return (
        f"{output_dir} is finished ({done} trained, tested in results.json): nothing to do; "
        f"retest=true tests it again, trainer.max_epochs=<more> trains on"
    )


def prepare_run_dir(cfg: DictConfig, output_dir: Path) -> str | None:
    """Set up the run directory for a new run or a resume; return the checkpoint to resume from, if any.

    A new run writes ``config.yaml`` and starts ``metrics.csv`` afresh. A resume checks the configuration against
    the run's (:func:`check_run_dir`), records an accepted change, and cuts ``metrics.csv`` back to the rows its
    ``last.ckpt`` covers (rows a killed process logged after it are logged again). Another checkpoint (a best
    ``epoch_*.ckpt``: the history after it is rewritten), or one that does not record its rows, moves
    ``metrics.csv`` aside to ``metrics.<n>.csv`` and starts a new one. Files are written by the first process only
    (DDP starts one per device).
    """
    first = rank_zero_only.rank == 0
    ckpt_path = check_run_dir(cfg, output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    if ckpt_path is None:
        if first:
            atomic_write_text(output_dir / "config.yaml", OmegaConf.to_yaml(cfg, resolve=True))
            (output_dir / "metrics.csv").unlink(missing_ok=True)
        return None
    log.info("resuming %s from %s with the run's config.yaml", output_dir, ckpt_path)
    check_resume(cfg, output_dir, write=first)
    rows = read_checkpoint(ckpt_path, mmap=True).get(METRIC_ROWS_KEY)
    if Path(ckpt_path).name != "last.ckpt":
        # A best checkpoint may share last.ckpt's bytes, rows record included (checkpointing.share_file): resuming
        # from it still rewrites the history after it, so the earlier rows are kept aside.
        rows = None
    if first:
        remove_stale_temporaries(output_dir / "checkpoints")  # left by a kill during a checkpoint write
        metrics = output_dir / "metrics.csv"
        if rows is not None:
            keep_metric_rows(metrics, rows)
        elif metrics.is_file():
            aside = numbered_sibling(metrics)
            os.replace(metrics, aside)
            log.warning(
                "%s is not where metrics.csv left off: its earlier rows are kept in %s", ckpt_path, aside
            )
    return ckpt_path


def instantiate_node(node: DictConfig, key: str, **kwargs: Any) -> Any:
    """``hydra.utils.instantiate(node, **kwargs)``; a key its class does not take is a :class:`ConfigError`.

    ``+trainer.max_epoch=1`` adds a key Hydra cannot check: the class refuses it with a ``TypeError``, which
    becomes one line naming ``trainer.max_epoch`` and the nearest argument the class takes.
    """
    try:
        return hydra.utils.instantiate(node, **kwargs)
    except InstantiationException as err:
        cause = err.__cause__
        match = (
            re.search(r"unexpected keyword argument '(\w+)'", str(cause))
            if isinstance(cause, TypeError)
            else None
        )
        if match is None:
            raise
        raise _unknown_argument(node, key, match.group(1)) from None


def check_node_arguments(node: DictConfig, key: str) -> None:
    """Refuse, without building it, a key that ``node``'s class does not take (:func:`instantiate_node`'s
    message): for the objects built only once the run directory is written (a logger opens its store when built).
    """
    taken = inspect.signature(hydra.utils.get_class(node._target_)).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in taken.values()):
        return
    for name in node:
        if not str(name).startswith("_") and name not in taken:
            raise _unknown_argument(node, key, str(name))


def _unknown_argument(node: DictConfig, key: str, name: str) -> ConfigError:
    taken = list(inspect.signature(hydra.utils.get_class(node._target_)).parameters)
    nearest = difflib.get_close_matches(name, taken, n=1)
    hint = f"did you mean {key}.{nearest[0]}?" if nearest else f"it takes {', '.join(taken)}"
    return ConfigError(f"{key}.{name}: {node._target_} takes no argument {name!r}; {hint}")


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
        + (", use fewer processes (trainer.devices, trainer.num_nodes)" if world > 1 else "")
        + ", or train on a larger dataset (data.preset=quickstart or data.root=...)"
    )


def train(cfg: DictConfig) -> dict[str, Any]:
    """Check the configuration (:func:`~airfisheye_bench.config_checks.check_train_config`), then
    :func:`train_checked`: what a library caller runs.

    Returns:
        See :func:`train_checked`.
    """
    check_train_config(cfg)
    return train_checked(cfg)


def train_checked(cfg: DictConfig) -> dict[str, Any]:
    """Train, validate and test as configured, on a configuration that
    :func:`~airfisheye_bench.config_checks.check_train_config` passed (``airfisheye-train`` checks it before it
    imports this module, so a mistyped value is answered at once, and checked once).

    Everything else that can refuse the command is checked before anything is written into the run directory. A resume
    of a finished run (:func:`finished_run`) says so and stops, unless ``retest=true``: then it tests the run's
    best checkpoint again and rewrites ``results.json``.

    Returns:
        The test results (``metrics``, ``breakdown``; none when ``test=false`` or a finished run is not re-tested)
        and ``best_val``: the best value of the monitored validation metric, ``{"val/<metric>": value}``, what a
        sweep optimises.
    """
    check_sources(cfg.data)
    output_dir = Path(cfg.paths.output_dir)
    resume_from = check_run_dir(cfg, output_dir)
    finished = finished_run(cfg, output_dir, resume_from) if resume_from is not None else None
    if finished is not None and not cfg.get("retest"):
        log.info(finished)
        return {}
    with run_log(output_dir) as open_log:
        return _train(cfg, output_dir, resume_from, open_log, retest_only=finished is not None)


def _train(
    cfg: DictConfig,
    output_dir: Path,
    resume_from: str | None,
    open_log: Callable[[], None],
    retest_only: bool,
) -> dict[str, Any]:
    log_lightning_once()
    L.seed_everything(cfg.seed, workers=True)
    # Everything that can refuse the run is checked before the run directory is written: the data (its source,
    # files and the task it can serve), the model, the callbacks and trainer, a process without a batch.
    datamodule, module = build(cfg, resume_from=resume_from)
    # A group entry set to null (callbacks.rich_progress_bar=null) switches that callback or logger off.
    groups = {"callbacks": cfg.get("callbacks") or {}, "logger": cfg.get("logger") or {}}
    nodes = {
        group: {name: c for name, c in entries.items() if c is not None} for group, entries in groups.items()
    }
    callbacks = [instantiate_node(c, f"callbacks.{name}") for name, c in nodes["callbacks"].items()]
    for name, node in nodes["logger"].items():
        check_node_arguments(node, f"logger.{name}")
    terminal: dict[str, Any] = {}
    if not console_is_terminal():
        # Redirected (a file, nohup, SLURM): ProgressLog's lines instead of a bar's frames, and the model's size in
        # one line instead of the summary table.
        callbacks = [c for c in callbacks if not isinstance(c, ProgressBar)]
        terminal = {"enable_progress_bar": False, "enable_model_summary": False}
    trainer: L.Trainer = instantiate_node(
        cfg.trainer, "trainer", callbacks=callbacks, logger=False, plugins=[AtomicCheckpointIO()], **terminal
    )
    if terminal and trainer.is_global_zero:
        log.info("model %s: %s", cfg.model.name, parameter_counts(module))
    if cfg.get("train", True) and not retest_only:
        check_training_batches(trainer, datamodule)

    ckpt_path = prepare_run_dir(cfg, output_dir)
    open_log()
    # Built now: a logger opens its store when built (MLflow creates its database in the run directory). What
    # Trainer(logger=...) does with them is this setter.
    loggers = [instantiate_node(c, f"logger.{name}") for name, c in nodes["logger"].items()]
    trainer.loggers = loggers
    if trainer.is_global_zero:
        start_tracking(loggers, OmegaConf.to_container(cfg, resolve=True))

    if cfg.get("train", True) and not retest_only:
        trainer.fit(module, datamodule=datamodule, ckpt_path=ckpt_path)

    results: dict[str, Any] = {}
    best = trainer.checkpoint_callback.best_model_path if trainer.checkpoint_callback else ""
    if cfg.get("test", True):
        if retest_only:
            best = str(resolve_checkpoint(output_dir))
            log.info("retest=true: testing %s again", best)
        if not best:
            log.warning("no best checkpoint: testing the current weights")
        trainer.test(module, datamodule=datamodule, ckpt_path=best or None, verbose=False)
        results = module.test_results
        if trainer.is_global_zero:
            dataset, sources = source_results(datamodule, results)
            dataset = dataset or dataset_identity(
                datamodule.dataset_root(), datamodule.split_dataset("test").spec.name
            )
            log.info("%s", summarise_test(cfg, results))
            path = write_results(
                output_dir / "results.json",
                task=cfg.task.name,
                split=datamodule.split_names[2],
                metrics=results["metrics"],
                breakdown=results["breakdown"],
                dataset=dataset,
                sources=sources,
                sparse_coverage=input_coverage(datamodule.split_dataset("test"), cfg.task.name),
                model={
                    "source": "checkpoint",
                    "stage": "training",  # the leaderboard tells this row from evaluate.py's of the same weights
                    "run_name": run_label(output_dir),
                    # A multirun job: what its sweep chose (the leaderboard shows it beside the run's name).
                    **({"sweep_overrides": chosen} if (chosen := job_sweep_overrides()) else {}),
                    "name": cfg.model.name,
                    "checkpoint": best or None,
                    "config": OmegaConf.to_container(cfg.model, resolve=True),
                    "weights": module.hparams.get("weights"),  # what training started from
                },
                # The served camera, as evaluation records it (the leaderboard shows it).
                config={**OmegaConf.to_container(cfg, resolve=True), "camera": datamodule.camera.to_dict()},
            )
            log.info("test results written to %s", path)
            # A quick start (python train.py task=<task> [seed=<s>]): where it falls against the README's table.
            threads = torch.get_num_threads()
            note = quick_start_line(
                cfg.task.name, results["metrics"], cfg.seed, threads, dataset.get("content_sha256")
            )
            if note:
                log.info(note)
    if trainer.is_global_zero:
        log_run_outputs(loggers, best or None)
    results = dict(results)
    # What a hyper-parameter search optimises (optimized_metric=val/<metric>): the best validation score, which
    # the test split plays no part in choosing.
    callback = trainer.checkpoint_callback
    if callback is not None and getattr(callback, "best_model_score", None) is not None:
        results["best_val"] = {str(callback.monitor): float(callback.best_model_score)}
    return results


def parameter_counts(module: torch.nn.Module) -> str:
    """``<n> parameters (<m> trainable)`` in Lightning's units (``12.3 M``).

    Example:
        >>> parameter_counts(torch.nn.Linear(1000, 10))
        '10.0 K parameters (10.0 K trainable)'
    """
    total = sum(p.numel() for p in module.parameters())
    trainable = sum(p.numel() for p in module.parameters() if p.requires_grad)
    return f"{get_human_readable_count(total)} parameters ({get_human_readable_count(trainable)} trainable)"


def source_results(
    datamodule: L.LightningDataModule, results: dict[str, Any]
) -> tuple[dict | None, dict | None]:
    """``results.json``'s ``dataset`` and ``sources`` of a run of several sources (``(None, None)`` otherwise).

    Each source gets its settings, its dataset's identity (name, root, content identity) and served camera, its
    test frames, and its metrics; ``dataset`` is the mixture's identity (:func:`mixture_identity`).
    """
    if not getattr(datamodule, "source_names", None):
        return None, None
    test = datamodule.split_dataset("test")
    roots = datamodule.source_roots()
    sources: dict[str, Any] = {}
    for src in datamodule.sources:
        part = test.datasets[src.name]
        identity = {**src.record(), **dataset_identity(roots[src.name], part.spec.name)}
        identity |= {"frames": len(part), "camera": test.source_camera(src.name).to_dict()}
        scores = results.get("sources", {}).get(src.name, {})
        sources[src.name] = {
            "dataset": identity,
            "metrics": scores.get("metrics", {}),
            "breakdown": scores.get("breakdown", {}),
        }
    return mixture_identity([s["dataset"] for s in sources.values()]), sources


def summarise_test(cfg: DictConfig, results: dict[str, Any]) -> str:
    """The test metrics as a compact table (as ``evaluate.py`` prints them); with ``print_breakdown=true`` also
    every metric per incidence-angle ring (and depth range), per class. ``results.json`` holds them all."""
    table = format_results_table(
        cfg.task.name, results["metrics"], results["breakdown"], cfg.task.primary_metric
    )
    lines = [f"test results ({cfg.task.name}, best checkpoint)", table]
    if cfg.get("print_breakdown"):
        lines += ["", "per ring and range, per class", "-" * 36]
        lines += [f"{key:<40}{value:.4f}" for key, value in results["breakdown"].items()]
    else:
        lines.append("(per ring and per class: results.json, or print_breakdown=true)")
    return "\n".join(lines)
