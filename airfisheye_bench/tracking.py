"""MLflow tracking of a run (``logger=mlflow``; ``pip install -e ".[mlflow]"``).

:class:`RunMLFlowLogger` is Lightning's ``MLFlowLogger`` with the run directory's conventions: by default a local
SQLite store under the run directory (``<run>/mlflow/mlflow.db``, artifacts beside it; MLflow 3 refuses a plain
folder store), or the server of ``logger.mlflow.tracking_uri``. Lightning logs every metric through it; training
adds the resolved configuration as parameters (:func:`start_tracking`) and, once tested, ``results.json``,
``config.yaml``, the panels and the best checkpoint's path (:func:`log_run_outputs`). The run's id and store are
recorded in ``<run>/mlflow_run.json``, so that a resume continues the same MLflow run and ``airfisheye-evaluate``
/ ``airfisheye-export`` with ``mlflow_run=auto`` log to it (:func:`log_to_run`).

``mlflow`` is imported only where it is used: the rest of the project runs without it (an optional extra), and
a configuration that needs it is refused up front (:data:`airfisheye_bench.config_checks.EXTRAS`).
"""

from __future__ import annotations

import json
import logging
import math
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from lightning.pytorch.loggers import MLFlowLogger

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.errors import ConfigError, MissingFileError
from airfisheye_bench.runs import flatten, run_label

log = logging.getLogger(__name__)

#: The file in a run directory naming its MLflow run: ``{"tracking_uri": ..., "experiment_id": ..., "run_id": ...}``.
RUN_RECORD = "mlflow_run.json"

# MLflow's limits: a parameter value of at most 6000 characters, at most 100 parameters per logging call.
_PARAM_VALUE_CHARS = 6000
_BATCH = 100


def local_store(run_dir: str | os.PathLike) -> tuple[str, str]:
    """The default store of a run: its SQLite database URI and artifact folder under ``<run>/mlflow``.

    Example:
        >>> local_store("/logs/seg/runs/r1")
        ('sqlite:////logs/seg/runs/r1/mlflow/mlflow.db', '/logs/seg/runs/r1/mlflow/artifacts')
    """
    folder = Path(run_dir).absolute() / "mlflow"
    return f"sqlite:///{folder / 'mlflow.db'}", str(folder / "artifacts")


def read_run_record(run_dir: str | os.PathLike) -> dict[str, str] | None:
    """The MLflow run a run directory logged to (:data:`RUN_RECORD`), or ``None`` when it has none."""
    path = Path(run_dir) / RUN_RECORD
    if not path.is_file():
        return None
    try:
        record = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return record if isinstance(record, dict) and record.get("run_id") else None


#: The runs' own stores chosen in this process. MLflow puts the store in use into ``$MLFLOW_TRACKING_URI`` (for its
#: subprocesses): the next job of a multirun run in this process (an Optuna search) would take the previous job's
#: store for the user's choice and log into it.
_LOCAL_STORES: set[str] = set()


def choose_store(
    save_dir: str | os.PathLike, tracking_uri: str | None = None, artifact_location: str | None = None
) -> tuple[str, str | None]:
    """The store a run logs to and where a new experiment keeps its artifacts: ``(tracking URI, location)``.

    ``tracking_uri`` when given, else ``$MLFLOW_TRACKING_URI`` when the user set it, else the run's own SQLite store
    (:func:`local_store`, its artifacts beside it unless ``artifact_location`` says otherwise; its folder is created:
    SQLite creates the database, not its folder). A store chosen this way is remembered (:data:`_LOCAL_STORES`):
    MLflow exports it as ``$MLFLOW_TRACKING_URI``, which the next run in this process must not take for the user's
    choice.
    """
    from_env = os.environ.get("MLFLOW_TRACKING_URI")
    tracking_uri = tracking_uri or (from_env if from_env not in _LOCAL_STORES else None)
    if tracking_uri is None:
        tracking_uri, default_artifacts = local_store(save_dir)
        _LOCAL_STORES.add(tracking_uri)
        artifact_location = artifact_location or default_artifacts
        Path(default_artifacts).parent.mkdir(parents=True, exist_ok=True)
    return tracking_uri, artifact_location


