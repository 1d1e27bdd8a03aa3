"""Returns a spinning LiDAR cannot have measured in the scene, found and counted so that nothing is dropped silently.

* **near the sensor**: closer than ``min_range`` (self-hits on the vehicle or the drone's frame, and returns at the
  origin that stand for no return);
* **unexplained**: no channel of the spec can have fired them (ring -1: more than half a channel spacing above
  the highest or below the lowest beam, or a ring field's -1).

The empty cells of organised clouds (NaN or zero) are dropped by the reader and counted there
(``io.Scan.no_returns``). Users see the counts in ``airfisheye-inspect`` and in the datamodule's log.

Example:
    >>> pts = np.array([[10.0, 0.0, 0.0], [0.3, 0.1, 0.0], [5.0, 0.0, 20.0]])
    >>> kept = filter_scan(pts, np.array([1, 1, -1]), min_range=1.0)
    >>> kept.keep.tolist(), kept.near_origin, kept.unexplained
    ([True, False, False], 1, 1)
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Default minimum range in metres: below it a return is taken for a self-hit (nuScenes holds thousands within
#: ~1.5 m; KITTI's car roof is ~1 m from its HDL-64E).
DEFAULT_MIN_RANGE = 1.0


class FilteredScan(NamedTuple):
    """What :func:`filter_scan` keeps (``bool [N]``) and how many returns each rule removed."""

    keep: np.ndarray
    near_origin: int
    unexplained: int

    def counts(self) -> dict[str, int]:
        """The removed returns by rule (for logs and reports)."""
        return {"near_origin": self.near_origin, "unexplained": self.unexplained}


def filter_scan(points: np.ndarray, rings: np.ndarray, min_range: float = DEFAULT_MIN_RANGE) -> FilteredScan:
    """The returns to keep: beyond ``min_range`` metres and with a ring (see the module docstring).

    A point near the sensor is counted there even if it also has no ring.
    """
    if not (isinstance(min_range, (int, float)) and min_range >= 0):
        raise ValueError(f"min_range must be a non-negative number of metres, got {min_range!r}")
    points = np.asarray(points, dtype=np.float64)
    near = np.einsum("ij,ij->i", points, points) < float(min_range) ** 2
    unexplained = ~near & (np.asarray(rings) < 0)
    return FilteredScan(~near & ~unexplained, int(near.sum()), int(unexplained.sum()))


__all__ = ["DEFAULT_MIN_RANGE", "FilteredScan", "filter_scan"]
