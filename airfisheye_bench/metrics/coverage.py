"""How densely a sparse input covers the ground truth, by incidence-angle ring: sparse pixels per pixel with
ground truth (``results.json``'s ``sparse_coverage``; ``scripts/sparse_coverage.py``)."""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import torch
from torch import Tensor

from airfisheye_bench.metrics.binned import DEFAULT_RING_EDGES_DEG, bin_index

__all__ = ["RingCoverage"]


class RingCoverage:
    """Sparse pixels and ground-truth pixels of every ring, summed over frames of one camera.

    Args:
        theta_deg: Incidence angle of every pixel ``[H, W]`` in degrees (NaN: no ray, in no ring).
        edges: Ring edges in degrees.

    Example:
        >>> coverage = RingCoverage(torch.tensor([[10.0, 50.0], [50.0, 10.0]]), edges=(0, 30, 60))
        >>> coverage.update(torch.tensor([[2.0, 0.0], [3.0, 0.0]]), torch.ones(2, 2))
        >>> coverage.compute()
        {'ring_0-30': 0.5, 'ring_30-60': 0.5}
    """

    def __init__(self, theta_deg: Tensor, edges: Sequence[float] = DEFAULT_RING_EDGES_DEG) -> None:
        self.edges = tuple(float(e) for e in edges)
        self.theta = theta_deg
        self.ring = bin_index(theta_deg.float(), self.edges, include_lowest=True)
        self.sparse = torch.zeros(len(self.edges) - 1, dtype=torch.float64)
        self.truth = torch.zeros_like(self.sparse)

    def update(self, sparse: Tensor, truth: Tensor) -> None:
        """Add frames: ``sparse`` and ``truth`` ``[..., H, W]`` (a pixel counts where it is > 0 or True)."""
        ring = self.ring.expand(truth.shape)
        for total, value in ((self.sparse, sparse), (self.truth, truth)):
            total += torch.bincount(ring[(value > 0) & (ring >= 0)], minlength=len(total)).double()

    def add_pixels(
        self, sparse_theta_deg: Tensor, truth_theta_deg: Tensor, truth_weight: float = 1.0
    ) -> None:
        """Add counts given as the incidence angles of the sparse and the ground-truth pixels (another camera's
        pixels, ``truth_weight`` of them per given one: the paper's 1536^2 image against a served ground truth)."""
        n = len(self.sparse)
        for total, theta, weight in (
            (self.sparse, sparse_theta_deg, 1.0),
            (self.truth, truth_theta_deg, truth_weight),
        ):
            ring = bin_index(theta.float(), self.edges, include_lowest=True)
            total += weight * torch.bincount(ring[ring >= 0], minlength=n).double()

    def add(self, other: RingCoverage) -> None:
        """Pool another camera's counts (rings with the same edges)."""
        self.sparse += other.sparse
        self.truth += other.truth

    def compute(self) -> dict[str, float]:
        """``{"ring_0-30": sparse / truth pixels, ...}`` (NaN for a ring without ground truth)."""
        ratio = (self.sparse / self.truth).tolist()
        return {
            f"ring_{lo:g}-{hi:g}": r
            for (lo, hi), r in zip(itertools.pairwise(self.edges), ratio, strict=True)
        }
