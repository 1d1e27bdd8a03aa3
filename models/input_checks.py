"""Input validation shared by the models of the zoo.

The checks run on concrete shapes, so they cost nothing at export time (torch.export sees them as guards on
static sizes) and turn shape mistakes into a clear ``ValueError`` instead of a cryptic error deep in a conv.
"""

from __future__ import annotations

import math

from torch import Tensor


def check_image(image: Tensor, in_channels: int, divisor: int = 1, name: str = "image") -> None:
    """Check that ``image`` is ``[B, in_channels, H, W]`` with ``H`` and ``W`` divisible by ``divisor``.

    Args:
        image: the input batch.
        in_channels: expected channel count.
        divisor: the model's output stride (H and W must be multiples of it); 1 disables the check.
        name: argument name used in error messages.

    Raises:
        ValueError: wrong rank or channels, or a size not divisible by ``divisor`` (the message says what
            size to pad to).

    Example:
        >>> import torch
        >>> check_image(torch.zeros(1, 3, 64, 96), in_channels=3, divisor=32)
        >>> check_image(torch.zeros(1, 3, 70, 96), in_channels=3, divisor=32)
        Traceback (most recent call last):
        ...
        ValueError: image height and width must be divisible by 32, got 70x96; pad it to 96x96 (e.g. with torch.nn.functional.pad)
    """
    if not isinstance(image, Tensor):
        raise ValueError(f"{name} must be a torch.Tensor, got {type(image).__name__}")
    if image.ndim != 4 or image.shape[1] != in_channels:
        raise ValueError(f"{name} must have shape [B, {in_channels}, H, W], got {list(image.shape)}")
    h, w = int(image.shape[-2]), int(image.shape[-1])
    if divisor > 1 and (h % divisor or w % divisor):
        pad_h, pad_w = math.ceil(h / divisor) * divisor, math.ceil(w / divisor) * divisor
        raise ValueError(
            f"{name} height and width must be divisible by {divisor}, got {h}x{w}; "
            f"pad it to {pad_h}x{pad_w} (e.g. with torch.nn.functional.pad)"
        )


def check_sparse_depth(sparse_depth: Tensor, image: Tensor, name: str = "sparse_depth") -> None:
    """Check that ``sparse_depth`` is ``[B, 1, H, W]`` with the batch size and spatial size of ``image``.

    Example:
        >>> import torch
        >>> check_sparse_depth(torch.zeros(2, 1, 8, 8), torch.zeros(2, 3, 8, 8))
        >>> check_sparse_depth(torch.zeros(2, 8, 8), torch.zeros(2, 3, 8, 8))
        Traceback (most recent call last):
        ...
        ValueError: sparse_depth must have shape [2, 1, 8, 8] (batch and size of image), got [2, 8, 8]
    """
    if not isinstance(sparse_depth, Tensor):
        raise ValueError(f"{name} must be a torch.Tensor, got {type(sparse_depth).__name__}")
    # Compare sizes without int(): that would pin a dynamic (exported) batch size to the example's.
    same = sparse_depth.ndim == 4 and sparse_depth.shape[1] == 1
    same = same and sparse_depth.shape[0] == image.shape[0] and sparse_depth.shape[2:] == image.shape[2:]
    if not same:
        expected = [image.shape[0], 1, image.shape[-2], image.shape[-1]]
        raise ValueError(
            f"{name} must have shape {list(map(int, expected))} (batch and size of image), got {list(sparse_depth.shape)}"
        )
