"""Leaderboard rows: ``results.json`` files found, read and validated into :class:`LeaderboardEntry`, and the
paper's published baselines."""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from airfisheye_bench.errors import MissingFileError, UserError
from airfisheye_bench.evaluation.leaderboard.lens_matrix import LensScore, lens_scores
from airfisheye_bench.io.calibration_files import camera_label
from airfisheye_bench.runs import checkpoint_run_name, run_started
from airfisheye_bench.runs.results import RESULTS_VERSION, evaluated_label, load_results, source_records
from airfisheye_bench.specs import UnknownTaskError, all_tasks, get_task

__all__ = [
    "PAPER_DATASET",
    "PAPER_SOURCE",
    "LeaderboardEntry",
    "LeaderboardError",
    "collect_results",
    "find_results",
    "is_debug_trainer",
    "load_entries",
    "load_entry",
    "paper_baselines",
]

PAPER_SOURCE = "paper (released AirFisheye)"
PAPER_DATASET = "AirFisheye (released)"


class LeaderboardError(UserError, ValueError):
    """Invalid ``results.json`` files; ``problems`` holds one ``"<path>: <what is wrong>"`` per file."""

    def __init__(self, problems: Sequence[str]) -> None:
        self.problems = list(problems)
        lines = "\n".join(f"  {p}" for p in self.problems)
        super().__init__(f"{len(self.problems)} invalid results.json file(s):\n{lines}")


