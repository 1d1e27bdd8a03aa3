"""DepthMetrics and CompletionMetrics against per-image NumPy re-statements of AdaBins and NLSPN."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from torchmetrics.utilities.data import dim_zero_sum

from airfisheye_bench.metrics import (
    COMPLETION_METRIC_KEYS,
    DEPTH_METRIC_KEYS,
    CompletionMetrics,
    DepthMetrics,
    completion_errors,
    depth_errors,
    functional,
)
from airfisheye_bench.metrics._torchmetrics_compat import state_reduction
from airfisheye_bench.specs import get_task
from tests.helpers.metric_refs import ref_average, ref_depth_image, ref_nlspn_image

MAX = 120.0


def _depth_batches(seed=0, n=3, b=3, h=8, w=10):
    """Ground truth with holes (0), NaN, values beyond MAX; predictions with 0, negatives, inf, NaN.

    The last image of the second batch has no valid pixel at all.
    """
    g = torch.Generator().manual_seed(seed)
    out = []
    for i in range(n):
        gt = torch.rand(b, h, w, generator=g) * 140.0
        gt[torch.rand(b, h, w, generator=g) < 0.2] = 0.0
        gt[0, 0, 0] = float("nan")
        gt[0, 0, 1] = MAX  # inclusive upper bound
        gt[0, 0, 2] = 1e-4  # invalid for depth (<= min_depth 1e-3) and for completion (<= 1e-4)
        gt[0, 0, 3] = 5e-4  # invalid for depth, valid for completion
        pred = gt * torch.exp(0.3 * torch.randn(b, h, w, generator=g)) + torch.randn(b, h, w, generator=g)
        pred[0, 1, :4] = torch.tensor([0.0, -3.0, float("inf"), float("nan")])
        pred[1, 1, :2] = torch.tensor([1e-5, 500.0])
        if i == 1:
            gt[-1] = 0.0
        out.append((pred.unsqueeze(1), gt.unsqueeze(1)))
    return out


def _reference(batches, image_fn):
    per_image = []
    for pred, gt in batches:
        for p, t in zip(pred[:, 0].numpy(), gt[:, 0].numpy(), strict=True):
            per_image.append(image_fn(t, p))
    return ref_average(per_image)


def test_depth_metrics_match_adabins_per_image_average():
    batches = _depth_batches()
    metric = DepthMetrics(min_depth=1e-3, max_depth=MAX)
    for pred, gt in batches:
        metric.update(pred, gt)
    out = metric.compute()
    ref = _reference(batches, lambda t, p: ref_depth_image(t, p, 1e-3, MAX))
    assert tuple(out) == DEPTH_METRIC_KEYS
    for k in DEPTH_METRIC_KEYS:
        assert out[k].item() == pytest.approx(ref[k], rel=1e-10, abs=1e-12), k
    assert metric.num_images.item() == 3 * 3 - 1  # the empty image is left out


def test_completion_metrics_match_nlspn_per_image_average():
    batches = _depth_batches(seed=4)
    metric = CompletionMetrics(max_depth=MAX)
    for pred, gt in batches:
        metric.update(pred, gt)
    out = metric.compute()
    ref = _reference(batches, lambda t, p: ref_nlspn_image(t, p, MAX))
    assert tuple(out) == COMPLETION_METRIC_KEYS
    for k in COMPLETION_METRIC_KEYS:
        assert out[k].item() == pytest.approx(ref[k], rel=1e-10, abs=1e-12), k
    assert metric.num_images.item() == 3 * 3 - 1


def test_silog_is_scale_invariant_and_rmse_log_is_not():
    gt = torch.rand(2, 1, 6, 6, generator=torch.Generator().manual_seed(0)) * 50 + 1
    errors, _ = depth_errors(2.0 * gt, gt)
    torch.testing.assert_close(errors["rmse_log"], torch.full((2,), math.log(2.0), dtype=torch.float64))
    torch.testing.assert_close(errors["silog"], torch.zeros(2, dtype=torch.float64), atol=1e-6, rtol=0)
    torch.testing.assert_close(errors["log10"], torch.full((2,), math.log10(2.0), dtype=torch.float64))


def test_perfect_prediction():
    gt = torch.rand(2, 5, 5, generator=torch.Generator().manual_seed(1)) * 100 + 1
    depth = DepthMetrics()
    depth.update(gt, gt)
    for k, v in depth.compute().items():
        assert v.item() == (1.0 if k.startswith("delta") else 0.0), k  # silog exactly 0, not NaN
    completion = CompletionMetrics()
    completion.update(gt, gt)
    for k, v in completion.compute().items():
        assert v.item() == pytest.approx(1.0 if k.startswith("delta") else 0.0, abs=1e-9), k


def test_depth_prediction_clipping_nan_and_inf():
    gt = torch.full((1, 1, 4), 10.0)
    pred = torch.tensor([[[0.0, float("inf"), float("nan"), -float("inf")]]])
    errors, n = depth_errors(pred, gt, min_depth=1e-3, max_depth=MAX)
    clipped = np.array([1e-3, MAX, 1e-3, 1e-3])  # -inf clips to min like any negative value
    assert n.item() == 4
    assert errors["abs_rel"].item() == pytest.approx(np.mean(np.abs(clipped - 10.0) / 10.0))
    assert errors["delta3"].item() == 0.0


def test_completion_zero_prediction_fails_every_delta_and_has_zero_inverse():
    gt = torch.tensor([[[2.0, 4.0, 0.0]]])
    pred = torch.tensor([[[0.0, float("nan"), 3.0]]])  # NaN counts as "no prediction" = 0
    errors, n = completion_errors(pred, gt)
    assert n.item() == 2
    for k in ("delta1", "delta2", "delta3"):
        assert errors[k].item() == 0.0
    inv_gt = 1.0 / (np.array([2.0, 4.0]) + 1e-8)  # inverse error = 0 - 1/gt
    assert errors["imae"].item() == pytest.approx(inv_gt.mean())
    assert errors["irmse"].item() == pytest.approx(np.sqrt((inv_gt**2).mean()))
    assert errors["mae"].item() == pytest.approx(3.0)


def test_completion_inf_prediction_is_clamped_to_max_depth():
    errors, _ = completion_errors(torch.tensor([[[float("inf")]]]), torch.tensor([[[100.0]]]), max_depth=MAX)
    assert errors["mae"].item() == pytest.approx(20.0)


@pytest.mark.parametrize("metric_cls", [DepthMetrics, CompletionMetrics])
def test_no_valid_image_gives_nan_values(metric_cls):
    metric = metric_cls()
    metric.update(torch.ones(2, 1, 3, 3), torch.zeros(2, 1, 3, 3))
    out = metric.compute()
    assert metric.num_images.item() == 0
    assert all(math.isnan(v.item()) for v in out.values())
    errors, n = metric._errors(torch.ones(2, 3, 3), torch.zeros(2, 3, 3), None)  # the functional form
    assert n.tolist() == [0, 0]
    assert all(torch.isnan(v).all() for v in errors.values())


@pytest.mark.parametrize("metric_cls", [DepthMetrics, CompletionMetrics])
def test_mask_argument_equals_removing_the_ground_truth(metric_cls):
    (pred, gt), *_ = _depth_batches(seed=7, n=1)
    mask = torch.rand(gt.shape, generator=torch.Generator().manual_seed(3)) < 0.6  # [B, 1, H, W]
    masked, ref = metric_cls(), metric_cls()
    masked.update(pred, gt, mask=mask)
    ref.update(pred, torch.where(mask, gt, 0.0))
    for k, v in masked.compute().items():
        torch.testing.assert_close(v, ref.compute()[k], equal_nan=True)


@pytest.mark.parametrize("metric_cls", [DepthMetrics, CompletionMetrics])
def test_three_and_four_dim_inputs_agree(metric_cls):
    (pred, gt), *_ = _depth_batches(seed=2, n=1)
    a, b = metric_cls(), metric_cls()
    a.update(pred, gt)
    b.update(pred[:, 0], gt[:, 0])
    for k, v in a.compute().items():
        torch.testing.assert_close(v, b.compute()[k])


@pytest.mark.parametrize("metric_cls", [DepthMetrics, CompletionMetrics])
def test_shape_mismatch_names_the_shapes(metric_cls):
    with pytest.raises(ValueError, match=r"\(2, 1, 4, 4\).*\(2, 1, 4, 5\)"):
        metric_cls().update(torch.ones(2, 1, 4, 4), torch.ones(2, 1, 4, 5))
    with pytest.raises(ValueError, match=r"\[B, 1, H, W\] or \[B, H, W\].*\(2, 3, 4, 4\)"):
        metric_cls().update(torch.ones(2, 3, 4, 4), torch.ones(2, 3, 4, 4))
    with pytest.raises(ValueError, match="mask"):
        metric_cls().update(torch.ones(2, 4, 4), torch.ones(2, 4, 4), mask=torch.ones(3, 3, dtype=torch.bool))
    with pytest.raises(ValueError, match="bool"):
        metric_cls().update(torch.ones(2, 4, 4), torch.ones(2, 4, 4), mask=torch.ones(4, 4))


def test_bad_depth_bounds_raise():
    with pytest.raises(ValueError, match="min_depth"):
        DepthMetrics(min_depth=0.0)
    with pytest.raises(ValueError, match="min_depth"):
        DepthMetrics(min_depth=10.0, max_depth=5.0)
    with pytest.raises(ValueError, match="max_depth"):
        CompletionMetrics(max_depth=0.0)


@pytest.mark.parametrize("metric_cls", [DepthMetrics, CompletionMetrics])
def test_states_are_summed_float64_and_attributes_are_set(metric_cls):
    metric = metric_cls()
    assert metric.sum_values.dtype == torch.float64
    assert all(state_reduction(metric, name) is dim_zero_sum for name in ("sum_values", "num_images"))
    assert metric.full_state_update is False
    spec = get_task("depth" if metric_cls is DepthMetrics else "completion")  # the one source of directions
    assert spec.primary_metric == "rmse"
    assert metric.higher_is_better is spec.higher_is_better is False
    assert spec.column("delta1").higher_is_better is True
    assert spec.column("rmse").higher_is_better is False


@pytest.mark.parametrize("chunk_pixels", [1, 170])  # one image per slice; two images (80 px each) per slice
@pytest.mark.parametrize("errors_fn", [depth_errors, completion_errors])
def test_batch_slicing_does_not_change_per_image_values(monkeypatch, chunk_pixels, errors_fn):
    (pred, gt), *_ = _depth_batches(seed=8, n=1)  # 3 images of 8x10
    mask = torch.rand(gt.shape[-2:], generator=torch.Generator().manual_seed(4)) < 0.7  # [H, W]
    whole, n_whole = errors_fn(pred, gt, mask=mask)
    monkeypatch.setattr(functional, "_CHUNK_PIXELS", chunk_pixels)
    sliced, n_sliced = errors_fn(pred, gt, mask=mask)
    assert torch.equal(n_whole, n_sliced)
    for k, v in whole.items():
        torch.testing.assert_close(sliced[k], v, rtol=0, atol=0, equal_nan=True)
