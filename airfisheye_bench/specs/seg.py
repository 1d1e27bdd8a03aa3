"""Semantic segmentation (paper IV-A): class logits from the image, dataset-pooled mIoU."""

from __future__ import annotations

from airfisheye_bench.metrics import SegmentationMetrics
from airfisheye_bench.specs.base import Baseline, ExportSpec, MetricColumn, MetricOptions, TaskSpec
from airfisheye_bench.specs.formats import LABELS


def _metric(options: MetricOptions) -> SegmentationMetrics:
    if not options.class_names:
        raise ValueError("the seg metric needs class_names")
    names = list(options.class_names)
    return SegmentationMetrics(len(names), ignore_index=options.ignore_index, class_names=names)


SEG = TaskSpec(
    name="seg",
    title="Semantic segmentation",
    description="per-pixel class of the fisheye image (13 training classes on AirFisheye)",
    inputs=("image",),
    target="label",
    output="logits",
    metric=_metric,
    columns=(
        MetricColumn("mIoU", "mIoU (%)", higher_is_better=True, percent=True),
        MetricColumn("pixel_acc", "pixel acc (%)", higher_is_better=True, percent=True),
    ),
    primary_metric="mIoU",
    prediction=LABELS,
    # The labels carry no depth: the breakdown is by incidence angle only.
    depth_breakdown=False,
    uses_classes=True,
    export=ExportSpec(
        metadata=("class_names", "palette", "ignore_index"),
        atol=1e-4,  # logits: absolute
        rtol=0.0,
        headline=("mIoU", "pixel_acc"),
    ),
    baselines=(Baseline("DeepLabV3+ / ResNet50", "paper IV-A", {"mIoU": 0.512}),),
)
