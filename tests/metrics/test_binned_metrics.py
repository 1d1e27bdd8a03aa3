"""BinnedMetrics: the fisheye breakdown by incidence-angle ring and by ground-truth depth range."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import torch

from airfisheye_bench.metrics import (
    DEFAULT_DEPTH_EDGES_M,
    DEFAULT_RING_EDGES_DEG,
    BinnedMetrics,
    CompletionMetrics,
    DepthMetrics,
    SegmentationMetrics,
    bin_index,
)
from tests.helpers.metric_refs import ref_average, ref_confusion, ref_depth_image

H = W = 24
C = 4


def _theta_grid(h=H, w=W, fov_deg=190.0):
    """Equidistant fisheye incidence angle per pixel (deg), image circle inscribed; > fov/2 outside."""
    v, u = torch.meshgrid(
        torch.arange(h, dtype=torch.float32), torch.arange(w, dtype=torch.float32), indexing="ij"
    )
    r = torch.hypot(u - (w - 1) / 2, v - (h - 1) / 2)
    return r / (w / 2) * (fov_deg / 2)


def _seg_batch(seed=0, b=2):
    g = torch.Generator().manual_seed(seed)
    target = torch.randint(0, C, (b, H, W), generator=g)
    target[torch.rand(b, H, W, generator=g) < 0.1] = 255
    return torch.randn(b, C, H, W, generator=g), target


def _depth_batch(seed=0, b=3):
    g = torch.Generator().manual_seed(seed)
    gt = torch.rand(b, 1, H, W, generator=g) * 130.0
    gt[torch.rand(b, 1, H, W, generator=g) < 0.15] = 0.0
    pred = gt * torch.exp(0.2 * torch.randn(b, 1, H, W, generator=g))
    return pred, gt


def test_bin_index_is_right_closed_with_optional_lowest_edge():
    v = torch.tensor([-1.0, 0.0, 0.5, 30.0, 30.01, 95.0, 95.5, float("nan")])
    edges = (0.0, 30.0, 95.0)
    assert bin_index(v, edges, include_lowest=True).tolist() == [-1, 0, 0, 0, 1, 1, -1, -1]
    assert bin_index(v, edges, include_lowest=False).tolist() == [-1, -1, 0, 0, 1, 1, -1, -1]


def test_default_edges_and_key_names():
    rings = BinnedMetrics(DepthMetrics)
    ranges = BinnedMetrics(DepthMetrics, key="depth")
    assert rings.edges == DEFAULT_RING_EDGES_DEG == (0, 30, 60, 80, 95)
    assert ranges.edges == DEFAULT_DEPTH_EDGES_M == (0, 10, 20, 40, 80, 120)
    assert rings.bin_names == ["ring_0-30", "ring_30-60", "ring_60-80", "ring_80-95"]
    assert ranges.bin_names[0] == "range_0-10"
    pred, gt = _depth_batch()
    rings.update(pred, gt, theta=_theta_grid())
    out = rings.compute()
    assert "ring_60-80/rmse" in out
    assert len(out) == 4 * 9


def test_ring_confusion_matrices_add_up_to_the_global_one():
    theta = _theta_grid()
    rings = BinnedMetrics(lambda: SegmentationMetrics(C), key="theta")
    inside = SegmentationMetrics(C)
    for seed in range(2):
        logits, target = _seg_batch(seed)
        rings.update(logits, target, theta=theta)
        inside.update(logits, target, mask=theta <= 95.0)
    total = sum(child.confmat for child in rings.bins)
    torch.testing.assert_close(total, inside.confmat, rtol=0, atol=0)
    assert 0 < inside.confmat.sum() < 2 * 2 * H * W  # corners (theta > 95) really were left out
    # and each ring is the reference confusion on its own pixels
    logits, target = _seg_batch(1)
    ring = (theta > 60) & (theta <= 80)
    single = BinnedMetrics(lambda: SegmentationMetrics(C))
    single.update(logits, target, theta=theta)
    expected = ref_confusion(
        logits.argmax(1).numpy(), target.numpy(), C, mask=np.broadcast_to(ring.numpy(), target.shape)
    )
    np.testing.assert_array_equal(single.bins[2].confmat.numpy(), expected)


def test_ring_depth_metrics_match_the_reference_on_each_ring():
    theta = _theta_grid()
    pred, gt = _depth_batch(seed=3)
    rings = BinnedMetrics(DepthMetrics, edges=(0, 45, 80, 95))
    rings.update(pred, gt, theta=theta)
    out = rings.compute()
    th = theta.numpy()
    for lo, hi in [(0, 45), (45, 80), (80, 95)]:
        ring = ((th > lo) | (lo == 0)) & (th <= hi)
        ref = ref_average(
            [
                ref_depth_image(t, p, 1e-3, 120.0, mask=ring)
                for t, p in zip(gt[:, 0].numpy(), pred[:, 0].numpy(), strict=True)
            ]
        )
        for k, v in ref.items():
            assert out[f"ring_{lo}-{hi}/{k}"].item() == pytest.approx(v, rel=1e-10), (lo, hi, k)


def test_range_bins_use_the_ground_truth_and_recombine_to_the_global_rmse():
    pred, gt = _depth_batch(seed=5, b=1)  # one image: per-image means recombine by pixel counts
    ranges = BinnedMetrics(CompletionMetrics, key="depth")
    whole = CompletionMetrics()
    ranges.update(pred, gt)
    whole.update(pred, gt)
    out = ranges.compute()
    g = gt.numpy().ravel()
    sq_sum, n_total = 0.0, 0
    for lo, hi in itertools.pairwise(DEFAULT_DEPTH_EDGES_M):
        n = int(((g > max(lo, 1e-4)) & (g <= hi)).sum())
        assert n > 0
        sq_sum += n * out[f"range_{lo:g}-{hi:g}/rmse"].item() ** 2
        n_total += n
    assert n_total == int(((g > 1e-4) & (g <= 120)).sum())
    assert math.sqrt(sq_sum / n_total) == pytest.approx(whole.compute()["rmse"].item(), rel=1e-10)


def test_segmentation_by_depth_range_needs_a_depth_map():
    logits, target = _seg_batch()
    ranges = BinnedMetrics(lambda: SegmentationMetrics(C), key="depth")
    with pytest.raises(ValueError, match="depth"):
        ranges.update(logits, target)
    depth = torch.rand(2, 1, H, W, generator=torch.Generator().manual_seed(0)) * 150
    depth[:, :, :4] = 0.0  # "sky": no range bin
    ranges.update(logits, target, depth=depth)
    in_range = (depth[:, 0] > 0) & (depth[:, 0] <= 120) & (target != 255)
    assert sum(int(child.confmat.sum()) for child in ranges.bins) == int(in_range.sum())


def test_theta_per_image_and_mask_combine():
    pred, gt = _depth_batch(seed=1, b=2)
    theta = _theta_grid().expand(2, H, W).clone()
    theta[1] = 10.0  # second image: every pixel in the first ring
    mask = torch.zeros(2, 1, H, W, dtype=torch.bool)
    mask[:, :, : H // 2] = True
    rings = BinnedMetrics(DepthMetrics, edges=(0, 30, 95))
    rings.update(pred, gt, theta=theta, mask=mask)
    assert rings.bins[0].num_images.item() == 2
    assert rings.bins[1].num_images.item() == 1  # only the first image has pixels beyond 30 deg
    th, m = theta.numpy(), mask[:, 0].numpy()
    ref = ref_average(
        [
            ref_depth_image(gt[i, 0].numpy(), pred[i, 0].numpy(), 1e-3, 120.0, mask=m[i] & (th[i] <= 30))
            for i in range(2)
        ]
    )
    assert rings.compute()["ring_0-30/rmse"].item() == pytest.approx(ref["rmse"], rel=1e-10)


def test_forward_returns_batch_values_and_reset_clears_children():
    theta = _theta_grid()
    rings = BinnedMetrics(DepthMetrics)
    pred, gt = _depth_batch(seed=2)
    batch_out = rings(pred, gt, theta=theta)
    torch.testing.assert_close(batch_out, rings.compute())
    rings(pred * 2, gt, theta=theta)
    assert rings.bins[0].num_images.item() == 2 * 3
    rings.reset()
    assert all(child.num_images.item() == 0 for child in rings.bins)


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="theta"):
        BinnedMetrics(DepthMetrics).update(*_depth_batch())
    with pytest.raises(ValueError, match="theta"):
        BinnedMetrics(DepthMetrics).update(*_depth_batch(), theta=torch.zeros(H, W + 1))
    with pytest.raises(ValueError, match="mask"):
        BinnedMetrics(DepthMetrics).update(*_depth_batch(), theta=_theta_grid(), mask=torch.ones(H, W))
    with pytest.raises(ValueError, match="edges"):
        BinnedMetrics(DepthMetrics, edges=(0, 30, 30))
    with pytest.raises(ValueError, match="key"):
        BinnedMetrics(DepthMetrics, key="phi")
    shared = DepthMetrics()
    with pytest.raises(ValueError, match="new metric"):
        BinnedMetrics(lambda: shared)


@pytest.mark.parametrize("metric_cls", [DepthMetrics, CompletionMetrics])
@pytest.mark.parametrize("key", ["theta", "depth"])
def test_grouped_pass_equals_one_metric_per_bin(metric_cls, key: str) -> None:
    """The one-pass evaluation of all bins gives what a separately masked metric per bin gives."""
    gen = torch.Generator().manual_seed(3)
    binned = BinnedMetrics(metric_cls, key=key)
    assert binned._grouped
    edges = binned.edges
    theta = torch.rand(24, 32, generator=gen) * 100.0  # some pixels beyond 95 deg: in no ring
    singles = [metric_cls() for _ in range(len(edges) - 1)]
    for step in range(3):
        gt = torch.rand(3, 1, 24, 32, generator=gen) * 130.0
        gt[gt < 5.0] = 0.0  # no ground truth
        pred = gt * (1 + 0.3 * torch.randn(3, 1, 24, 32, generator=gen))
        mask = torch.rand(3, 24, 32, generator=gen) > 0.2
        if step == 1:
            gt[1] = 0.0  # an image without any valid pixel
        binned.update(pred, gt, theta=theta, mask=mask)
        values = theta.expand(3, 24, 32).contiguous() if key == "theta" else gt[:, 0].contiguous()
        index = bin_index(values, edges, include_lowest=key == "theta")
        for k, single in enumerate(singles):
            single.update(pred, gt, mask=mask & (index == k))
        # compute() between updates must see every update (no stale cached value).
        out = binned.compute()
        for name, single in zip(binned.bin_names, singles, strict=True):
            for metric_key, value in single.compute().items():
                got = out[f"{name}/{metric_key}"]
                if torch.isnan(value):
                    assert torch.isnan(got), (name, metric_key)
                else:
                    assert got.item() == pytest.approx(value.item(), rel=1e-12, abs=1e-12), (name, metric_key)