@dataclass(frozen=True)
class LeaderboardEntry:
    """One row: a model evaluated on one split of one dataset.

    Attributes:
        task: ``seg``, ``depth`` or ``completion``.
        split: The evaluated split (``test``, ``val``, ...).
        model: Model name with its encoder, e.g. ``deeplabv3plus / resnet18``.
        run: The run's name: ``model.run_name`` of the results (the training run of the evaluated weights, or
            the evaluation's ``name=``); for files written before it existed, the run of the evaluated
            checkpoint, else the ``results.json`` folder name.
        dataset_name: ``dataset.name`` of the results (``dataset.yaml`` name).
        manifest_sha256: SHA-256 of the dataset's ``manifest.json``, when it had one.
        content_sha256: The dataset's content hash (SHA-256 of the decoded arrays, the same on every
            installation), when the results record it; it groups rows (the manifest hash for files without it).
        metrics: Metric values (fractions or metres); ``None`` for missing or non-finite.
        breakdown: Ring/range breakdown values, same rules.
        paper: True for the paper's published baselines.
        path: The ``results.json`` the row came from, absolute (``None`` for the paper's rows).
        predictor: What produced the predictions: ``checkpoint``, ``onnx`` or ``predictions`` (``model.source``
            of the results; empty when unknown or for the paper's rows).
        evaluated: The row's label of what was evaluated, e.g. ``checkpoint epoch_003``, ``ONNX int8, flip TTA``
            or ``predictions`` (:func:`~airfisheye_bench.runs.results.evaluated_label`; empty when unknown).
        camera: The served camera, ``<model> <W>x<H>`` (``config.camera`` of the results; empty when unknown or
            for the paper's rows).
        dataset_root: ``dataset.root`` of the results: where the dataset was on the machine that measured it
            (never shown: the leaderboard names a dataset by :attr:`dataset_label`).
        overrides: What a multirun's sweep chose for the run (``model.sweep_overrides``: ``key=value`` as on the
            command line); empty for a single run.
        debug: Trained and tested with a smoke run's trainer (``trainer=debug``: :func:`is_debug_trainer` of
            ``config.trainer``): a batch or two of training and of the test split. ``airfisheye-leaderboard`` leaves
            such rows out unless ``include_debug=true``, and marks them when it ranks them.
        lenses: The model's score on each test lens of ``airfisheye-evaluate lenses=[...]`` (``cross_lens`` of the
            results; :mod:`~airfisheye_bench.evaluation.leaderboard.lens_matrix`), empty without.
        lens_robustness: The robustness row's largest change of each metric, empty without.
    """

    task: str
    split: str
    model: str
    run: str
    dataset_name: str
    manifest_sha256: str | None = None
    content_sha256: str | None = None
    metrics: Mapping[str, float | None] = field(default_factory=dict)
    breakdown: Mapping[str, float | None] = field(default_factory=dict)
    paper: bool = False
    path: str | None = None
    predictor: str = ""
    evaluated: str = ""
    camera: str = ""
    dataset_root: str | None = None
    overrides: tuple[str, ...] = ()
    debug: bool = False
    lenses: tuple[LensScore, ...] = ()
    lens_robustness: Mapping[str, float | None] = field(default_factory=dict)

    @property
    def run_with_overrides(self) -> str:
        """The run's name, with what its sweep chose: ``<sweep>/3 (data.batch_size=8 model.encoder_name=resnet34)``.

        Example:
            >>> LeaderboardEntry("seg", "test", "m", "s/3", "d", overrides=("a.lr=0.01", "b=8")).run_with_overrides
            's/3 (a.lr=0.01 b=8)'
        """
        return f"{self.run} ({' '.join(self.overrides)})" if self.overrides else self.run

    @property
    def run_title(self) -> str:
        """The run as the tables show it: a folder name that ``train.py`` made (``2026-12-01_10-22-33_1234-ab12``)
        as the task, the model and when the run started; a name given by hand as it is; then what its sweep chose,
        and ``[trainer=debug]`` for a smoke run (:attr:`run` is the folder's name: the CSV's ``run`` column).

        Example:
            >>> LeaderboardEntry("seg", "test", "deeplabv3plus / resnet18", "2026-12-01_10-22-33_1234-ab12", "d",
            ...                  debug=True).run_title
            'seg · deeplabv3plus · 2026-12-01 10:22:33 [trainer=debug]'
            >>> LeaderboardEntry("seg", "test", "m", "s/3", "d", overrides=("b=8",)).run_title
            's/3 (b=8)'
        """
        started = None if self.paper else run_started(self.run)
        title = f"{self.task} · {self.model.split(' / ')[0]} · {started}" if started else self.run
        if self.overrides:
            title += f" ({' '.join(self.overrides)})"
        return title + " [trainer=debug]" if self.debug else title

    @property
    def source(self) -> str:
        """``paper (released AirFisheye)`` or ``ours (<dataset name>)``."""
        return PAPER_SOURCE if self.paper else f"ours ({self.dataset_name})"

    @property
    def group_key(self) -> tuple[bool, str, str, str]:
        """Rows with the same key were measured on the same data and may be ranked together."""
        return (not self.paper, self.dataset_name, self._identity(), self.split)

    def _identity(self) -> str:
        """``content <8 hex>`` (the content hash: it survives a re-encoding of the files) when known, else
        ``manifest <8 hex>`` (the manifest hash of files written before the content hash existed)."""
        if self.content_sha256:
            return f"content {self.content_sha256[:8]}"
        return f"manifest {self.manifest_sha256[:8]}" if self.manifest_sha256 else ""

    @property
    def dataset_label(self) -> str:
        """The dataset as the leaderboard names it: ``<name> (content <8 hex>)``, never by where it lies.

        Example:
            >>> LeaderboardEntry("seg", "test", "m", "r", "quickstart", content_sha256="8b04c5ff" + "0" * 56).dataset_label
            'quickstart (content 8b04c5ff)'
        """
        if self.paper:
            return PAPER_DATASET
        return f"{self.dataset_name} ({self._identity() or 'no content hash'})"

    @property
    def group_title(self) -> str:
        """Human-readable dataset identity of :attr:`group_key`."""
        if self.paper:
            return f"{PAPER_DATASET}, {self.split} split — the paper's published baselines (not re-run here)"
        return f"{self.dataset_label}, {self.split} split"


