"""The affected-pixel and near-range completion metrics, on hand-built tensors whose answers are worked out here."""

from __future__ import annotations

import math

import pytest
import torch

from airfisheye_bench.metrics import CompletionMetrics
from airfisheye_bench.metrics.regions import (
    RegionCompletionMetrics,
    affected_pixels,
    dilate,
    input_difference,
    near_pixels,
)


def test_dilate_is_a_square_window_clipped_at_the_border() -> None:
    m = torch.zeros(1, 1, 6, 7, dtype=torch.bool)
    m[0, 0, 0, 0] = True  # a corner: the window is cut by the border
    m[0, 0, 4, 4] = True  # rows 2-6 cut to 2-5, columns 2-6
    grown = dilate(m, 2)[0]
    assert grown.shape == (6, 7)
    assert (
        grown[:3, :3].all() and grown.int().sum() == 3 * 3 + 4 * 5 - 1
    )  # the two windows share pixel (2, 2)
    assert grown[2:, 2:].all() and not grown[0, 3] and not grown[3, 0]
    assert torch.equal(dilate(m, 0), m[:, 0])
    with pytest.raises(ValueError, match="radius"):
        dilate(m, -1)


def test_affected_pixels_follow_the_difference_of_none_and_oracle_only() -> None:
    none = torch.zeros(2, 1, 8, 8)
    none[0, 0, 3, 3] = 5.0  # frame 0: a hidden point the oracle drops
    none[0, 0, 7, 7] = 9.0  # a visible point, in both maps
    none[1, 0, 0, 4] = 4.0  # frame 1: a hidden point nearest on its pixel, a visible one behind it
    oracle = none.clone()
    oracle[0, 0, 3, 3] = 0.0
    oracle[1, 0, 0, 4] = 30.0
    valid = torch.ones(2, 8, 8, dtype=torch.bool)
    valid[1, 0, :] = False  # frame 1's top row is outside the image circle
    region = affected_pixels(none, oracle, radius=1, valid=valid)
    assert region[0].int().sum() == 9 and region[0, 2:5, 2:5].all()  # 3x3 around (3, 3); (7, 7) untouched
    assert region[1].int().sum() == 3 and region[1, 1, 3:6].all()  # 3x3 around (0, 4), top row invalid
    assert not affected_pixels(none, none, radius=3).any()


def test_near_pixels_need_ground_truth() -> None:
    gt = torch.tensor([[[0.0, 0.5, 19.0, 20.0, 80.0]]])
    assert near_pixels(gt, 20.0).tolist() == [[[False, True, True, False, False]]]


def test_input_difference_counts_against_none() -> None:
    none = torch.tensor([[[3.0, 4.0, 0.0], [8.0, 0.0, 6.0]]])
    zbuf = torch.tensor(
        [[[3.0, 0.0, 0.0], [9.0, 0.0, 6.0]]]
    )  # one point removed, one pixel's nearest replaced
    valid = torch.tensor([[[True, True, True], [True, True, False]]])  # (1, 2) outside
    assert input_difference(zbuf, none, valid) == {"differing": 2, "sparse": 3, "valid": 5}
    assert input_difference(none, none, valid)["differing"] == 0


def test_region_metrics_by_hand() -> None:
    """Two 4x4 frames; every number below is worked out by hand (per-image means, then the mean over images)."""
    gt = torch.full((2, 1, 4, 4), 30.0)
    gt[:, :, 0, :] = 10.0  # the top row is near (< 20 m)
    pred = gt.clone()
    pred[0, 0, 0, 0] = 14.0  # frame 0: 4 m off at a near pixel next to its hidden point
    pred[1, 0, 3, 3] = 36.0  # frame 1: 6 m off at the far corner; frame 1 has no hidden point
    none, oracle = torch.zeros_like(gt), torch.zeros_like(gt)
    none[0, 0, 0, 1] = 3.0  # frame 0's hidden point at (0, 1): affected with radius 1 = rows 0-1, cols 0-2
    metric = RegionCompletionMetrics(radius=1, near_m=20.0)
    metric.update(pred, gt, none, oracle, torch.ones(2, 4, 4, dtype=torch.bool))
    out = metric.compute()

    # all: frame 0 MAE 4/16, frame 1 MAE 6/16 -> mean 0.3125; RMSE sqrt(16/16)=1 and sqrt(36/16)=1.5 -> 1.25
    assert out["all"]["mae"] == pytest.approx((4 / 16 + 6 / 16) / 2)
    assert out["all"]["rmse"] == pytest.approx((1.0 + 1.5) / 2)
    assert out["all"]["pixels"] == 32 and out["all"]["images"] == 2
    # affected: only frame 0, 6 pixels, one 4 m off -> MAE 4/6, RMSE sqrt(16/6); frame 1 is left out
    assert out["affected"]["pixels"] == 6 and out["affected"]["images"] == 1
    assert out["affected"]["mae"] == pytest.approx(4 / 6)
    assert out["affected"]["rmse"] == pytest.approx(math.sqrt(16 / 6))
    # near: the top row of both frames; frame 0 MAE 4/4, frame 1 MAE 0 -> 0.5
    assert out["near"]["pixels"] == 8 and out["near"]["mae"] == pytest.approx(0.5)
    # the whole-image region is the task metric itself
    plain = CompletionMetrics()
    plain.update(pred, gt)
    assert out["all"]["rmse"] == pytest.approx(float(plain.compute()["rmse"]))

    metric.reset()
    metric.update(pred, gt, none, none)  # no affected pixel anywhere: NaN, counted as empty
    empty = metric.compute()["affected"]
    assert math.isnan(empty["rmse"]) and empty["pixels"] == 0 and empty["images"] == 0
