"""The camera as a model input (``camera_input="rays"``): the ray map beside the image (docs/design.md, "Ray map").

Every model of the zoo takes ``camera_input``: ``"none"`` (the default: the model, its state dict and its ONNX graph
are those of a model without the option) or ``"rays"``, the ray map ``[B, 4, H, W]``
(:func:`airfisheye_bench.geometry.ray_maps.ray_map`) as the keyword input ``rays``. It enters, as in CAM-Convs
(arXiv 1904.02028), at the input (the image's first convolution takes ``3 + 4`` channels) and, where the
architecture has a clean place for it, concatenated to decoder features at their resolution. Every weight that reads
the ray map starts at zero (:func:`widen_conv`), so pretrained encoder weights keep their meaning: an untrained ray
path leaves the encoder's first layer what ImageNet made it.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from airfisheye_bench.geometry.ray_maps import RAY_MAP_CHANNELS, check_camera_input

__all__ = [
    "RAY_MAP_CHANNELS",
    "check_camera_input",
    "check_rays",
    "resize_rays",
    "widen_conv",
    "widen_first_conv",
]


def check_rays(rays: Tensor | None, image: Tensor, camera_input: str) -> None:
    """Check the ``rays`` a model built with ``camera_input`` was given: ``[B, 4, H, W]`` of ``image`` for
    ``"rays"``, none for ``"none"``.

    Raises:
        ValueError: one line saying what the model takes and how to give it.

    Example:
        >>> check_rays(None, torch.zeros(1, 3, 8, 8), "rays")
        Traceback (most recent call last):
        ...
        ValueError: this model was built with camera_input=rays and needs rays, the ray map [B, 4, H, W] of its camera (geometry.ray_maps.ray_map; the datamodule serves it as batch['rays'] with data.camera_input=rays)
    """
    if camera_input == "none":
        if rays is not None:
            raise ValueError(
                "this model was built with camera_input=none and takes no rays; build it with camera_input=rays "
                "(model.camera_input=rays) to feed the ray map"
            )
        return
    if rays is None:
        raise ValueError(
            "this model was built with camera_input=rays and needs rays, the ray map [B, 4, H, W] of its camera "
            "(geometry.ray_maps.ray_map; the datamodule serves it as batch['rays'] with data.camera_input=rays)"
        )
    if not isinstance(rays, Tensor):
        raise ValueError(f"rays must be a torch.Tensor, got {type(rays).__name__}")
    # Sizes compared without int(): that would pin a dynamic (exported) batch size to the example's.
    same = rays.ndim == 4 and rays.shape[1] == RAY_MAP_CHANNELS
    same = same and rays.shape[0] == image.shape[0] and rays.shape[2:] == image.shape[2:]
    if not same:
        expected = [image.shape[0], RAY_MAP_CHANNELS, image.shape[-2], image.shape[-1]]
        raise ValueError(
            f"rays must have shape {list(map(int, expected))} (batch and size of image), got {list(rays.shape)}"
        )


def resize_rays(rays: Tensor, size: tuple[int, int] | torch.Size) -> Tensor:
    """The ray map at a feature map's ``size`` (bilinear; CAM-Convs resize their maps to each decoder level)."""
    if tuple(rays.shape[-2:]) == tuple(size):
        return rays
    return F.interpolate(rays, size=size, mode="bilinear", align_corners=False)


def widen_conv(conv: nn.Conv2d, extra: int) -> nn.Conv2d:
    """A copy of ``conv`` that reads ``extra`` more input channels after its own, their weights zero: on inputs
    whose extra channels are anything, it gives ``conv``'s output until training moves them.

    A depthwise convolution (``groups == in_channels``) gets ``extra`` more groups with a fresh initialisation
    instead (a zero filter there would pass nothing to train the next layer's zero weights with).

    Example:
        >>> conv = nn.Conv2d(3, 8, 3, padding=1)
        >>> wide = widen_conv(conv, 4)
        >>> x = torch.randn(1, 3, 5, 5)
        >>> bool(torch.equal(wide(torch.cat([x, torch.randn(1, 4, 5, 5)], 1)), conv(x)))
        True
    """
    depthwise = conv.groups == conv.in_channels and conv.groups > 1
    if conv.groups != 1 and not depthwise:
        raise ValueError(
            f"cannot widen a grouped convolution ({conv.groups} groups of {conv.in_channels} channels)"
        )
    channels = conv.in_channels + extra
    wide = nn.Conv2d(
        channels,
        channels if depthwise else conv.out_channels,
        conv.kernel_size,
        stride=conv.stride,
        padding=conv.padding,
        dilation=conv.dilation,
        groups=channels if depthwise else 1,
        bias=conv.bias is not None,
        padding_mode=conv.padding_mode,
    ).to(device=conv.weight.device, dtype=conv.weight.dtype)
    with torch.no_grad():
        if depthwise:
            wide.weight[: conv.in_channels] = conv.weight
            if conv.bias is not None:
                wide.bias[: conv.in_channels] = conv.bias
        else:
            wide.weight.zero_()
            wide.weight[:, : conv.in_channels] = conv.weight
            if conv.bias is not None:
                wide.bias.copy_(conv.bias)
    return wide


def widen_first_conv(module: nn.Module, extra: int, in_channels: int = 3) -> None:
    """Make the first convolution of ``module`` that reads ``in_channels`` channels read ``extra`` more
    (:func:`widen_conv`, in place): an encoder then takes the image with the ray map concatenated.

    Raises:
        ValueError: ``module`` has no such convolution.
    """
    for name, child in module.named_modules():
        if isinstance(child, nn.Conv2d) and child.in_channels == in_channels:
            parent_name, _, attr = name.rpartition(".")
            parent = module.get_submodule(parent_name) if parent_name else module
            setattr(parent, attr, widen_conv(child, extra))
            return
    raise ValueError(f"{type(module).__name__} has no convolution of {in_channels} input channels to widen")