class RunMLFlowLogger(MLFlowLogger):
    """``MLFlowLogger`` storing into the run directory unless given a tracking URI; resumes the run's MLflow run.

    Args:
        save_dir: The run directory.
        experiment_name: The MLflow experiment (created when missing).
        run_name: The MLflow run's name; ``None``: the run directory's (:func:`~airfisheye_bench.runs.run_label`).
        tracking_uri: ``http://host:port`` of an ``mlflow server``, a database URI, or ``None``:
            ``$MLFLOW_TRACKING_URI`` when set, else the run's own SQLite store (:func:`local_store`).
        artifact_location: Where a new experiment keeps artifacts; ``None``: beside a local store, the server's
            choice otherwise.
        tags: Tags of the MLflow run.
    """

    def __init__(
        self,
        save_dir: str,
        experiment_name: str,
        run_name: str | None = None,
        tracking_uri: str | None = None,
        artifact_location: str | None = None,
        tags: Mapping[str, Any] | None = None,
    ) -> None:
        # "Creating initial MLflow database tables...", "Updating database tables": every run's own new store.
        logging.getLogger("mlflow.store.db.utils").setLevel(logging.WARNING)
        tracking_uri, artifact_location = choose_store(save_dir, tracking_uri, artifact_location)
        record = read_run_record(save_dir)
        # A resumed run directory continues its MLflow run (the same store), instead of starting a second one.
        run_id = record["run_id"] if record and record.get("tracking_uri") == tracking_uri else None
        super().__init__(
            experiment_name=experiment_name,
            run_name=run_name or run_label(save_dir),
            tracking_uri=tracking_uri,
            artifact_location=artifact_location,
            tags=dict(tags) if tags else None,
            run_id=run_id,
            log_model=False,  # checkpoints stay in the run directory; the best one's path is a tag
        )
        self.run_dir = Path(save_dir)


def _mlflow_loggers(loggers: Iterable[Any]) -> list[RunMLFlowLogger]:
    return [lg for lg in loggers if isinstance(lg, RunMLFlowLogger)]


def start_tracking(loggers: Iterable[Any], config: Mapping[str, Any]) -> None:
    """Log the resolved configuration as the MLflow run's parameters and record the run in the run directory.

    Parameters are flattened to dotted keys (``task.module.optimizer.lr``). Call on the first process only.
    """
    for logger in _mlflow_loggers(loggers):
        client, run_id = logger.experiment, logger.run_id
        _log_params(client, run_id, flatten(dict(config)))
        record = {
            "tracking_uri": logger._tracking_uri,
            "experiment_id": logger.experiment_id,
            "run_id": run_id,
        }
        atomic_write_text(logger.run_dir / RUN_RECORD, json.dumps(record, indent=2) + "\n")
        log.info("MLflow run %s in %s", run_id, record["tracking_uri"])


def _log_params(client: Any, run_id: str, params: Mapping[str, Any]) -> None:
    from mlflow.entities import Param  # optional dependency (the mlflow extra)
    from mlflow.exceptions import MlflowException  # optional dependency (the mlflow extra)

    items = [Param(key, str(value)[:_PARAM_VALUE_CHARS]) for key, value in sorted(params.items())]
    for start in range(0, len(items), _BATCH):
        try:
            client.log_batch(run_id, params=items[start : start + _BATCH])
        except (
            MlflowException
        ) as err:  # a resume with resume_overrides_ok: MLflow keeps a parameter's first value
            log.warning("MLflow kept the run's earlier parameters: %s", str(err).splitlines()[0])