def paper_baselines() -> tuple[LeaderboardEntry, ...]:
    """The paper's baselines of every registered task (``TaskSpec.baselines``, docs/design.md "Paper baselines").

    They were measured on the real dataset's test split; metrics the paper does not report are absent ("–").

    Example:
        >>> [(e.task, e.run) for e in paper_baselines()][:2]
        [('seg', 'paper IV-A'), ('depth', 'paper Table II')]
    """
    return tuple(
        LeaderboardEntry(
            spec.name, "test", b.model, b.source, PAPER_DATASET, metrics=dict(b.metrics), paper=True
        )
        for spec in all_tasks()
        for b in spec.baselines
    )


def find_results(paths: Iterable[str | Path]) -> list[Path]:
    """Expand files and directories (searched recursively for ``results.json``) into a sorted, unique list.

    Args:
        paths: ``results.json`` files (any name is accepted when given directly) or directories. In a directory,
            the copies that an MLflow store keeps among a run's artifacts are not runs of their own.

    Returns:
        The files found, each once.

    Raises:
        FileNotFoundError: A path does not exist, or nothing was found at all.

    Example:
        >>> import tempfile, pathlib
        >>> from airfisheye_bench.evaluation import write_results
        >>> root = pathlib.Path(tempfile.mkdtemp())
        >>> _ = write_results(root / "run_a" / "results.json", "seg", "test", {"mIoU": 0.4})
        >>> [p.parent.name for p in find_results([root])]
        ['run_a']
    """
    found: dict[Path, Path] = {}  # resolved -> as given: a file reached through two paths counts once
    searched = []
    for raw in paths:
        path = Path(raw).expanduser()
        if path.is_file():
            hits = [path]
        elif path.is_dir():
            searched.append(str(path))
            hits = [
                hit
                for hit in path.rglob("results.json")
                if hit.is_file() and not _in_tracking_store(hit, path)
            ]
        else:
            raise MissingFileError(f"{path}: no such file or directory")
        for hit in hits:
            found.setdefault(hit.resolve(), hit)
    if not found:
        raise MissingFileError(f"no results.json found under {', '.join(searched) or '(no paths given)'}")
    return sorted(found.values())


def _in_tracking_store(hit: Path, root: Path) -> bool:
    """``hit`` lies in an MLflow store below ``root`` (``<run>/mlflow/``, holding ``mlflow.db``, or ``mlruns/``):
    the copy of a run's ``results.json`` that ``logger=mlflow`` keeps among the run's artifacts, not another run."""
    for folder in hit.parents:
        if folder == root:
            return False
        if folder.name in ("mlruns", "mlartifacts") or (folder / "mlflow.db").is_file():
            return True
    return False


