"""Building blocks of the NLSPN encoder-decoder: conv / transposed-conv units and the ResNet encoder stages.

The layer structure (``nn.Sequential`` of conv, optional BN, LeakyReLU(0.2)) follows the official code
(zzangjinsun/NLSPN_ECCV20, ``src/model/common.py``) so that parameter names line up with its checkpoints.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import torchvision
from torch import Tensor, nn

from models.weights import (
    IMAGENET,
    file_identity,
    read_state_dict,
    resolve_encoder_weights,
    torchvision_imagenet_state,
)

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
        >>> import torch
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
        >>> import torch
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


def resnet_stages(
    name: str = "resnet34", weights: str | os.PathLike | None = None
) -> tuple[list[nn.Sequential], dict[str, Any] | None]:
    """The four residual stages (``layer1`` .. ``layer4``) of a torchvision ResNet, without its stem.

    NLSPN feeds its own full-resolution stem (64 channels) into ``layer1``, so the stages run at strides
    1, 1/2, 1/4 and 1/8 of the input with 64, 128, 256 and 512 channels.

    Args:
        name: ``"resnet18"`` or ``"resnet34"`` (the official choices; ``resnet34`` is the paper's).
        weights: ``None`` (random), ``"imagenet"`` (torchvision's ImageNet weights through the torch hub cache,
            as upstream's ``pretrained/resnet34.pth``) or a local torchvision/timm ResNet ``state_dict`` file;
            see :mod:`models.weights`.

    Returns:
        ``([layer1, layer2, layer3, layer4], record)``, the record of the weights read (``None`` if random).

    Raises:
        ValueError: unknown ``name``, or a weight file without the stage parameters (or with wrong shapes).

    Example:
        >>> stages, record = resnet_stages("resnet18")
        >>> [s[0].conv1.out_channels for s in stages], record
        ([64, 128, 256, 512], None)
    """
    if name not in ENCODERS:
        raise ValueError(f"encoder must be one of {sorted(ENCODERS)}, got {name!r}")
    net = ENCODERS[name](weights=None)
    tag, path = resolve_encoder_weights(weights)
    record = None
    if tag is not None:
        if tag != IMAGENET:
            raise ValueError(f"encoder_weights must be null, 'imagenet' or a local file, got {tag!r}")
        state, record = torchvision_imagenet_state(name)
        _load_stages(net, state, f"torchvision's ImageNet {name}", name)
    elif path is not None:
        _load_stages(net, read_state_dict(path, "encoder_weights"), f"encoder_weights {str(path)!r}", name)
        record = file_identity(path, encoder_weights=str(weights))
    return [net.layer1, net.layer2, net.layer3, net.layer4], record


def _load_stages(net: nn.Module, state: dict[str, Tensor], what: str, name: str) -> None:
    # Only the stages are used; the stem and fc may be missing or absent without harm.
    layers = ("layer1", "layer2", "layer3", "layer4")
    stages = {k: v for k, v in state.items() if k.split(".")[0] in layers}
    expected = {k for k in net.state_dict() if k.split(".")[0] in layers}
    missing, unexpected = sorted(expected - set(stages)), sorted(set(stages) - expected)
    if missing or unexpected:
        example = (missing or unexpected)[0]
        raise ValueError(
            f"{what} do not fit the {name} stages: {len(missing)} missing and {len(unexpected)} unexpected "
            f"tensors (e.g. {example!r}); expected a torchvision ResNet state_dict of the same depth"
        )
    try:
        net.load_state_dict(stages, strict=False)
    except RuntimeError as err:  # shape mismatch, e.g. resnet18 weights for resnet34
        raise ValueError(f"{what} do not fit this encoder: {err}") from None
