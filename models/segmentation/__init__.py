"""Segmentation models: any segmentation-models-pytorch architecture, and the paper's DeepLabV3+ / ResNet50.

Registered names:

- ``smp``: generic, ``create_model("smp", arch="unet", encoder_name="resnet34", num_classes=13)``.
- ``deeplabv3plus``: the paper baseline (ResNet50 encoder, output stride 16; ``experiment=paper/seg`` sets the
  DeepLabV3+ paper's ASPP rates 6/12/18).
"""

from __future__ import annotations

from models.registry import register_model
from models.segmentation.smp_model import SmpSegmentationModel

__all__ = ["SmpSegmentationModel", "deeplabv3plus", "smp_model"]


@register_model("smp", task="seg")
def smp_model(
    arch: str = "unet", encoder_name: str = "resnet34", num_classes: int = 13, **kwargs
) -> SmpSegmentationModel:
    """Any smp architecture and encoder; see :class:`SmpSegmentationModel` for the arguments.

    Example:
        >>> import models
        >>> net = models.create_model("smp", arch="fpn", encoder_name="resnet18", num_classes=3)
        >>> net.output_stride
        32
    """
    return SmpSegmentationModel(arch=arch, encoder_name=encoder_name, num_classes=num_classes, **kwargs)


@register_model("deeplabv3plus", task="seg")
def deeplabv3plus(
    encoder_name: str = "resnet50", num_classes: int = 13, encoder_output_stride: int = 16, **kwargs
) -> SmpSegmentationModel:
    """DeepLabV3+ as in the paper: ResNet50 encoder, output stride 16, smp's decoder (256 channels, separable
    ASPP; ``decoder_atrous_rates`` and the other smp arguments pass through ``kwargs``).

    smp's default ASPP rates (12, 24, 36) are DeepLabV3's for output stride 8; at stride 16 the DeepLabV3+ paper
    (Chen et al., ECCV 2018) uses (6, 12, 18): on a 512x512 input the stride-16 map is 32x32 and dilations of 24
    and 36 read mostly padding. ``experiment=paper/seg`` sets (6, 12, 18); the quick start keeps smp's default,
    with which its published numbers were measured.

    Example:
        >>> import models
        >>> net = models.create_model("deeplabv3plus", encoder_name="resnet18", num_classes=13)
        >>> net.output_stride
        16
    """
    return SmpSegmentationModel(
        arch="deeplabv3plus",
        encoder_name=encoder_name,
        num_classes=num_classes,
        encoder_output_stride=encoder_output_stride,
        **kwargs,
    )
