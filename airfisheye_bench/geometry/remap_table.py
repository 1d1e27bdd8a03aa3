"""Weighted-gather lookup tables: the one mechanism behind every remap to a camera image (docs/design.md, "Cubemap",
"Equirectangular panoramas").

A remap source (the stacked cube faces, an equirectangular panorama) is flattened to ``L`` texels; a
:class:`RemapTable` lists, for every output pixel it fills, ``T`` texel indices and ``T`` weights. Applying it is a
gather: ``out[p] = sum_t weight[p, t] * src[index[p, t]]`` (an exact copy when ``T = 1``). On CPU a fused numba kernel
applies it in one pass; on other devices ``index_select`` does.

Tables are cached per process in one LRU shared by every source (:data:`TABLES`, keyed by whatever identifies a
table: the source's kind and size, the camera's ``key()``, the orientation, the mode, the supersampling) and, with a
cache directory, on disk as ``<prefix>-<hash>.npz``.
"""

from __future__ import annotations

import hashlib
import json
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.atomic import atomic_write
from airfisheye_bench.geometry import numba_kernels

#: Interpolation modes of every remap: ``nearest`` (labels, depth: values copied exactly) and ``bilinear`` (images).
MODES = ("nearest", "bilinear")


@dataclass(frozen=True)
class RemapTable:
    """A weighted-gather lookup table.

    Attributes:
        pixels: ``[P]`` int64 flat indices (``row * W + col``) of the output pixels that are filled.
        index: ``[P, T]`` int32 flat indices into the flattened source ``[L]`` (cube: ``face * S * S + row * S + col``;
            panorama: ``row * W + col``). Pixel-major, so one pixel's taps are adjacent in memory.
        weight: ``[P, T]`` float32 weights, summing to one over ``T`` for every pixel.
    """

    pixels: torch.Tensor
    index: torch.Tensor
    weight: torch.Tensor


def pack_table(pixels: torch.Tensor, index: torch.Tensor, weight: torch.Tensor) -> RemapTable:
    """Pack ``[T, P]`` indices and weights into a pixel-major :class:`RemapTable`."""
    return RemapTable(pixels, index.T.to(torch.int32).contiguous(), weight.T.to(torch.float32).contiguous())


def filled_mask(table: RemapTable, height: int, width: int) -> torch.Tensor:
    """``[height, width]`` bool: the output pixels a table fills (a source's ``valid_mask``)."""
    mask = torch.zeros(height * width, dtype=torch.bool)
    mask[table.pixels] = True
    return mask.view(height, width)


def apply_table(
    planar: Callable[[], torch.Tensor], interleaved: torch.Tensor | None, lut: RemapTable, out: torch.Tensor
) -> None:
    """Apply ``lut`` to a source, writing into ``out [B, C, H*W]`` (pre-filled with the fill value).

    Args:
        planar: Returns the source as ``[B, C, L]`` (a view where the memory allows, else a copy: called only when
            needed).
        interleaved: The same source as a ``[B, L, 3]`` view when it is three-channel and stored channels last
            (images as a decoder returns them, permuted without a copy), else ``None``; on CPU a bilinear table then
            blends it in place, with no planar copy.
        lut: The table.
        out: The output, on the source's device.

    Nearest tables copy values exactly (any dtype); bilinear ones interpolate in float32 and round integer outputs
    half up (clamped to the dtype's range).
    """
    if out.device.type != "cpu":
        out[..., lut.pixels.to(out.device)] = _apply_torch(planar(), lut)
        return
    pixels, index, weight = lut.pixels.numpy(), lut.index.numpy(), lut.weight.numpy()
    if index.shape[1] == 1:
        numba_kernels.copy_nearest(planar().numpy(), pixels, index[:, 0].copy(), out.numpy())
        return
    is_int = not out.is_floating_point()
    lo, hi = (float(torch.iinfo(out.dtype).min), float(torch.iinfo(out.dtype).max)) if is_int else (0.0, 0.0)
    args = (pixels, index, weight, out.numpy(), is_int, np.float32(lo), np.float32(hi))
    if interleaved is not None:
        numba_kernels.blend_interleaved3(interleaved.numpy(), *args)
    else:
        numba_kernels.blend_planar(planar().numpy(), *args)


def interleaved_view(source: torch.Tensor) -> torch.Tensor | None:
    """``[B, C, *spatial]`` -> a ``[B, L, 3]`` view (no copy) when ``C = 3`` and the memory is channels last, else
    ``None``."""
    if source.shape[1] != 3:
        return None
    last = source.movedim(1, -1)
    return last.reshape(source.shape[0], -1, 3) if last.is_contiguous() else None


