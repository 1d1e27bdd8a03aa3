"""Semantic segmentation with any segmentation-models-pytorch architecture and encoder."""

from __future__ import annotations

import os

import segmentation_models_pytorch as smp
import torch
from torch import Tensor, nn

from models.camera_input import (
    RAY_MAP_CHANNELS,
    check_camera_input,
    check_rays,
    resize_rays,
    widen_conv,
    widen_first_conv,
)
from models.input_checks import check_image
from models.weights import (
    build_smp_with_encoder_weights,
    load_weights,
    resolve_weights_path,
    weights_identity,
)


class SmpSegmentationModel(nn.Module):
    """A segmentation-models-pytorch network behind the zoo's calling convention.

    ``forward(image, rays=None)`` returns logits ``[B, num_classes, H, W]`` at the input resolution;
    ``forward_with_aux(image, rays=None)`` returns ``{"logits": ...}``. Input is validated up front: the image must be
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
        camera_input: ``"none"`` or ``"rays"``: the ray map ``rays`` ``[B, 4, H, W]`` enters the encoder's first
            convolution (4 more input channels, their weights zero) and, for DeepLabV3+, the decoder's fusion of
            the ASPP and stride-4 features (:mod:`models.camera_input`).
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
        camera_input: str = "none",
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
        self.camera_input = check_camera_input(camera_input)
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
        #: Whether the ray map also meets the decoder's features (DeepLabV3+: before its last fusion block).
        self.rays_in_decoder = self.camera_input == "rays" and self.arch == "deeplabv3plus"
        if self.camera_input == "rays":
            widen_first_conv(self.net.encoder, RAY_MAP_CHANNELS, in_channels)
        if (
            self.rays_in_decoder
        ):  # block2 fuses [ASPP, stride-4 features]: a separable conv, both halves widened
            fusion = self.net.decoder.block2[0]
            fusion[0], fusion[1] = (widen_conv(conv, RAY_MAP_CHANNELS) for conv in fusion)
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

    def forward(self, image: Tensor, rays: Tensor | None = None) -> Tensor:
        """Logits ``[B, num_classes, H, W]`` for a normalised image batch ``[B, in_channels, H, W]`` (and, with
        ``camera_input="rays"``, its ray map ``[B, 4, H, W]``)."""
        check_image(image, self.in_channels, self.output_stride)
        check_rays(rays, image, self.camera_input)
        if rays is None:
            return self.net(image)
        x = torch.cat([image, rays], dim=1)
        if not self.rays_in_decoder:
            return self.net(x)
        # smp's DeepLabV3PlusDecoder.forward with the ray map concatenated before its fusion block.
        features = self.net.encoder(x)
        decoder = self.net.decoder
        context = decoder.up(decoder.aspp(features[-1]))
        high_res = decoder.block1(features[2])
        fused = decoder.block2(torch.cat([context, high_res, resize_rays(rays, high_res.shape[-2:])], dim=1))
        masks = self.net.segmentation_head(fused)
        if self.net.classification_head is not None:  # smp's aux_params: what smp's forward returns then
            return masks, self.net.classification_head(features[-1])
        return masks

    def forward_with_aux(self, image: Tensor, rays: Tensor | None = None) -> dict[str, Tensor]:
        """``{"logits": forward(image, rays)}`` (segmentation needs no auxiliary output)."""
        return {"logits": self(image, rays)}
