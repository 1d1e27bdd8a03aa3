"""Losses: compared with plain reference implementations written from the papers / official code."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from models.losses import AdaBinsLoss, BinsChamferLoss, SegmentationCELoss, SILogLoss


def _depth_pair(seed=0, shape=(2, 1, 16, 24)):
    g = torch.Generator().manual_seed(seed)
    gt = 0.5 + 100 * torch.rand(shape, generator=g)
    gt[torch.rand(shape, generator=g) < 0.3] = 0.0  # no return
    gt[torch.rand(shape, generator=g) < 0.05] = 150.0  # beyond max_depth
    pred = 0.5 + 100 * torch.rand(shape, generator=g)
    return pred, gt


def _silog_reference(pred, gt, lambd=0.85, min_depth=1e-3, max_depth=120.0):
    """Eigen et al. 2014, eq. 4 (pooled over the batch), times 10 after the sqrt as AdaBins."""
    p, t = pred.numpy().astype(np.float64).ravel(), gt.numpy().astype(np.float64).ravel()
    valid = (t > min_depth) & (t <= max_depth)
    d = np.log(p[valid]) - np.log(t[valid])
    n = d.size
    return 10 * math.sqrt((d**2).sum() / n - lambd * d.sum() ** 2 / n**2)


# ---------------------------------------------------------------- SILog


@pytest.mark.parametrize("lambd", [0.85, 0.5, 1.0])
def test_silog_matches_eigen_formula(lambd):
    pred, gt = _depth_pair()
    got = SILogLoss(lambd=lambd)(pred, gt)
    assert got.item() == pytest.approx(_silog_reference(pred, gt, lambd), rel=1e-5)


def test_silog_matches_official_adabins_expression():
    pred, gt = _depth_pair(shape=(2, 1, 64, 64))
    valid = (gt > 1e-3) & (gt <= 120)
    g = torch.log(pred[valid]) - torch.log(gt[valid])
    official = 10 * torch.sqrt(torch.var(g) + 0.15 * torch.mean(g) ** 2)  # unbiased var: differs by O(1/N)
    assert SILogLoss()(pred, gt).item() == pytest.approx(official.item(), rel=1e-3)


def test_silog_ignores_invalid_pixels_and_accepts_bhw():
    pred, gt = _depth_pair()
    changed = pred.clone()
    changed[(gt == 0) | (gt > 120)] = 1e-6  # garbage where there is no valid ground truth
    loss = SILogLoss()
    assert loss(changed, gt).item() == pytest.approx(loss(pred, gt).item(), rel=1e-6)
    assert loss(pred[:, 0], gt[:, 0]).item() == pytest.approx(loss(pred, gt).item(), rel=1e-6)
    mask = torch.zeros_like(gt, dtype=torch.bool)
    mask[..., :8] = True
    expected = _silog_reference(pred[..., :8].contiguous(), gt[..., :8].contiguous())
    assert loss(pred, gt, mask=mask).item() == pytest.approx(expected, rel=1e-5)


def test_silog_resizes_prediction_with_align_corners():
    pred, gt = _depth_pair(shape=(2, 1, 16, 16))
    low = pred[..., ::2, ::2].contiguous()
    up = torch.nn.functional.interpolate(low, size=(16, 16), mode="bilinear", align_corners=True)
    assert SILogLoss()(low, gt).item() == pytest.approx(SILogLoss()(up, gt).item(), rel=1e-6)


def test_silog_is_scale_invariant_with_lambda_one():
    pred, gt = _depth_pair()
    loss = SILogLoss(lambd=1.0)
    assert loss(pred * 7.0, gt).item() == pytest.approx(loss(pred, gt).item(), rel=1e-4)


def test_silog_gradients_finite_at_perfect_prediction_and_without_valid_pixels():
    _, gt = _depth_pair()
    pred = gt.clamp_min(1.0).clone().requires_grad_(True)
    SILogLoss()(pred, gt.clamp_min(1.0)).backward()
    assert torch.isfinite(pred.grad).all()
    pred = torch.rand(1, 1, 4, 4, requires_grad=True)
    loss = SILogLoss()(pred, torch.zeros(1, 1, 4, 4))
    loss.backward()
    assert loss.item() == 0.0 and torch.equal(pred.grad, torch.zeros_like(pred))


def test_silog_rejects_bad_shapes():
    with pytest.raises(ValueError, match="target"):
        SILogLoss()(torch.rand(2, 1, 4, 4), torch.rand(2, 3, 4, 4))
    with pytest.raises(ValueError, match="batch"):
        SILogLoss()(torch.rand(2, 1, 4, 4), torch.rand(3, 1, 4, 4))


# ---------------------------------------------------------------- Chamfer


def _chamfer_reference(bin_edges, target, min_depth=1e-3, max_depth=120.0):
    """pytorch3d chamfer_distance defaults on 1-D points, written with explicit pairwise distances."""
    per_image = []
    for edges, t in zip(bin_edges, target.flatten(1), strict=True):
        centers = 0.5 * (edges[1:] + edges[:-1])
        y = t[(t > min_depth) & (t <= max_depth)]
        if y.numel() == 0:
            continue
        d2 = (centers[:, None] - y[None, :]) ** 2  # [P, T]
        per_image.append(d2.min(dim=1).values.mean() + d2.min(dim=0).values.mean())
    return torch.stack(per_image).mean()


def _random_edges(batch, n_bins, seed=0, requires_grad=False):
    g = torch.Generator().manual_seed(seed)
    widths = torch.rand(batch, n_bins, generator=g) + 0.05
    widths = widths / widths.sum(1, keepdim=True) * 120
    edges = torch.cumsum(torch.nn.functional.pad(widths, (1, 0), value=1e-3), dim=1)
    return edges.requires_grad_(requires_grad)


def test_chamfer_matches_pairwise_reference_value_and_gradient():
    _, gt = _depth_pair(shape=(3, 1, 12, 20))
    gt[1] = 0.0  # an image without valid depth is left out of the mean
    edges = _random_edges(3, 32, requires_grad=True)
    ref_edges = edges.detach().clone().requires_grad_(True)
    got, ref = BinsChamferLoss()(edges, gt), _chamfer_reference(ref_edges, gt)
    torch.testing.assert_close(got, ref, rtol=1e-5, atol=1e-6)
    got.backward()
    ref.backward()
    torch.testing.assert_close(edges.grad, ref_edges.grad, rtol=1e-4, atol=1e-6)


def test_chamfer_handles_unsorted_centres_and_targets_without_channel_dim():
    _, gt = _depth_pair(shape=(2, 1, 8, 8))
    edges = _random_edges(2, 8)
    # Reverse the centres' order: edges [e0..e8] reversed keep the same set of midpoints.
    reversed_edges = edges.flip(1)
    torch.testing.assert_close(BinsChamferLoss()(reversed_edges, gt[:, 0]), _chamfer_reference(edges, gt))


def test_a_range_normalised_chamfer_is_the_metric_one_scaled_to_its_reference_range():
    edges, gt = _random_edges(2, 16), torch.rand(2, 1, 8, 8) * 120
    metric = BinsChamferLoss()(edges, gt)
    normalised = BinsChamferLoss(max_depth=120.0, reference_range=10.0)(edges, gt)
    torch.testing.assert_close(normalised, metric * (10.0 / 120.0) ** 2)
    with pytest.raises(ValueError, match="reference_range"):
        BinsChamferLoss(max_depth=None, reference_range=10.0)


def test_chamfer_is_zero_when_centres_and_depths_coincide():
    edges = torch.tensor([[1.0, 3.0, 5.0, 9.0]])  # centres 2, 4, 7
    gt = torch.tensor([2.0, 4.0, 7.0, 7.0, 0.0, 2.0]).view(1, 1, 2, 3)
    assert BinsChamferLoss()(edges, gt).item() == 0.0
    gt_shifted = gt + 1.0 * (gt > 0)  # every valid depth moves by 1 m
    assert BinsChamferLoss()(edges, gt_shifted).item() > 0.0


def test_chamfer_without_any_valid_depth_is_zero_with_graph():
    edges = _random_edges(2, 4, requires_grad=True)
    loss = BinsChamferLoss()(edges, torch.zeros(2, 1, 4, 4))
    loss.backward()
    assert loss.item() == 0.0 and torch.equal(edges.grad, torch.zeros_like(edges))


def test_chamfer_scales_to_full_resolution_targets():
    # 2 x 512 x 512 depths and 256 bins: a dense [B, 256, 262144] distance matrix would take 0.5 GB.
    gt = torch.rand(2, 1, 512, 512) * 120
    loss = BinsChamferLoss()(_random_edges(2, 256), gt)
    assert torch.isfinite(loss) and loss.item() > 0


# ---------------------------------------------------------------- AdaBins total


def test_adabins_loss_combines_terms_with_weight():
    pred, gt = _depth_pair()
    edges = _random_edges(2, 16)
    outputs = {"depth": pred, "bin_edges": edges}
    terms = AdaBinsLoss(w_chamfer=0.1).terms(outputs, gt)
    assert terms["silog"].item() == pytest.approx(SILogLoss()(pred, gt).item())
    assert terms["chamfer"].item() == pytest.approx(BinsChamferLoss()(edges, gt).item())
    assert terms["loss"].item() == pytest.approx(terms["silog"].item() + 0.1 * terms["chamfer"].item())
    assert AdaBinsLoss()(outputs, gt).item() == pytest.approx(terms["loss"].item())
    with pytest.raises(
        ValueError, match=r"missing \['bin_edges'\]; a model without bins trains with w_chamfer=0"
    ):
        AdaBinsLoss()({"depth": pred}, gt)


def test_adabins_loss_without_the_chamfer_term_needs_no_bins():
    pred, gt = _depth_pair()
    terms = AdaBinsLoss(w_chamfer=0.0).terms({"depth": pred}, gt)
    assert terms.keys() == {"loss", "silog", "chamfer"} and terms["chamfer"].item() == 0.0
    assert terms["loss"].item() == terms["silog"].item() == pytest.approx(SILogLoss()(pred, gt).item())
    with_bins = AdaBinsLoss(w_chamfer=0.0).terms({"depth": pred, "bin_edges": _random_edges(2, 16)}, gt)
    assert with_bins["loss"].item() == terms["loss"].item()  # the bins are not read
    with pytest.raises(ValueError, match="'depth'"):
        AdaBinsLoss(w_chamfer=0.0)({"bin_edges": _random_edges(2, 16)}, gt)


# ---------------------------------------------------------------- segmentation


def test_cross_entropy_ignores_255():
    g = torch.Generator().manual_seed(0)
    logits = torch.randn(2, 4, 5, 6, generator=g)
    target = torch.randint(0, 4, (2, 5, 6), generator=g)
    target[:, :2] = 255
    keep = target != 255
    log_probs = logits.log_softmax(1).permute(0, 2, 3, 1)[keep]  # [N, C]
    expected = -log_probs.gather(1, target[keep][:, None]).mean()
    torch.testing.assert_close(SegmentationCELoss()(logits, target), expected)


def test_cross_entropy_class_weights_from_a_config_list():
    g = torch.Generator().manual_seed(0)
    logits = torch.randn(2, 3, 4, 4, generator=g)
    target = torch.randint(0, 3, (2, 4, 4), generator=g)
    weight = [1.0, 2.0, 0.5]
    torch.testing.assert_close(
        SegmentationCELoss(weight=weight)(logits, target),
        SegmentationCELoss(weight=torch.tensor(weight))(logits, target),
    )
    assert SegmentationCELoss(weight=weight)(logits, target) != SegmentationCELoss()(logits, target)


def test_cross_entropy_all_ignored_is_zero_and_shape_errors():
    logits = torch.randn(1, 3, 2, 2, requires_grad=True)
    loss = SegmentationCELoss()(logits, torch.full((1, 2, 2), 255))
    loss.backward()
    assert loss.item() == 0.0 and torch.isfinite(logits.grad).all()
    with pytest.raises(ValueError, match="target"):
        SegmentationCELoss()(logits, torch.zeros(1, 1, 2, 2, dtype=torch.long))
