"""Book-keeping for metric states filled without going through ``Metric.update``."""

from __future__ import annotations

from torchmetrics import Metric


def record_update(metric: Metric) -> None:
    """Do what torchmetrics' ``update`` wrapper does after an update, for states changed directly.

    Used where one computation fills several metrics (all bins of :class:`BinnedMetrics` at once) or where states
    are merged from elsewhere (batches scored in loader workers). Without it ``compute()`` would warn that the
    metric was never updated, or return a value cached before the new states.
    """
    metric._update_count += 1
    metric._computed = None
