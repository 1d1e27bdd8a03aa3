"""``TaskSpec``: everything the layers above need to know about one benchmark task, in one frozen record.

A spec is data plus a few small callables; it imports no Lightning. Models, datasets, scorers, submissions, the
leaderboard and the ONNX export look a task up by name (:func:`~airfisheye_bench.specs.get_task`) instead of keeping
their own per-task tables (docs/design.md, "Adding a task").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from airfisheye_bench.specs.formats import PredictionFormat

if TYPE_CHECKING:
    from torchmetrics import Metric

__all__ = ["Baseline", "ExportSpec", "MetricColumn", "MetricOptions", "TaskSpec"]


@dataclass(frozen=True)
class MetricOptions:
    """The evaluation settings a task metric may take; each task's factory reads the ones it uses.

    Attributes:
        class_names: Training class names in id order (classification tasks; their count is the class count).
        ignore_index: Label excluded from the metric (classification tasks).
        min_depth: Lower bound of valid ground truth in metres (range tasks).
        max_depth: Upper bound of valid ground truth in metres (range tasks; the paper evaluates up to 120 m).
    """

    class_names: tuple[str, ...] | None = None
    ignore_index: int = 255
    min_depth: float = 1e-3
    max_depth: float = 120.0


@dataclass(frozen=True)
class MetricColumn:
    """One headline metric of a task as the leaderboard shows it.

    Attributes:
        key: The metric's key in ``results.json`` (``mIoU``, ``rmse``, ...).
        label: Column title, units and percent marker included (``RMSE (m)``).
        higher_is_better: Rank descending on it.
        percent: Printed as a percentage in markdown and HTML (the paper writes "mIoU 51.2"); files keep fractions.
        decimals: Decimals printed for fractions and metres (the paper's own precision; percentages print one).
    """

    key: str
    label: str
    higher_is_better: bool = False
    percent: bool = False
    decimals: int = 3


@dataclass(frozen=True)
class Baseline:
    """A published result of the paper, measured on the real dataset's test split (docs/design.md, "Paper baselines").

    Attributes:
        model: Architecture and encoder (``DeepLabV3+ / ResNet50``).
        source: Where the paper gives it (``paper Table II``).
        metrics: ``{metric key: value}``, fractions or metres; metrics the paper does not report are absent.
    """

    model: str
    source: str
    metrics: Mapping[str, float]


@dataclass(frozen=True)
class ExportSpec:
    """What a deployed ONNX model of the task carries and how closely it must match PyTorch.

    The graph's input names are the spec's ``inputs`` and its output name the spec's ``output``.

    Attributes:
        metadata: Task-specific deployment metadata keys, without the ``airfisheye.`` prefix (their values come
            from the task module and the data config; see ``runs/deployment.py``).
        atol: Absolute parity tolerance: ``|ort - torch| <= atol + rtol * |torch|`` element-wise.
        rtol: Relative parity tolerance.
        headline: Metrics shown in the int8 quantisation report.
    """

    metadata: tuple[str, ...]
    atol: float
    rtol: float
    headline: tuple[str, ...]


@dataclass(frozen=True)
class TaskSpec:
    """One benchmark task.

    Attributes:
        name: Short name used in configs, file names and ``results.json`` (``seg``).
        title: Human-readable name (``Semantic segmentation``).
        inputs: Batch keys fed to the model, in call order; also the ONNX graph input names.
        target: Batch key of the ground truth the metric compares against.
        output: Key of the primary output in ``forward_with_aux``; also the ONNX graph output name.
        metric: Builds a fresh task metric from :class:`MetricOptions`.
        columns: Leaderboard headline metrics, in the paper's column order.
        primary_metric: Key of the metric that ranks runs and picks checkpoints; one of ``columns``.
        prediction: How a model output becomes the metric input, and how a prediction file is written, read and
            checked (labels or range maps; see :mod:`airfisheye_bench.specs.formats`).
        depth_breakdown: Also break the metrics down by ground-truth range (the target is a range in metres).
        uses_classes: Module, metric and panels take the dataset's class names and palette.
        requires: Dataset contents (``dataset.yaml`` ``contents``) the task needs beyond the images.
        export: The ONNX contract (see :class:`ExportSpec`).
        baselines: The paper's published results for the task.
        description: One line on what the task is, for ``--help`` and the docs.
    """

    name: str
    title: str
    inputs: tuple[str, ...]
    target: str
    output: str
    metric: Callable[[MetricOptions], Metric]
    columns: tuple[MetricColumn, ...]
    primary_metric: str
    prediction: PredictionFormat
    export: ExportSpec
    depth_breakdown: bool = True
    uses_classes: bool = False
    requires: tuple[str, ...] = ()
    baselines: tuple[Baseline, ...] = ()
    description: str = ""
    _columns_by_key: dict[str, MetricColumn] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(
                f"task name must be an identifier (it names files and config keys), got {self.name!r}"
            )
        if not self.inputs or self.inputs[0] != "image":
            raise ValueError(f"task {self.name}: inputs must start with 'image', got {self.inputs}")
        by_key = {c.key: c for c in self.columns}
        if self.primary_metric not in by_key:
            raise ValueError(
                f"task {self.name}: primary_metric {self.primary_metric!r} is not one of its columns {list(by_key)}"
            )
        object.__setattr__(self, "_columns_by_key", by_key)

    @property
    def higher_is_better(self) -> bool:
        """Whether a larger primary metric is better (``mode: max`` of the checkpoint callback)."""
        return self._columns_by_key[self.primary_metric].higher_is_better

    @property
    def metric_keys(self) -> tuple[str, ...]:
        """Keys of the headline columns, in order."""
        return tuple(self._columns_by_key)

    def column(self, key: str) -> MetricColumn | None:
        """The headline column of metric ``key``, or ``None`` when the task has none by that key."""
        return self._columns_by_key.get(key)

    def make_metric(
        self,
        class_names: tuple[str, ...] | list[str] | None = None,
        ignore_index: int = 255,
        min_depth: float = 1e-3,
        max_depth: float = 120.0,
    ) -> Metric:
        """A fresh metric of the task with the paper's conventions (docs/design.md, "Metrics").

        Options a task does not use are ignored (see :class:`MetricOptions`).

        Example:
            >>> from airfisheye_bench.specs import get_task
            >>> type(get_task("completion").make_metric(max_depth=80.0)).__name__
            'CompletionMetrics'
        """
        names = tuple(class_names) if class_names is not None else None
        return self.metric(MetricOptions(names, int(ignore_index), float(min_depth), float(max_depth)))
