"""The torchmetrics internals that ``airfisheye_bench/metrics/_torchmetrics_compat.py`` relies on still hold.

Each check names the installed torchmetrics version when it fails: a new torchmetrics that renamed or changed one
of these private attributes breaks the binned metrics and worker-side scoring silently otherwise (a result
cached before the new states, or states that do not add up).
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import pytest
import torch
import torchmetrics
from torchmetrics import Metric
from torchmetrics.utilities.data import dim_zero_cat, dim_zero_sum

from airfisheye_bench.metrics import BinnedMetrics, DepthMetrics, SegmentationMetrics
from airfisheye_bench.metrics._torchmetrics_compat import (
    record_update,
    state_names,
    state_reduction,
    sums_every_state,
)

INCOMPATIBLE = (
    f"torchmetrics {torchmetrics.__version__} is incompatible with metrics/_torchmetrics_compat.py: "
)


class _Probe(Metric):
    """Two summed states and one concatenated one, the kinds the project's metrics declare."""

    full_state_update = False

    def __init__(self) -> None:
        super().__init__()
        self.add_state("total", default=torch.tensor(0.0), dist_reduce_fx="sum")
        self.add_state("count", default=torch.tensor(0), dist_reduce_fx="sum")
        self.add_state("values", default=[], dist_reduce_fx="cat")

    def update(self, x: torch.Tensor) -> None:
        self.total += x.sum()
        self.count += x.numel()

    def compute(self) -> torch.Tensor:
        return self.total / self.count


def test_state_names_are_the_declared_states_in_order() -> None:
    assert state_names(_Probe()) == ("total", "count", "values"), INCOMPATIBLE + "Metric._defaults changed"


def test_state_reductions_are_the_declared_functions() -> None:
    probe = _Probe()
    assert state_reduction(probe, "total") is dim_zero_sum, INCOMPATIBLE + "Metric._reductions changed"
    assert state_reduction(probe, "values") is dim_zero_cat, INCOMPATIBLE + "Metric._reductions changed"
    assert not sums_every_state(probe)


def test_record_update_marks_directly_filled_states_as_updated() -> None:
    probe = _Probe()
    probe.total += 6.0
    probe.count += 3
    record_update(probe)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # "compute called before update" would mean _update_count is not read
        assert float(probe.compute()) == 2.0, (
            INCOMPATIBLE + "Metric._update_count is not what compute() checks"
        )


def test_record_update_drops_the_cached_result() -> None:
    probe = _Probe()
    probe.update(torch.tensor([1.0, 3.0]))
    assert float(probe.compute()) == 2.0
    probe.total += 8.0
    probe.count += 2
    record_update(probe)
    assert float(probe.compute()) == 3.0, (
        INCOMPATIBLE + "Metric._computed no longer caches compute()'s result"
    )


@pytest.mark.parametrize(
    "metric",
    [SegmentationMetrics(3), DepthMetrics(), BinnedMetrics(DepthMetrics, edges=(0, 45, 95), key="theta")],
    ids=["seg", "depth", "binned"],
)
def test_the_project_metrics_sum_every_state(metric: Metric) -> None:
    """Worker-side scoring adds partial states up: every state of every metric must be a sum."""
    stateful = [m for m in metric.modules() if isinstance(m, Metric) and state_names(m)]
    assert stateful and all(sums_every_state(m) for m in stateful)


def test_a_missing_attribute_names_the_version() -> None:
    probe = _Probe()
    del probe._defaults
    with pytest.raises(
        RuntimeError, match=rf"torchmetrics {torchmetrics.__version__} has no Metric\._defaults"
    ):
        state_names(probe)


def test_no_other_module_touches_these_internals() -> None:
    root = Path(__file__).resolve().parents[2]
    adapter = root / "airfisheye_bench" / "metrics" / "_torchmetrics_compat.py"
    private = re.compile(r"\.(_update_count|_computed|_defaults|_reductions)\b")
    offenders = [
        f"{path.relative_to(root)}:{number}"
        for folder in ("airfisheye_bench", "datamodules", "models", "scripts", "tests")
        for path in sorted((root / folder).rglob("*.py"))
        if path not in (adapter, Path(__file__).resolve())
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if private.search(line)
    ]
    assert not offenders, f"torchmetrics internals outside {adapter.relative_to(root)}: {offenders}"