def _apply_torch(src: torch.Tensor, lut: RemapTable) -> torch.Tensor:
    """Device-agnostic: planar ``[B, C, L]`` -> ``[B, C, P]``, ``out[..., p] = sum_t w[p, t] * src[..., index[p, t]]``."""
    index = lut.index.T.to(device=src.device, dtype=torch.int64)
    if index.shape[0] == 1:
        return src.index_select(2, index[0])
    weight = lut.weight.T.to(src.device)
    work = src if src.is_floating_point() else src.float()
    acc = work.index_select(2, index[0]) * weight[0].to(work.dtype)
    for t in range(1, index.shape[0]):
        acc.addcmul_(work.index_select(2, index[t]), weight[t].to(work.dtype))
    if src.is_floating_point():
        return acc.to(src.dtype)
    info = torch.iinfo(src.dtype)
    return (acc + 0.5).floor_().clamp_(info.min, info.max).to(src.dtype)


def load_or_build(
    key: tuple, prefix: str, cache_dir: Path | None, build: Callable[[], RemapTable]
) -> RemapTable:
    """The table of ``key`` from the process LRU, else from ``cache_dir/<prefix>-<hash>.npz``, else ``build()``
    (then stored in both)."""

    def from_disk_or_build() -> RemapTable:
        path = None
        if cache_dir is not None:
            digest = hashlib.sha1(json.dumps(key, default=str).encode()).hexdigest()[:16]
            path = cache_dir / f"{prefix}-{digest}.npz"
            if path.exists():
                with np.load(path, allow_pickle=False) as z:
                    return RemapTable(*(torch.from_numpy(z[name]) for name in ("pixels", "index", "weight")))
        lut = build()
        if path is not None:
            _save_atomic(path, lut)
        return lut

    return TABLES.get(key, from_disk_or_build)


def _save_atomic(path: Path, lut: RemapTable) -> None:
    def write(tmp: Path) -> None:
        with tmp.open("wb") as f:  # a file object: np.savez would append ".npz" to the temporary's name
            np.savez(f, pixels=lut.pixels.numpy(), index=lut.index.numpy(), weight=lut.weight.numpy())

    atomic_write(path, write)


def rotation_key(rotation: np.ndarray | None) -> tuple[float, ...] | None:
    """A hashable identity of an orientation (``None`` for the identity), rounded so that one rotation computed twice
    gives one key."""
    if rotation is None or np.allclose(rotation, np.eye(3), rtol=0.0, atol=1e-12):
        return None
    return tuple(round(float(x), 12) + 0.0 for x in np.asarray(rotation).reshape(-1))


def check_rotation(rotation: object, name: str = "rotation") -> np.ndarray | None:
    """``rotation`` as a float64 3x3 proper rotation (``None`` stays ``None``: no rotation).

    Raises:
        ValueError: naming ``name``, when it is not a finite 3x3 orthonormal matrix with determinant +1.
    """
    if rotation is None:
        return None
    r = rotation.detach().cpu().numpy() if isinstance(rotation, torch.Tensor) else rotation
    r = np.asarray(r, dtype=np.float64)
    if r.shape != (3, 3) or not np.isfinite(r).all():
        raise ValueError(f"{name} must be a finite 3x3 rotation matrix, got shape {r.shape}")
    if not np.allclose(r.T @ r, np.eye(3), atol=1e-6) or abs(np.linalg.det(r) - 1.0) > 1e-6:
        raise ValueError(f"{name} must be a proper rotation (R^T R = I, det R = +1)")
    return r


class TableCache:
    """A small LRU of lookup tables shared by every remap in the process."""

    def __init__(self, maxsize: int) -> None:
        self.maxsize = maxsize
        self._items: OrderedDict[tuple, RemapTable] = OrderedDict()

    def get(self, key: tuple, build: Callable[[], RemapTable]) -> RemapTable:
        if key in self._items:
            self._items.move_to_end(key)
            return self._items[key]
        value = build()
        self._items[key] = value
        while len(self._items) > self.maxsize:
            self._items.popitem(last=False)
        return value

    def clear(self) -> None:
        self._items.clear()

    def __len__(self) -> int:
        return len(self._items)


#: The process-wide table cache (cube and panorama tables alike).
TABLES = TableCache(maxsize=16)


def reserve_tables(count: int) -> None:
    """Let the process cache hold at least ``count`` tables (it never shrinks): a user of many orientations (a
    virtual gimbal's views) keeps them all instead of rebuilding them in turn.

    Example:
        >>> reserve_tables(4); TABLES.maxsize >= 16
        True
    """
    TABLES.maxsize = max(TABLES.maxsize, int(count))


def clear_table_cache() -> None:
    """Forget the lookup tables held in memory (files in the disk cache stay): the next ``table()`` call of any remap
    loads or builds its table again, as in a fresh process (benchmarks, tests).

    Example:
        >>> clear_table_cache()
    """
    TABLES.clear()


__all__ = [
    "MODES",
    "TABLES",
    "RemapTable",
    "TableCache",
    "apply_table",
    "check_rotation",
    "clear_table_cache",
    "filled_mask",
    "interleaved_view",
    "load_or_build",
    "pack_table",
    "reserve_tables",
    "rotation_key",
]
