"""Semantic segmentation with any segmentation-models-pytorch architecture and encoder."""

from __future__ import annotations

import os

import segmentation_models_pytorch as smp
from torch import Tensor, nn

from models.input_checks import check_image
from models.weights import (
    build_smp_with_encoder_weights,
    load_weights,
    resolve_weights_path,
    weights_identity,
)


class SmpSegmentationModel(nn.Module):
    """A segmentation-models-pytorch network behind the zoo's calling convention.

    ``forward(image)`` returns logits ``[B, num_classes, H, W]`` at the input resolution;
    ``forward_with_aux(image)`` returns ``{"logits": ...}``. Input is validated up front: the image must be
    ``[B, in_channels, H, W]`` with H and W multiples of :attr:`output_stride` (the error says what to pad to).

    Args:
        arch: smp architecture name (``"deeplabv3plus"``, ``"unet"``, ``"fpn"``, ...; see
            ``smp.MODEL_ARCHITECTURES_MAPPING``).
        encoder_name: smp encoder (``"resnet50"``, ...) or any timm model as ``"tu-<name>"``.
        num_classes: output channels (training classes; 13 in the paper).
        in_channels: input channels.
        encoder_weights: ``None`` (random), ``"imagenet"`` (fetched through smp into the Hugging Face cache) or
            a local file with encoder weights, e.g. a torchvision/timm ImageNet ResNet ``state_dict`` (smp's
            ResNet encoders drop the ``fc.*`` keys); see :mod:`models.weights`.
        weights_path: local file with weights for the whole model (state dict or Lightning checkpoint).
        **arch_kwargs: passed to the smp architecture (e.g. ``encoder_output_stride``, ``decoder_channels``).

    Attributes:
        weights_identity: what the weights started from (:func:`models.weights.weights_identity`).

    Example:
        >>> import torch
        >>> net = SmpSegmentationModel("fpn", "resnet18", num_classes=4).eval()
        >>> net(torch.randn(1, 3, 64, 96)).shape
        torch.Size([1, 4, 64, 96])
    """

    def __init__(
        self,
        arch: str = "deeplabv3plus",
        encoder_name: str = "resnet50",
        num_classes: int = 13,
        in_channels: int = 3,
        encoder_weights: str | os.PathLike | None = None,
        weights_path: str | os.PathLike | None = None,
        **arch_kwargs,
    ) -> None:
        super().__init__()
        if num_classes < 1:
            raise ValueError(f"num_classes must be >= 1, got {num_classes}")
        if arch.lower() not in smp.MODEL_ARCHITECTURES_MAPPING:
            raise ValueError(f"arch must be one of {sorted(smp.MODEL_ARCHITECTURES_MAPPING)}, got {arch!r}")
        self.arch = arch.lower()
        self.num_classes = num_classes
        self.in_channels = in_channels
        if "decoder_atrous_rates" in arch_kwargs:  # a YAML list; smp documents a tuple
            arch_kwargs["decoder_atrous_rates"] = tuple(arch_kwargs["decoder_atrous_rates"])

        def build(weights: str | bool | None) -> nn.Module:
            return smp.create_model(
                self.arch,
                encoder_name=encoder_name,
                encoder_weights=weights,
                in_channels=in_channels,
                classes=num_classes,
                **arch_kwargs,
            )

        self.net, encoder_record = build_smp_with_encoder_weights(
            build, encoder_name, encoder_weights, encoder_of=lambda net: net.encoder
        )
        weights_path = resolve_weights_path(weights_path)
        if weights_path is not None:
            load_weights(self, weights_path, what="weights_path")
        self.weights_identity = weights_identity(encoder_record, weights_path)

    @property
    def output_stride(self) -> int:
        """H and W must be multiples of this (1 for architectures that take any size, e.g. smp's Unet)."""
        if not getattr(self.net, "requires_divisible_input_shape", True):
            return 1
        return int(self.net.encoder.output_stride)

    def forward(self, image: Tensor) -> Tensor:
        """Logits ``[B, num_classes, H, W]`` for a normalised image batch ``[B, in_channels, H, W]``."""
        check_image(image, self.in_channels, self.output_stride)
        return self.net(image)

    def forward_with_aux(self, image: Tensor) -> dict[str, Tensor]:
        """``{"logits": forward(image)}`` (segmentation needs no auxiliary output)."""
        return {"logits": self(image)}
