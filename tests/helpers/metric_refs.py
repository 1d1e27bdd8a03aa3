"""Plain NumPy re-statements of the reference metric definitions, one image / one pixel at a time.

Deliberately written like the reference code (AdaBins ``compute_errors``, NLSPN ``NLSPNMetric``, a
Cityscapes-style confusion matrix) and not like the vectorised implementation under test.
"""

from __future__ import annotations

import numpy as np


def ref_confusion(pred_labels, target, num_classes, ignore_index=255, mask=None):
    """Confusion matrix by an explicit loop over pixels (rows = target)."""
    cm = np.zeros((num_classes, num_classes), dtype=np.int64)
    pred_labels = np.asarray(pred_labels).ravel()
    target = np.asarray(target).ravel()
    mask = np.ones_like(target, dtype=bool) if mask is None else np.asarray(mask).ravel()
    for p, t, m in zip(pred_labels, target, mask, strict=True):
        if m and t != ignore_index:
            cm[t, p] += 1
    return cm


def ref_seg_scores(cm):
    """mIoU over classes with a non-empty union, pixel accuracy, per-class IoU (NaN if union is empty)."""
    ious = []
    for c in range(cm.shape[0]):
        tp = cm[c, c]
        fp = cm[:, c].sum() - tp
        fn = cm[c, :].sum() - tp
        union = tp + fp + fn
        ious.append(tp / union if union > 0 else float("nan"))
    present = [v for v in ious if not np.isnan(v)]
    miou = float(np.mean(present)) if present else float("nan")
    acc = float(np.trace(cm) / cm.sum()) if cm.sum() > 0 else float("nan")
    return miou, acc, ious


def ref_compute_errors(gt, pred):
    """AdaBins ``evaluate.py`` ``compute_errors`` (on 1-D arrays of valid pixels)."""
    thresh = np.maximum((gt / pred), (pred / gt))
    a1 = (thresh < 1.25).mean()
    a2 = (thresh < 1.25**2).mean()
    a3 = (thresh < 1.25**3).mean()
    abs_rel = np.mean(np.abs(gt - pred) / gt)
    sq_rel = np.mean(((gt - pred) ** 2) / gt)
    rmse = np.sqrt(((gt - pred) ** 2).mean())
    rmse_log = np.sqrt(((np.log(gt) - np.log(pred)) ** 2).mean())
    err = np.log(pred) - np.log(gt)
    silog = np.sqrt(np.mean(err**2) - np.mean(err) ** 2) * 100
    log_10 = (np.abs(np.log10(gt) - np.log10(pred))).mean()
    return {
        "abs_rel": abs_rel,
        "sq_rel": sq_rel,
        "rmse": rmse,
        "rmse_log": rmse_log,
        "log10": log_10,
        "silog": silog,
        "delta1": a1,
        "delta2": a2,
        "delta3": a3,
    }


def ref_depth_image(gt, pred, min_depth, max_depth, mask=None):
    """AdaBins evaluation of one image: inf/nan handling, clipping, valid mask (upper bound inclusive)."""
    gt = np.asarray(gt, dtype=np.float64)
    pred = np.asarray(pred, dtype=np.float64).copy()
    pred[np.isinf(pred) & (pred > 0)] = max_depth
    pred[np.isnan(pred) | np.isneginf(pred)] = min_depth
    pred = np.clip(pred, min_depth, max_depth)
    with np.errstate(invalid="ignore"):
        valid = (gt > min_depth) & (gt <= max_depth)
    if mask is not None:
        valid &= mask
    if not valid.any():
        return None
    return ref_compute_errors(gt[valid], pred[valid])


def ref_nlspn_image(gt, pred, max_depth, mask=None):
    """NLSPN ``NLSPNMetric.evaluate`` on one image, with the prediction clamped to [0, max_depth]."""
    t_valid = 0.0001
    gt = np.asarray(gt, dtype=np.float64)
    pred = np.asarray(pred, dtype=np.float64).copy()
    pred[np.isnan(pred)] = 0.0
    pred = np.clip(pred, 0.0, max_depth)  # clips +-inf too
    with np.errstate(invalid="ignore"):
        valid = (gt > t_valid) & (gt <= max_depth)
    if mask is not None:
        valid &= mask
    if not valid.any():
        return None
    pred_inv = 1.0 / (pred + 1e-8)
    gt_inv = 1.0 / (gt + 1e-8)
    pred, gt = pred[valid], gt[valid]
    pred_inv, gt_inv = pred_inv[valid], gt_inv[valid]
    pred_inv[pred <= t_valid] = 0.0
    n = valid.sum()
    diff = pred - gt
    diff_inv = pred_inv - gt_inv
    ratio = np.maximum(gt / (pred + 1e-8), pred / (gt + 1e-8))
    return {
        "abs_rel": (np.abs(diff) / (gt + 1e-8)).sum() / n,
        "rmse": np.sqrt((diff**2).sum() / n),
        "mae": np.abs(diff).sum() / n,
        "irmse": np.sqrt((diff_inv**2).sum() / n),
        "imae": np.abs(diff_inv).sum() / n,
        "delta1": (ratio < 1.25).sum() / n,
        "delta2": (ratio < 1.25**2).sum() / n,
        "delta3": (ratio < 1.25**3).sum() / n,
    }


def ref_average(per_image):
    """Mean over images of per-image dicts, skipping images without a valid pixel (None)."""
    valid = [d for d in per_image if d is not None]
    if not valid:
        return None
    return {k: float(np.mean([d[k] for d in valid])) for k in valid[0]}
