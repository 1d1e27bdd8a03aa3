"""The one place that touches torchmetrics' private ``Metric`` attributes.

torchmetrics has no public API for three things the metrics here need:

- marking a metric as updated when its states were filled directly rather than through ``update`` (all bins of
  :class:`~airfisheye_bench.metrics.BinnedMetrics` at once, states merged from loader workers): ``_update_count``
  and the cached result ``_computed``;
- the names of the states a metric declared with ``add_state`` (``_defaults``);
- how each state is reduced across processes (``_reductions``).

Every access goes through the functions below, and ``tests/metrics/test_torchmetrics_compat.py`` checks each of
them against the installed torchmetrics, naming its version when one no longer holds.

Example:
    >>> import torch
    >>> from torchmetrics import SumMetric
    >>> metric = SumMetric()
    >>> state_names(metric), sums_every_state(metric)
    (('sum_value',), True)
    >>> metric.sum_value += 3.0
    >>> record_update(metric)
    >>> float(metric.compute())
    3.0
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import torchmetrics
from torchmetrics import Metric
from torchmetrics.utilities.data import dim_zero_sum

__all__ = ["record_update", "state_names", "state_reduction", "sums_every_state"]


def _private(metric: Metric, name: str) -> Any:
    try:
        return getattr(metric, name)
    except AttributeError:
        raise RuntimeError(
            f"torchmetrics {torchmetrics.__version__} has no Metric.{name}, which "
            "airfisheye_bench/metrics/_torchmetrics_compat.py relies on; install a torchmetrics this project supports "
            "(pyproject.toml) or update that module"
        ) from None


def record_update(metric: Metric) -> None:
    """Do what torchmetrics' ``update`` wrapper does after an update, for states changed directly.

    Without it ``compute()`` would warn that the metric was never updated, or return a value cached before the
    new states.
    """
    count = _private(metric, "_update_count")
    # _computed must exist: a torchmetrics caching the result elsewhere would return stale values.
    _private(metric, "_computed")
    metric._update_count, metric._computed = count + 1, None


def state_names(metric: Metric) -> tuple[str, ...]:
    """The names of the states ``metric`` declared with ``add_state``, in declaration order."""
    return tuple(_private(metric, "_defaults"))


def state_reduction(metric: Metric, name: str) -> Callable | None:
    """The function that reduces state ``name`` across processes (``dim_zero_sum`` for ``"sum"``)."""
    return _private(metric, "_reductions")[name]


def sums_every_state(metric: Metric) -> bool:
    """Whether every state of ``metric`` is reduced by summing (so partial states can be added up anywhere)."""
    return all(state_reduction(metric, name) is dim_zero_sum for name in state_names(metric))
