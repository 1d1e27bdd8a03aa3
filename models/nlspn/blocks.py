"""Building blocks of the NLSPN encoder-decoder: conv / transposed-conv units and the ResNet encoder stages.

The layer structure (``nn.Sequential`` of conv, optional BN, LeakyReLU(0.2)) follows the official code
(zzangjinsun/NLSPN_ECCV20, ``src/model/common.py``) so that parameter names line up with its checkpoints.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import torch
import torchvision
from torch import nn

__all__ = ["ENCODERS", "conv_bn_relu", "convt_bn_relu", "resnet_stages"]

#: ResNet encoders the official code supports; both use BasicBlocks with 64/128/256/512 channels.
ENCODERS: dict[str, Callable[..., torchvision.models.ResNet]] = {
    "resnet18": torchvision.models.resnet18,
    "resnet34": torchvision.models.resnet34,
}


def conv_bn_relu(
    in_channels: int,
    out_channels: int,
    kernel_size: int = 3,
    stride: int = 1,
    bn: bool = True,
    relu: bool = True,
) -> nn.Sequential:
    """``Conv2d`` (``same`` padding for stride 1) -> optional ``BatchNorm2d`` -> optional ``LeakyReLU(0.2)``.

    The convolution has a bias only when there is no batch norm (as upstream).

    Example:
        >>> conv_bn_relu(3, 8, stride=2)(torch.zeros(1, 3, 9, 9)).shape
        torch.Size([1, 8, 5, 5])
    """
    if kernel_size % 2 != 1:
        raise ValueError(f"kernel_size must be odd, got {kernel_size}")
    layers: list[nn.Module] = [
        nn.Conv2d(in_channels, out_channels, kernel_size, stride, kernel_size // 2, bias=not bn)
    ]
    if bn:
        layers.append(nn.BatchNorm2d(out_channels))
    if relu:
        layers.append(nn.LeakyReLU(0.2, inplace=True))
    return nn.Sequential(*layers)


def convt_bn_relu(in_channels: int, out_channels: int, kernel_size: int = 3) -> nn.Sequential:
    """Stride-2 ``ConvTranspose2d`` that exactly doubles the size -> ``BatchNorm2d`` -> ``LeakyReLU(0.2)``.

    Example:
        >>> convt_bn_relu(8, 4)(torch.zeros(1, 8, 5, 7)).shape
        torch.Size([1, 4, 10, 14])
    """
    if kernel_size % 2 != 1:
        raise ValueError(f"kernel_size must be odd, got {kernel_size}")
    return nn.Sequential(
        nn.ConvTranspose2d(
            in_channels,
            out_channels,
            kernel_size,
            stride=2,
            padding=kernel_size // 2,
            output_padding=1,
            bias=False,
        ),
        nn.BatchNorm2d(out_channels),
        nn.LeakyReLU(0.2, inplace=True),
    )


def resnet_stages(name: str = "resnet34", weights: str | os.PathLike | None = None) -> list[nn.Sequential]:
    """The four residual stages (``layer1`` .. ``layer4``) of a torchvision ResNet, without its stem.

    NLSPN feeds its own full-resolution stem (64 channels) into ``layer1``, so the stages run at strides
    1, 1/2, 1/4 and 1/8 of the input with 64, 128, 256 and 512 channels.

    Args:
        name: ``"resnet18"`` or ``"resnet34"`` (the official choices; ``resnet34`` is the paper's).
        weights: optional path to a local torchvision ResNet ``state_dict`` (e.g. ImageNet weights saved with
            ``torch.save(resnet34(weights=...).state_dict(), path)``). Nothing is ever downloaded.

    Returns:
        ``[layer1, layer2, layer3, layer4]``.

    Raises:
        ValueError: unknown ``name``, or a weight file without the stage parameters (or with wrong shapes).

    Example:
        >>> [s[0].conv1.out_channels for s in resnet_stages("resnet18")]
        [64, 128, 256, 512]
    """
    if name not in ENCODERS:
        raise ValueError(f"encoder must be one of {sorted(ENCODERS)}, got {name!r}")
    net = ENCODERS[name](weights=None)
    if weights is not None:
        _load_stage_weights(net, Path(weights), name)
    return [net.layer1, net.layer2, net.layer3, net.layer4]


def _load_stage_weights(net: nn.Module, path: Path, name: str) -> None:
    if not path.is_file():
        raise ValueError(f"encoder weights file {str(path)!r} does not exist")
    state = torch.load(path, map_location="cpu", weights_only=True)
    if isinstance(state, dict) and "state_dict" in state:  # a checkpoint wrapping the state dict
        state = state["state_dict"]
    # Only the stages are used; the stem and fc may be missing or absent without harm.
    stages = {k: v for k, v in state.items() if k.split(".")[0] in ("layer1", "layer2", "layer3", "layer4")}
    expected = {k for k in net.state_dict() if k.split(".")[0] in ("layer1", "layer2", "layer3", "layer4")}
    missing, unexpected = sorted(expected - set(stages)), sorted(set(stages) - expected)
    if missing or unexpected:
        example = (missing or unexpected)[0]
        raise ValueError(
            f"encoder weights {str(path)!r} do not fit the {name} stages: {len(missing)} missing and "
            f"{len(unexpected)} unexpected tensors (e.g. {example!r}); expected a torchvision ResNet state_dict "
            "of the same depth"
        )
    try:
        net.load_state_dict(stages, strict=False)
    except RuntimeError as err:  # shape mismatch, e.g. resnet18 weights for resnet34
        raise ValueError(f"encoder weights {str(path)!r} do not fit this encoder: {err}") from None
