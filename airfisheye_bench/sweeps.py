"""Sweeps: the run directory of an Optuna search's best trial (``hparams_search=<task>_optuna``).

Hydra's Optuna sweeper prints the best trial's parameters and value and writes them to
``<sweep>/optimization_results.yaml``, but not which of the sweep's run directories it was. :class:`BestTrialReport`
(a Hydra callback of the ``hparams_search`` configs) finds it by the trial's saved configuration and reports it, with
``<sweep>/best_trial.yaml``.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.atomic import atomic_write_text

log = logging.getLogger(__name__)


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
