"""AdaBins' U-Net decoder (``DecoderBN`` of the official code), generalised to any smp encoder."""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from models.camera_input import resize_rays, widen_conv


class UpSampleBN(nn.Module):
    """Upsample to the skip's size (bilinear, ``align_corners=True``), concatenate, two conv3x3-BN-LeakyReLU.

    The official convs carry a bias; it is dropped here because a bias directly before a training-mode
    BatchNorm is cancelled by the mean subtraction (it would only ever get a zero gradient).
    """

    def __init__(self, skip_input: int, output_features: int) -> None:
        super().__init__()
        self._net = nn.Sequential(
            nn.Conv2d(skip_input, output_features, kernel_size=3, stride=1, padding=1, bias=False),
            nn.BatchNorm2d(output_features),
            nn.LeakyReLU(),
            nn.Conv2d(output_features, output_features, kernel_size=3, stride=1, padding=1, bias=False),
            nn.BatchNorm2d(output_features),
            nn.LeakyReLU(),
        )

    def forward(self, x: Tensor, concat_with: Tensor, rays: Tensor | None = None) -> Tensor:
        up_x = F.interpolate(x, size=concat_with.shape[-2:], mode="bilinear", align_corners=True)
        parts = (
            [up_x, concat_with] if rays is None else [up_x, concat_with, resize_rays(rays, up_x.shape[-2:])]
        )
        return self._net(torch.cat(parts, dim=1))

    def read_rays(self, channels: int) -> None:
        """Take ``channels`` more inputs after the skip (the ray map, CAM-Convs style), their weights zero."""
        self._net[0] = widen_conv(self._net[0], channels)


class DecoderBN(nn.Module):
    """Decoder from stride 32 back to stride 2, with skips at strides 16, 8, 4 and 2.

    Args:
        encoder_channels: channels of the smp encoder outputs at strides ``[1, 2, 4, 8, 16, 32]``
            (``encoder.out_channels``; the stride-1 entry is the input and is unused).
        num_features: width after the bottleneck conv; halves at each of the four up blocks
            (official: 2048 -> 1024 -> 512 -> 256 -> 128).
        out_channels: channels of the output (128, the mini-ViT input).
        ray_channels: channels of a ray map concatenated to every up block's input, resized to its resolution
            (``camera_input="rays"``: 4; 0: none, the decoder of the official code).

    Returns (forward):
        Features ``[B, out_channels, H/2, W/2]``; ``forward(features, rays)`` with ``ray_channels``.

    Example:
        >>> dec = DecoderBN([3, 8, 8, 16, 32, 64], num_features=64, out_channels=16)
        >>> feats = [torch.randn(1, c, 64 // s, 64 // s) for c, s in zip([3, 8, 8, 16, 32, 64], [1, 2, 4, 8, 16, 32])]
        >>> dec(feats).shape
        torch.Size([1, 16, 32, 32])
    """

    def __init__(
        self,
        encoder_channels: Sequence[int],
        num_features: int = 2048,
        out_channels: int = 128,
        ray_channels: int = 0,
    ) -> None:
        super().__init__()
        if len(encoder_channels) != 6:
            raise ValueError(
                f"encoder_channels must list 6 stages (strides 1..32), got {list(encoder_channels)}"
            )
        if num_features % 16:
            raise ValueError(f"num_features must be divisible by 16, got {num_features}")
        _, c2, c4, c8, c16, c32 = encoder_channels
        f = num_features
        # Upstream quirk kept for fidelity: a 1x1 conv with padding=1 grows the bottleneck by a 1-px border of
        # bias values; up1 then resizes it to the stride-16 skip.
        self.conv2 = nn.Conv2d(c32, f, kernel_size=1, stride=1, padding=1)
        self.up1 = UpSampleBN(f + c16, f // 2)
        self.up2 = UpSampleBN(f // 2 + c8, f // 4)
        self.up3 = UpSampleBN(f // 4 + c4, f // 8)
        self.up4 = UpSampleBN(f // 8 + c2, f // 16)
        self.conv3 = nn.Conv2d(f // 16, out_channels, kernel_size=3, stride=1, padding=1)
        if ray_channels:
            for up in (self.up1, self.up2, self.up3, self.up4):
                up.read_rays(ray_channels)

    def forward(self, features: Sequence[Tensor], rays: Tensor | None = None) -> Tensor:
        _, x2, x4, x8, x16, x32 = features
        x = self.conv2(x32)
        x = self.up1(x, x16, rays)
        x = self.up2(x, x8, rays)
        x = self.up3(x, x4, rays)
        x = self.up4(x, x2, rays)
        return self.conv3(x)
