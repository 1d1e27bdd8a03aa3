"""Sweeps: what a multirun's sweep chose for each job, and the run directory of an Optuna search's best trial
(``hparams_search=<task>_optuna``).

A job of a multirun (``-m``, an Optuna search) is an ordinary run directory named by its number; the run keeps no
``.hydra/`` folder (``hydra.output_subdir: null``), so the values its sweep chose for it are recorded in its
``results.json`` (``model.sweep_overrides``, :func:`job_sweep_overrides`; an evaluation of the run's weights copies
them, :func:`run_sweep_overrides`), where the leaderboard shows them beside the run's name.

Hydra's Optuna sweeper prints the best trial's parameters and value and writes them to
``<sweep>/optimization_results.yaml``, but not which of the sweep's run directories it was. :class:`BestTrialReport`
(a Hydra callback of the ``hparams_search`` configs) finds it by the trial's saved configuration and reports it, with
``<sweep>/best_trial.yaml``.
"""

from __future__ import annotations

import json
import logging
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml
from hydra.core.hydra_config import HydraConfig
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.atomic import atomic_write_text

log = logging.getLogger(__name__)


def sweep_overrides(job: Sequence[str], command: Sequence[str], searched: Iterable[str]) -> list[str]:
    """The overrides of a multirun job that its sweep chose, in the job's order.

    Those of the keys the command swept (``lr=0.01,0.02``, ``range(...)``, ``choice(...)``, ``interval(...)``) or
    the sweeper searched (``hydra.sweeper.params``: an Optuna search space); the command's other overrides are
    every job's and tell nothing about this one.

    Args:
        job: The job's overrides (``hydra.overrides.task`` of the job: the command's, with each sweep's value).
        command: The command's overrides (``hydra.overrides.task`` of the multirun; empty when unknown).
        searched: The keys of the sweeper's own search space.

    Example:
        >>> sweep_overrides(["task=seg", "task.module.optimizer.lr=0.01", "data.batch_size=8"],
        ...                 ["task=seg", "task.module.optimizer.lr=0.01,0.02", "data.batch_size=4,8"], [])
        ['task.module.optimizer.lr=0.01', 'data.batch_size=8']
        >>> sweep_overrides(["model.encoder_output_stride=8", "hparams_search=seg_optuna"],
        ...                 ["hparams_search=seg_optuna"], ["model.encoder_output_stride"])
        ['model.encoder_output_stride=8']
    """
    parser = OverridesParser.create()
    swept = set(searched) | {
        o.key_or_group for o in parser.parse_overrides(list(command)) if o.is_sweep_override()
    }
    return [o.input_line for o in parser.parse_overrides(list(job)) if o.key_or_group in swept]


def job_sweep_overrides() -> list[str]:
    """:func:`sweep_overrides` of the running Hydra job; ``[]`` for a single run or outside a Hydra application.

    The command's sweeps are read from ``<sweep>/multirun.yaml``, which Hydra's basic sweeper writes before it
    launches a job (every launcher: the file is in the sweep folder); the Optuna sweeper writes none, and its
    choices are the keys of its search space (``hydra.sweeper.params``, in the job's configuration too).
    """
    if not HydraConfig.initialized():
        return []
    hydra = HydraConfig.get()
    if hydra.mode != RunMode.MULTIRUN:
        return []
    searched = list(hydra.sweeper.get("params") or {})
    saved = Path(str(hydra.sweep.dir)) / "multirun.yaml"
    command = list(OmegaConf.load(saved).hydra.overrides.task) if saved.is_file() else []
    return sweep_overrides(list(hydra.overrides.task), command, searched)


def run_sweep_overrides(run_dir: str | Path) -> list[str]:
    """What a multirun's sweep chose for a run directory: ``model.sweep_overrides`` of its ``results.json`` (written
    at the end of training); ``[]`` for a single run, or a run not tested yet.

    Example:
        >>> import tempfile
        >>> run = Path(tempfile.mkdtemp())
        >>> _ = (run / "results.json").write_text('{"model": {"sweep_overrides": ["data.batch_size=8"]}}')
        >>> run_sweep_overrides(run), run_sweep_overrides(run / "nowhere")
        (['data.batch_size=8'], [])
    """
    try:
        record = json.loads((Path(run_dir) / "results.json").read_text())
    except (OSError, ValueError):
        return []
    model = record.get("model") if isinstance(record, dict) else None
    chosen = model.get("sweep_overrides") if isinstance(model, dict) else None
    return [str(o) for o in chosen] if isinstance(chosen, list) else []


def _same(given: Any, best: Any) -> bool:
    if isinstance(given, (int, float)) and isinstance(best, (int, float)) and not isinstance(given, bool):
        return abs(float(given) - float(best)) <= 1e-12 * max(1.0, abs(float(best)))
    return given == best


def best_trial_dir(sweep_dir: str | Path, best_params: Mapping[str, Any]) -> Path | None:
    """The job folder under ``sweep_dir`` whose configuration (``<job>/config.yaml``, the resolved configuration
    every run writes) has the values of ``best_params`` (dotted keys).

    Example:
        >>> import tempfile
        >>> sweep = Path(tempfile.mkdtemp())
        >>> for job, lr in (("0", 0.01), ("1", 0.003)):
        ...     (sweep / job).mkdir(parents=True)
        ...     _ = (sweep / job / "config.yaml").write_text(f"task: {{name: seg}}\\nmodel: {{lr: {lr}}}\\n")
        >>> best_trial_dir(sweep, {"model.lr": 0.003}).name
        '1'
    """
    for saved in sorted(Path(sweep_dir).glob("*/config.yaml")):
        config = OmegaConf.load(saved)
        missing = object()
        values = {key: OmegaConf.select(config, key, default=missing) for key in best_params}
        if all(
            values[key] is not missing and _same(values[key], value) for key, value in best_params.items()
        ):
            return saved.parent
    return None


class BestTrialReport(Callback):
    """At the end of an Optuna sweep: log the best trial's run directory and write ``<sweep>/best_trial.yaml``
    (``run_dir``, ``value``, ``params``, ``optimized_metric``)."""

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        """Before the sweeper is built: Optuna's messages go through the command's logging (one format, once),
        unless standard error is a terminal (Optuna's own handler colours them there, and only there)."""
        if sys.stderr.isatty():
            return
        import optuna  # the sweep extra, present whenever this callback runs (hparams_search=...)

        optuna.logging.disable_default_handler()  # its colour codes would land in the file
        optuna.logging.enable_propagation()

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(str(config.hydra.sweep.dir))
        results_file = sweep_dir / "optimization_results.yaml"
        if not results_file.is_file():
            return
        results = yaml.safe_load(results_file.read_text()) or {}
        if "best_params" not in results:  # a multi-objective study has a Pareto front, no single best
            return
        run_dir = best_trial_dir(sweep_dir, results["best_params"])
        metric = config.get("optimized_metric")
        record = {
            "run_dir": str(run_dir) if run_dir is not None else None,
            "optimized_metric": metric,
            "value": results.get("best_value"),
            "params": results["best_params"],
        }
        atomic_write_text(sweep_dir / "best_trial.yaml", yaml.safe_dump(record, sort_keys=False))
        log.info("best trial: %s (%s=%s)", run_dir, metric, results.get("best_value"))
