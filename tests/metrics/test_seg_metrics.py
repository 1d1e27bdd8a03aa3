"""SegmentationMetrics and the confusion-matrix functions against a per-pixel NumPy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from torchmetrics.classification import MulticlassJaccardIndex
from torchmetrics.utilities.data import dim_zero_sum

from airfisheye_bench.metrics import SegmentationMetrics, confusion_matrix
from airfisheye_bench.metrics._torchmetrics_compat import state_reduction
from airfisheye_bench.metrics.functional import _argmax_channels
from airfisheye_bench.specs import get_task
from tests.helpers.metric_refs import ref_confusion, ref_seg_scores

C = 5


def _batches(seed=0, n=3, b=2, h=9, w=11, num_classes=C):
    g = torch.Generator().manual_seed(seed)
    out = []
    for _ in range(n):
        target = torch.randint(0, num_classes, (b, h, w), generator=g)
        target[torch.rand(b, h, w, generator=g) < 0.2] = 255
        logits = torch.randn(b, num_classes, h, w, generator=g)
        out.append((logits, target))
    return out


def test_matches_reference_over_several_batches():
    metric = SegmentationMetrics(C, class_names=[f"c{i}" for i in range(C)])
    cm_ref = np.zeros((C, C), dtype=np.int64)
    for logits, target in _batches():
        metric.update(logits, target)
        cm_ref += ref_confusion(logits.argmax(1).numpy(), target.numpy(), C)
    np.testing.assert_array_equal(metric.confmat.numpy(), cm_ref)
    assert metric.confmat.dtype == torch.int64
    out = metric.compute()
    miou, acc, ious = ref_seg_scores(cm_ref)
    assert set(out) == {"mIoU", "pixel_acc", *(f"IoU/c{i}" for i in range(C))}
    assert out["mIoU"].item() == pytest.approx(miou, rel=1e-12)
    assert out["pixel_acc"].item() == pytest.approx(acc, rel=1e-12)
    for i in range(C):
        assert out[f"IoU/c{i}"].item() == pytest.approx(ious[i], rel=1e-12)


def test_matches_torchmetrics_jaccard():
    metric = SegmentationMetrics(C)
    jaccard = MulticlassJaccardIndex(num_classes=C, average="macro", ignore_index=255)
    for logits, target in _batches(seed=3):
        metric.update(logits, target)
        jaccard.update(logits.argmax(1), target)
    assert metric.compute()["mIoU"].item() == pytest.approx(jaccard.compute().item(), abs=1e-6)


def test_logits_and_labels_agree_and_argmax_breaks_ties_like_torch():
    g = torch.Generator().manual_seed(1)
    logits = torch.randint(0, 3, (2, C, 6, 7), generator=g).float()  # many ties
    assert torch.equal(_argmax_channels(logits).long(), logits.argmax(1))
    target = torch.randint(0, C, (2, 6, 7), generator=g)
    a, b = SegmentationMetrics(C), SegmentationMetrics(C)
    a.update(logits, target)
    b.update(logits.argmax(1).to(torch.uint8), target.unsqueeze(1))  # uint8 labels, [B,1,H,W] target
    torch.testing.assert_close(a.confmat, b.confmat, rtol=0, atol=0)


def test_class_absent_from_split_is_excluded_from_the_mean():
    metric = SegmentationMetrics(4)
    target = torch.tensor([[[0, 0, 1, 1]]])
    preds = torch.tensor([[[0, 0, 1, 2]]])  # class 2 only predicted (IoU 0), class 3 nowhere
    metric.update(preds, target)
    out = metric.compute()
    assert math.isnan(out["IoU/3"].item())
    assert out["IoU/2"].item() == 0.0
    assert out["IoU/0"].item() == 1.0
    assert out["IoU/1"].item() == 0.5
    assert out["mIoU"].item() == pytest.approx((1.0 + 0.5 + 0.0) / 3)


def test_pooled_miou_differs_from_mean_of_per_batch_mious():
    # Batch 1: 100 pixels of class 0, all right (class 1 absent -> batch mIoU 1.0).
    # Batch 2: one class-0 pixel right, one class-1 pixel called 0 (IoU0 = 1/2, IoU1 = 0 -> batch mIoU 0.25).
    batches = [
        (torch.zeros(1, 10, 10, dtype=torch.long), torch.zeros(1, 10, 10, dtype=torch.long)),
        (torch.tensor([[[0, 0]]]), torch.tensor([[[0, 1]]])),
    ]
    pooled = SegmentationMetrics(2)
    per_batch = []
    for preds, target in batches:
        pooled.update(preds, target)
        single = SegmentationMetrics(2)
        single.update(preds, target)
        per_batch.append(single.compute()["mIoU"].item())
    assert per_batch == pytest.approx([1.0, 0.25])
    # Pooled: IoU0 = 101 / 102, IoU1 = 0.
    assert pooled.compute()["mIoU"].item() == pytest.approx((101 / 102 + 0.0) / 2)
    assert abs(pooled.compute()["mIoU"].item() - np.mean(per_batch)) > 0.1


def test_ignore_index_pixels_do_not_count_even_with_out_of_range_predictions():
    target = torch.tensor([[[0, 1, 255, 255]]])
    preds = torch.tensor([[[0, 1, 1, 200]]])  # 200 is no class but sits on an ignored pixel
    cm = confusion_matrix(preds, target, num_classes=2)
    np.testing.assert_array_equal(cm.numpy(), [[1, 0], [0, 1]])
    cm_none = confusion_matrix(preds[..., :3], torch.tensor([[[0, 1, 1]]]), num_classes=2, ignore_index=None)
    np.testing.assert_array_equal(cm_none.numpy(), [[1, 0], [0, 2]])


def test_labels_outside_the_classes_raise():
    with pytest.raises(ValueError, match="preds"):
        confusion_matrix(torch.tensor([[[0, 7]]]), torch.tensor([[[0, 1]]]), num_classes=2)
    with pytest.raises(ValueError, match="target"):
        confusion_matrix(torch.tensor([[[0, 1]]]), torch.tensor([[[0, 9]]]), num_classes=2)


def test_mask_restricts_pixels_like_setting_the_target_to_ignore():
    (logits, target), *_ = _batches(seed=5, n=1)
    mask = torch.rand(target.shape[-2:], generator=torch.Generator().manual_seed(2)) < 0.5  # [H, W] broadcast
    masked = SegmentationMetrics(C)
    masked.update(logits, target, mask=mask)
    ref = SegmentationMetrics(C)
    ref.update(logits, torch.where(mask, target, 255))
    torch.testing.assert_close(masked.confmat, ref.confmat, rtol=0, atol=0)
    expected = ref_confusion(
        logits.argmax(1).numpy(), target.numpy(), C, mask=np.broadcast_to(mask.numpy(), target.shape)
    )
    np.testing.assert_array_equal(masked.confmat.numpy(), expected)


def test_no_evaluated_pixel_gives_nan_not_an_error():
    metric = SegmentationMetrics(3)
    metric.update(torch.zeros(1, 4, 4, dtype=torch.long), torch.full((1, 4, 4), 255))
    out = metric.compute()
    assert all(math.isnan(v.item()) for v in out.values())


def test_reset_clears_the_confusion_matrix():
    metric = SegmentationMetrics(C)
    logits, target = _batches(n=1)[0]
    metric.update(logits, target)
    metric.reset()
    assert metric.confmat.sum().item() == 0


@pytest.mark.parametrize(
    ("preds", "target", "match"),
    [
        (
            torch.zeros(2, 4, 4, dtype=torch.long),
            torch.zeros(2, 4, 5, dtype=torch.long),
            r"\(2, 4, 4\).*\(2, 4, 5\)",
        ),
        (torch.zeros(2, 3, 4, 4), torch.zeros(2, 4, 4, dtype=torch.long), "num_classes"),
        (torch.zeros(2, 4, 4), torch.zeros(2, 4, 4, dtype=torch.long), "integer labels"),
        (torch.zeros(2, 4, 4, dtype=torch.long), torch.zeros(2, 4, 4), "target"),
    ],
)
def test_bad_inputs_raise_value_error(preds, target, match):
    with pytest.raises(ValueError, match=match):
        SegmentationMetrics(C).update(preds, target)


def test_bad_constructor_arguments_raise():
    with pytest.raises(ValueError, match="ignore_index"):
        SegmentationMetrics(3, ignore_index=1)
    with pytest.raises(ValueError, match="class_names"):
        SegmentationMetrics(3, class_names=["a", "b"])
    with pytest.raises(ValueError, match="num_classes"):
        SegmentationMetrics(0)


def test_metric_attributes_agree_with_the_task_spec():
    metric = SegmentationMetrics(2, class_names=["sky", "road"])
    spec = get_task("seg")  # the one source of the ranking key and the directions
    assert spec.primary_metric == "mIoU"
    assert metric.higher_is_better is spec.higher_is_better is True
    assert metric.full_state_update is False
    assert {c.key: c.higher_is_better for c in spec.columns} == {"mIoU": True, "pixel_acc": True}
    metric.update(torch.tensor([[[0, 1]]]), torch.tensor([[[0, 1]]]))
    assert set(spec.metric_keys) <= set(metric.compute())  # every ranked column is an output of the metric
    assert state_reduction(metric, "confmat") is dim_zero_sum