def log_run_outputs(loggers: Iterable[Any], best_checkpoint: str | None) -> None:
    """After testing: ``results.json``, ``config.yaml`` and ``panels/`` as artifacts, the best checkpoint's path
    as the tag ``best_checkpoint``. Call on the first process only."""
    for logger in _mlflow_loggers(loggers):
        client, run_id = logger.experiment, logger.run_id
        for name in ("results.json", "config.yaml"):
            if (logger.run_dir / name).is_file():
                client.log_artifact(run_id, str(logger.run_dir / name))
        if (logger.run_dir / "panels").is_dir():
            client.log_artifacts(run_id, str(logger.run_dir / "panels"), "panels")
        if best_checkpoint:
            client.set_tag(run_id, "best_checkpoint", str(Path(best_checkpoint).absolute()))


def resolve_run(
    mlflow_run: str, run_dir: str | os.PathLike | None, tracking_uri: str | None
) -> tuple[str, str]:
    """The ``(tracking URI, run id)`` that ``mlflow_run=`` names for ``airfisheye-evaluate`` / ``-export``.

    Args:
        mlflow_run: ``auto`` (the run recorded in ``run_dir``) or an MLflow run id.
        run_dir: The training run directory of the evaluated weights, when known.
        tracking_uri: ``mlflow_tracking_uri=``; ``None``: the recorded one, else ``$MLFLOW_TRACKING_URI``.

    Raises:
        MissingFileError: ``auto`` but the run directory records no MLflow run.
        ConfigError: no tracking URI is known for an explicit run id.

    Example:
        >>> resolve_run("0a1b2c", None, "http://127.0.0.1:5000")
        ('http://127.0.0.1:5000', '0a1b2c')
    """
    record = read_run_record(run_dir) if run_dir is not None else None
    if mlflow_run == "auto":
        if record is None:
            where = f"{Path(run_dir) / RUN_RECORD}" if run_dir is not None else "the evaluated model's run"
            raise MissingFileError(
                f"mlflow_run=auto: no MLflow run recorded in {where} (the run was not trained with "
                "logger=mlflow); give mlflow_run=<run id> and mlflow_tracking_uri=<uri>"
            )
        return tracking_uri or record["tracking_uri"], record["run_id"]
    uri = tracking_uri or (record or {}).get("tracking_uri") or os.environ.get("MLFLOW_TRACKING_URI")
    if not uri:
        raise ConfigError(
            f"mlflow_run={mlflow_run}: no tracking URI known; give mlflow_tracking_uri=<uri> "
            "(or set MLFLOW_TRACKING_URI)"
        )
    return uri, mlflow_run


def log_to_run(
    tracking_uri: str,
    run_id: str,
    metrics: Mapping[str, float | None] | None = None,
    artifacts: Mapping[str, str | os.PathLike] | None = None,
    tags: Mapping[str, str] | None = None,
) -> None:
    """Log finite metrics, files or folders (artifact path -> local path) and tags to an existing MLflow run.

    Raises:
        ConfigError: the run does not exist in that store.
    """
    from mlflow.exceptions import MlflowException  # optional dependency (the mlflow extra)
    from mlflow.tracking import MlflowClient  # optional dependency (the mlflow extra)

    client = MlflowClient(tracking_uri=tracking_uri)
    try:
        client.get_run(run_id)
    except MlflowException as err:
        raise ConfigError(
            f"mlflow_run={run_id}: no such run in {tracking_uri} ({str(err).splitlines()[0]})"
        ) from None
    for key, value in (metrics or {}).items():
        if value is not None and math.isfinite(value):
            client.log_metric(run_id, key, float(value))
    for artifact_path, local in (artifacts or {}).items():
        local = Path(local)
        folder, _, name = artifact_path.rpartition("/")
        if local.is_dir():
            client.log_artifacts(run_id, str(local), artifact_path)
        elif local.is_file():
            if name != local.name:
                raise ValueError(f"artifact path {artifact_path} must end in the file's name {local.name}")
            client.log_artifact(run_id, str(local), folder or None)
    for key, value in (tags or {}).items():
        client.set_tag(run_id, key, value)