def _number(value: Any, where: str) -> float | None:
    """A metric value as float, ``None`` for null/NaN/inf; anything else is invalid."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{where} is {value!r}, not a number or null")
    value = float(value)
    return value if math.isfinite(value) else None


def _numbers(record: Mapping[str, Any], key: str) -> dict[str, float | None]:
    values = record.get(key, {})
    if not isinstance(values, Mapping):
        raise ValueError(f"'{key}' is {type(values).__name__}, not an object")
    return {str(k): _number(v, f"{key}.{k}") for k, v in values.items()}


def _model_label(model: Mapping[str, Any]) -> str:
    config = model.get("config") if isinstance(model.get("config"), Mapping) else {}
    name = str(model.get("name") or config.get("name") or "unknown model")
    if config.get("arch"):  # smp: the architecture is what distinguishes the rows
        name = f"{name}-{config['arch']}"
    encoder = config.get("encoder_name") or config.get("encoder")
    return f"{name} / {encoder}" if encoder else name


def load_entry(path: str | Path) -> LeaderboardEntry:
    """Read and validate one ``results.json`` as a leaderboard row.

    Args:
        path: The file.

    Returns:
        The row; non-finite and null metric values become ``None``.

    Raises:
        ValueError: The file is unreadable or not a valid ``results.json``; the message starts with the path.

    Example:
        >>> import tempfile, pathlib
        >>> from airfisheye_bench.evaluation import write_results
        >>> p = write_results(pathlib.Path(tempfile.mkdtemp()) / "r1" / "results.json", "depth", "test",
        ...                   {"rmse": 4.2, "abs_rel": float("nan")}, dataset={"name": "tiny"},
        ...                   model={"name": "adabins", "config": {"encoder_name": "resnet18"}})
        >>> e = load_entry(p)
        >>> e.model, e.run, e.source, e.metrics["rmse"], e.metrics["abs_rel"]
        ('adabins / resnet18', 'r1', 'ours (tiny)', 4.2, None)
        >>> p = write_results(p, "depth", "test", {"rmse": 4.2}, model={"source": "onnx", "precision": "int8",
        ...                   "run_name": "adabins-r18"})
        >>> load_entry(p).run, load_entry(p).evaluated
        ('adabins-r18', 'ONNX int8')
    """
    path = Path(path)
    try:
        record = load_results(path)
    except TypeError as err:  # load_results assumes a JSON object
        raise ValueError(f"{path}: not a results.json object ({err})") from err
    try:
        return _entry(record, path)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err


def load_entry_rows(path: str | Path) -> list[LeaderboardEntry]:
    """The rows of one ``results.json``: its row, and for a run of several sources one more per source, ranked
    with that source's dataset (:func:`~airfisheye_bench.evaluation.results.source_records`).

    Raises:
        ValueError: as :func:`load_entry`.
    """
    first = load_entry(path)  # the file is valid; the pooled row
    try:
        return [first, *(_entry(r, Path(path)) for r in source_records(load_results(path))[1:])]
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err


def _entry(record: Mapping[str, Any], path: Path) -> LeaderboardEntry:
    version = record["version"]
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= RESULTS_VERSION:
        raise ValueError(f"unsupported version {version!r} (this reader knows 1..{RESULTS_VERSION})")
    task = record["task"]
    try:
        get_task(task)
    except UnknownTaskError as err:
        raise ValueError(str(err)) from None
    if not isinstance(record["split"], str) or not record["split"]:
        raise ValueError(f"split is {record['split']!r}, not a name")
    dataset, model = record.get("dataset") or {}, record.get("model") or {}
    if not isinstance(dataset, Mapping) or not isinstance(model, Mapping):
        raise ValueError("'dataset' and 'model' must be objects")
    manifest = dataset.get("manifest_sha256")
    lenses, robustness = lens_scores(record)
    return LeaderboardEntry(
        task=task,
        split=record["split"],
        model=_model_label(model),
        run=_run_name(model, path),
        dataset_name=str(dataset.get("name") or "unknown dataset"),
        manifest_sha256=str(manifest) if manifest else None,
        content_sha256=str(dataset["content_sha256"]) if dataset.get("content_sha256") else None,
        metrics=_numbers(record, "metrics"),
        breakdown=_numbers(record, "breakdown"),
        path=str(path.resolve()),  # absolute: shown relative to the runs= folder, whatever the working folder
        predictor=str(model.get("source") or ("checkpoint" if model.get("checkpoint") else "")),
        evaluated=evaluated_label(model),
        camera=_camera(record),
        dataset_root=str(dataset["root"]) if dataset.get("root") else None,
        overrides=_overrides(model),
        debug=is_debug_trainer(
            config.get("trainer") if isinstance(config := record.get("config"), Mapping) else None
        ),
        lenses=lenses,
        lens_robustness=robustness,
    )


def is_debug_trainer(trainer: Any) -> bool:
    """Whether a run's resolved ``config.trainer`` (``results.json``) is a smoke run's, such as ``trainer=debug``:
    ``fast_dev_run``, or training or testing limited to a count of batches (``limit_train_batches: 2``,
    ``limit_test_batches: 1``; a fraction such as ``0.5`` is an ordinary shorter epoch). Its test scored a batch or
    two of the split, so it is no result to rank.

    Example:
        >>> is_debug_trainer({"max_epochs": 1, "limit_train_batches": 2, "limit_test_batches": 1})
        True
        >>> is_debug_trainer({"max_epochs": 8}), is_debug_trainer({"limit_train_batches": 0.5}), is_debug_trainer(None)
        (False, False, False)
    """
    if not isinstance(trainer, Mapping):
        return False
    limits = (trainer.get("limit_train_batches"), trainer.get("limit_test_batches"))
    counted = any(isinstance(v, int) and not isinstance(v, bool) for v in limits)
    return counted or bool(trainer.get("fast_dev_run"))


def _overrides(model: Mapping[str, Any]) -> tuple[str, ...]:
    """``model.sweep_overrides``: a list of ``key=value`` strings, or absent."""
    chosen = model.get("sweep_overrides") or []
    if not isinstance(chosen, list) or not all(isinstance(o, str) for o in chosen):
        raise ValueError(f"model.sweep_overrides is {chosen!r}, not a list of key=value strings")
    return tuple(chosen)


def _camera(record: Mapping[str, Any]) -> str:
    """The served camera's label from ``config.camera`` (written by training and evaluation), else empty."""
    config = record.get("config")
    camera = config.get("camera") if isinstance(config, Mapping) else None
    return camera_label(camera) if isinstance(camera, Mapping) else ""


