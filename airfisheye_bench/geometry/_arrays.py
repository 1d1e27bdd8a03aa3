"""numpy <-> torch plumbing so every geometry function accepts either and answers in kind."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

ArrayLike = np.ndarray | torch.Tensor


def as_tensor(x: Any, name: str, dtype: torch.dtype | None = None) -> tuple[torch.Tensor, bool]:
    """Convert ``x`` to a floating torch tensor; also return whether it came in as numpy.

    Integer inputs are promoted to float32 (pixel coordinates are often integers); float64 stays float64.
    """
    was_numpy = not isinstance(x, torch.Tensor)
    if was_numpy:
        try:
            x = torch.from_numpy(np.asarray(x))
        except TypeError as err:
            raise ValueError(
                f"{name} must be a numeric numpy array or torch tensor, got {type(x).__name__}"
            ) from err
    if dtype is not None:
        x = x.to(dtype)
    elif not x.is_floating_point():
        if x.dtype == torch.bool or x.is_complex():
            raise ValueError(f"{name} must be real-valued, got dtype {x.dtype}")
        x = x.to(torch.float32)
    return x, was_numpy


def back(x: torch.Tensor, was_numpy: bool) -> ArrayLike:
    """Return ``x`` as numpy if the input was numpy."""
    return x.detach().cpu().numpy() if was_numpy else x


def check_last_dim(x: torch.Tensor, size: int, name: str) -> None:
    if x.ndim == 0 or x.shape[-1] != size:
        raise ValueError(f"{name} must have shape [..., {size}], got {tuple(x.shape)}")
