"""AdaBins (Bhat et al., CVPR 2021): monocular depth as a per-pixel mixture of adaptive bin centres."""

from __future__ import annotations

import math
import os
from collections.abc import Iterator

import torch
import torch.nn.functional as F
from segmentation_models_pytorch.encoders import get_encoder
from torch import Tensor, nn

from models.adabins.decoder import DecoderBN
from models.adabins.mini_vit import BIN_NORMS, MiniViT
from models.camera_input import RAY_MAP_CHANNELS, check_camera_input, check_rays, widen_first_conv
from models.input_checks import check_image
from models.weights import (
    build_smp_with_encoder_weights,
    load_weights,
    resolve_weights_path,
    weights_identity,
)


class UnetAdaptiveBins(nn.Module):
    """AdaBins' ``UnetAdaptiveBins`` with a pluggable smp/timm encoder (ResNet50 in the AirFisheye paper).

    Pipeline (as the official code): encoder -> U-Net decoder at 1/2 resolution (``decoder_out_channels``
    features) -> mini-ViT, which gives normalised bin widths from a global token and ``n_query_channels``
    range-attention maps -> 1x1 conv + softmax over bins -> depth = sum(probability x bin centre). Bin edges
    are ``min_depth + cumsum(widths * (max_depth - min_depth))``; the half-resolution depth is upsampled to the
    input size (bilinear, ``align_corners=True``, as the official loss and inference do).

    Args:
        encoder_name: smp encoder (``"resnet50"``, ``"efficientnet-b5"``, ...) or ``"tu-<timm name>"``.
        n_bins: number of adaptive bins (256 in the paper).
        min_depth: lower end of the depth range in metres (edge 0).
        max_depth: upper end of the depth range in metres (last edge).
        norm: bin-width normalisation, ``"linear"``, ``"softmax"`` or ``"sigmoid"``.
        in_channels: input channels.
        encoder_weights: ``None`` (random), ``"imagenet"`` (fetched through smp into the Hugging Face cache; the
            official code starts from an ImageNet EfficientNet-B5) or a local file with encoder weights, e.g. a
            torchvision/timm ResNet50 ``state_dict``; see :mod:`models.weights`.
        weights_path: local file with weights for the whole model (state dict or Lightning checkpoint).
        decoder_features: decoder width after the bottleneck (halved 4 times); default: the encoder's deepest
            channel count (2048 for ResNet50, as the official 2048).
        decoder_out_channels: decoder output channels = mini-ViT input (128).
        patch_size: mini-ViT patch size on the 1/2-resolution features (16).
        embedding_dim: transformer token size (128).
        num_heads: attention heads (4).
        num_layers: transformer layers (4).
        dim_feedforward: transformer MLP width (1024).
        n_query_channels: number of range-attention maps (128); needs ``(H/2/patch) * (W/2/patch) > n_query``.
        pos_grid_size: side of the learned positional grid, resized to the patch grid (16 = 512x512 input).
        camera_input: ``"none"`` or ``"rays"``: the ray map ``rays`` ``[B, 4, H, W]`` enters the encoder's first
            convolution (4 more input channels, their weights zero) and is concatenated, resized, to the input of
            each of the decoder's four up blocks (CAM-Convs style; :mod:`models.camera_input`).

    Attributes:
        weights_identity: what the weights started from (:func:`models.weights.weights_identity`).

    Example:
        >>> net = UnetAdaptiveBins("resnet18", n_bins=16, decoder_features=64, decoder_out_channels=16,
        ...                        patch_size=4, embedding_dim=16, num_heads=2, num_layers=1,
        ...                        dim_feedforward=32, n_query_channels=16, pos_grid_size=8).eval()
        >>> out = net.forward_with_aux(torch.randn(1, 3, 64, 96))
        >>> out["depth"].shape, out["depth_lowres"].shape, out["bin_edges"].shape
        (torch.Size([1, 1, 64, 96]), torch.Size([1, 1, 32, 48]), torch.Size([1, 17]))
    """

    def __init__(
        self,
        encoder_name: str = "resnet50",
        n_bins: int = 256,
        min_depth: float = 1e-3,
        max_depth: float = 120.0,
        norm: str = "linear",
        in_channels: int = 3,
        encoder_weights: str | os.PathLike | None = None,
        weights_path: str | os.PathLike | None = None,
        decoder_features: int | None = None,
        decoder_out_channels: int = 128,
        patch_size: int = 16,
        embedding_dim: int = 128,
        num_heads: int = 4,
        num_layers: int = 4,
        dim_feedforward: int = 1024,
        n_query_channels: int = 128,
        pos_grid_size: int = 16,
        camera_input: str = "none",
    ) -> None:
        super().__init__()
        if not 0 < min_depth < max_depth:
            raise ValueError(
                f"need 0 < min_depth < max_depth, got min_depth={min_depth}, max_depth={max_depth}"
            )
        if n_bins < 1:
            raise ValueError(f"n_bins must be >= 1, got {n_bins}")
        if norm not in BIN_NORMS:
            raise ValueError(f"norm must be one of {BIN_NORMS}, got {norm!r}")
        if embedding_dim % num_heads:
            raise ValueError(f"embedding_dim ({embedding_dim}) must be divisible by num_heads ({num_heads})")
        self.n_bins = n_bins
        self.min_depth = float(min_depth)
        self.max_depth = float(max_depth)
        self.in_channels = in_channels
        self.camera_input = check_camera_input(camera_input)
        ray_channels = RAY_MAP_CHANNELS if self.camera_input == "rays" else 0

        def build_encoder(weights: str | bool | None) -> nn.Module:
            return get_encoder(encoder_name, in_channels=in_channels, depth=5, weights=weights)

        self.encoder, encoder_record = build_smp_with_encoder_weights(
            build_encoder, encoder_name, encoder_weights
        )
        if ray_channels:
            widen_first_conv(self.encoder, ray_channels, in_channels)
        channels = list(self.encoder.out_channels)
        self.decoder = DecoderBN(
            channels, decoder_features or channels[-1], decoder_out_channels, ray_channels
        )
        self.adaptive_bins_layer = MiniViT(
            decoder_out_channels,
            n_query_channels=n_query_channels,
            patch_size=patch_size,
            n_bins=n_bins,
            embedding_dim=embedding_dim,
            num_heads=num_heads,
            num_layers=num_layers,
            dim_feedforward=dim_feedforward,
            pos_grid_size=pos_grid_size,
            norm=norm,
        )
        self.conv_out = nn.Conv2d(n_query_channels, n_bins, kernel_size=1)
        # The encoder needs multiples of its stride; the mini-ViT needs whole patches on the 1/2-res features.
        self.output_stride = math.lcm(int(self.encoder.output_stride), 2 * patch_size)

        weights_path = resolve_weights_path(weights_path)
        if weights_path is not None:
            load_weights(self, weights_path, what="weights_path")
        self.weights_identity = weights_identity(encoder_record, weights_path)

    def forward(self, image: Tensor, rays: Tensor | None = None) -> Tensor:
        """Depth ``[B, 1, H, W]`` in metres, within ``[min_depth, max_depth]`` (``rays``: the ray map
        ``[B, 4, H, W]`` of a model built with ``camera_input="rays"``)."""
        return self.forward_with_aux(image, rays)["depth"]

    def forward_with_aux(self, image: Tensor, rays: Tensor | None = None) -> dict[str, Tensor]:
        """Depth plus what the AdaBins loss needs.

        Returns:
            ``"depth"`` ``[B, 1, H, W]``; ``"depth_lowres"`` ``[B, 1, H/2, W/2]`` (the network's native output);
            ``"bin_edges"`` ``[B, n_bins + 1]``, increasing from ``min_depth`` to ``max_depth``.
        """
        check_image(image, self.in_channels, self.output_stride)
        check_rays(rays, image, self.camera_input)
        if rays is None:
            features = self.decoder(self.encoder(image))
        else:
            features = self.decoder(self.encoder(torch.cat([image, rays], dim=1)), rays)
        widths_normed, range_attention_maps = self.adaptive_bins_layer(features)
        # conv_out (1x1) + softmax over bins, computed pixels-first ([B, h*w, n_bins]) so the softmax runs over
        # the contiguous last axis: the same maths as the official Conv2d + Softmax(dim=1), and ONNX Runtime
        # avoids a transpose pair around Softmax (which cost ~20 % of its runtime at 384x384).
        h, w = range_attention_maps.shape[-2:]
        pixels = range_attention_maps.flatten(2).transpose(1, 2)  # [B, h*w, Q]
        logits = F.linear(pixels, self.conv_out.weight.flatten(1), self.conv_out.bias)
        probs = torch.softmax(logits, dim=-1)  # [B, h*w, n_bins]

        widths = (self.max_depth - self.min_depth) * widths_normed
        bin_edges = torch.cumsum(F.pad(widths, (1, 0), mode="constant", value=self.min_depth), dim=1)
        centers = 0.5 * (bin_edges[:, :-1] + bin_edges[:, 1:])
        depth_lowres = torch.matmul(probs, centers.unsqueeze(-1)).transpose(1, 2).unflatten(2, (h, w))
        depth = F.interpolate(depth_lowres, size=image.shape[-2:], mode="bilinear", align_corners=True)
        return {"depth": depth, "depth_lowres": depth_lowres, "bin_edges": bin_edges}

    def get_1x_lr_params(self) -> Iterator[nn.Parameter]:
        """Encoder parameters: the official recipe trains them at lr / 10 (``experiment=paper/depth`` does, with
        ``task.module.lr_multipliers: {encoder: 0.1}``, which selects exactly these)."""
        return self.encoder.parameters()

    def get_10x_lr_params(self) -> Iterator[nn.Parameter]:
        """Decoder, mini-ViT and output-head parameters (trained at the full lr)."""
        for module in (self.decoder, self.adaptive_bins_layer, self.conv_out):
            yield from module.parameters()