def _run_name(model: Mapping[str, Any], path: Path) -> str:
    """``model.run_name``; for files written before it, the run of the checkpoint, else the file's folder."""
    if model.get("run_name"):
        return str(model["run_name"])
    checkpoint = model.get("checkpoint") or model.get("source_checkpoint")
    return checkpoint_run_name(str(checkpoint)) if checkpoint else path.resolve().parent.name


def load_entries(files: Iterable[str | Path]) -> tuple[list[LeaderboardEntry], list[str]]:
    """Load every file, collecting problems instead of stopping at the first.

    Args:
        files: ``results.json`` paths.

    Returns:
        ``(entries, problems)``: the valid rows, and ``"<path>: <what is wrong>"`` for each invalid file.

    Example:
        >>> import tempfile, pathlib
        >>> bad = pathlib.Path(tempfile.mkdtemp()) / "results.json"
        >>> _ = bad.write_text("{")
        >>> entries, problems = load_entries([bad])
        >>> entries, problems[0].startswith(str(bad))
        ([], True)
    """
    entries, problems = [], []
    for path in files:
        try:
            entries.extend(load_entry_rows(path))
        except ValueError as err:
            problems.append(str(err))
    return entries, problems


def collect_results(paths: Iterable[str | Path], skip_invalid: bool = False) -> list[LeaderboardEntry]:
    """Find, load and validate ``results.json`` files under ``paths``.

    Args:
        paths: Files or directories (searched recursively).
        skip_invalid: Leave invalid files out with a warning instead of raising.

    Returns:
        The valid rows.

    Raises:
        FileNotFoundError: A path is missing or no ``results.json`` was found.
        LeaderboardError: Some files are invalid (all of them listed) and ``skip_invalid`` is false.

    Example:
        >>> import tempfile, pathlib
        >>> from airfisheye_bench.evaluation import write_results
        >>> root = pathlib.Path(tempfile.mkdtemp())
        >>> _ = write_results(root / "a" / "results.json", "seg", "test", {"mIoU": 0.3})
        >>> [e.metrics["mIoU"] for e in collect_results([root])]
        [0.3]
    """
    entries, problems = load_entries(find_results(paths))
    if problems and not skip_invalid:
        raise LeaderboardError(problems)
    for problem in problems:
        warnings.warn(f"skipped invalid results.json: {problem}", stacklevel=2)
    return entries
