"""Elementwise maths that gives the same bits on every CPU, for the values a generated dataset is made of.

torch's CPU ``sqrt``, ``sin``, ``cos``, ``exp`` and ``log`` of a contiguous tensor run through MKL's vector maths,
and MKL picks its code path by processor: its AVX-512, AVX2 and generic paths (the last is what it takes on AMD
CPUs, or with ``MKL_CBWR=COMPATIBLE``) differ in the last bit, for about one float32 square root in six. numpy's
float64 ``sin``/``cos``/``arctan2`` take SVML on AVX-512 CPUs and the C library elsewhere. One bit is enough to round
a written float32 or a pixel the other way, so a dataset's content identity would depend on the machine that
generated it (``docs/design.md``, "Content identity").

Here the square root is the CPU's square-root instruction (IEEE 754 requires it to be correctly rounded, so every
processor gives the same result) and the trigonometric functions are the C library's, element by element (the
same code on every x86-64 CPU with FMA). They are slower than the vector kernels, so the generator uses them
where their results are written, not the training path. CUDA tensors keep torch's functions.

Example:
    >>> x = torch.tensor([2.0, 9.0, 0.5])
    >>> bool(torch.equal(sqrt(x), torch.sqrt(x)))  # the same values, only their last bit is made portable
    True
    >>> float(sin(np.array([np.pi / 2]))[0])
    1.0
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import torch

from airfisheye_bench.geometry._arrays import ArrayLike


def sqrt(x: ArrayLike) -> ArrayLike:
    """Correctly rounded square root of a tensor or array (NaN below 0), in its dtype."""
    if isinstance(x, np.ndarray):
        return np.sqrt(x)
    if x.device.type != "cpu" or x.requires_grad:
        return torch.sqrt(x)
    return torch.from_numpy(np.sqrt(x.numpy()))


def _libm(function: Callable[..., float], *args: ArrayLike) -> ArrayLike:
    """``function`` of the C library applied element by element (broadcast), float64 in, float64 out; a CPU
    tensor in gives a tensor of its dtype back."""
    tensor = next((a for a in args if isinstance(a, torch.Tensor)), None)
    if tensor is not None and (tensor.device.type != "cpu" or tensor.requires_grad):
        raise ValueError("portable maths runs on CPU tensors without gradients")
    arrays = np.broadcast_arrays(
        *(a.detach().numpy() if isinstance(a, torch.Tensor) else np.asarray(a) for a in args)
    )
    flat = [a.astype(np.float64, copy=False).ravel().tolist() for a in arrays]
    out = np.fromiter(map(function, *flat), dtype=np.float64, count=arrays[0].size).reshape(arrays[0].shape)
    if tensor is None:
        return out
    return torch.from_numpy(out).to(tensor.dtype)


def sin(x: ArrayLike) -> ArrayLike:
    """``sin`` from the C library, element by element."""
    return _libm(math.sin, x)


def cos(x: ArrayLike) -> ArrayLike:
    """``cos`` from the C library, element by element."""
    return _libm(math.cos, x)


def arctan2(y: ArrayLike, x: ArrayLike) -> ArrayLike:
    """``atan2(y, x)`` from the C library, element by element (broadcast)."""
    return _libm(math.atan2, y, x)
