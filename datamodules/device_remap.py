"""``data.remap_on=device``: the loader's workers decode the cube faces, the model's device remaps them.

What moves and what stays (``docs/design.md``, "Serving a sample"):

- **Stays in the worker**: reading and decoding the files; the checks that name a file (unknown raw label ids, depth
  that is not finite), made on the texels the fisheye sees (the nearest table's), as the remapped image would show
  them; the augmentation draw (``(seed, epoch, index)``); the LiDAR: its projection depends on the served camera
  and the draw (rotation, mirror), not on the remap, and the occlusion correction is CPU code.
- **Moves to the device** (:class:`DeviceRemap`, called by ``AirFisheyeDataModule.on_after_batch_transfer``): the
  remap with the same :class:`~airfisheye_bench.geometry.RemapTable` (labels and depth nearest, RGB from the four
  bilinear taps, rounded back to 8 bits as the CPU kernel rounds them), the label lookup, the depth range, the
  padded calibration's bands, then the augmentation (:mod:`datamodules.augment_batch`), the sparse depth's mask and
  the normalisation, in the worker path's order.

A worker's sample (:class:`CubeFaces`) holds ``cube_rgb`` (``uint8 [5, S, S, 3]``, as decoded), ``cube_label``
(``uint8 [5, S, S]`` raw ids), ``cube_depth`` (``float32 [5, S, S]``), ``sparse_depth`` (``[1, H, W]``, not yet
masked), ``augment`` (``float64 [15]``, training only) and ``sample_id``; :class:`DeviceRemap` turns a batch of them
into the batch the worker path would have served.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch.utils.data import Dataset

from airfisheye_bench.constants import IMAGENET_MEAN, IMAGENET_STD
from airfisheye_bench.geometry import CubemapToFisheye
from airfisheye_bench.geometry.remap_table import rotation_key
from datamodules.augment_batch import augment_batch

#: Batch keys of the faces a worker sends (modality -> key).
CUBE_KEYS = {"rgb": "cube_rgb", "seg": "cube_label", "depth": "cube_depth"}
#: Batch key of the packed augmentation draws.
AUGMENT_KEY = "augment"


class CubeFaces(Dataset):
    """The loader's view of a dataset under ``data.remap_on=device``: its samples as decoded faces.

    Every other attribute is the dataset's (the samplers read its length, the datamodule its epoch).
    """

    def __init__(self, dataset) -> None:
        self.dataset = dataset

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, index: int) -> dict | None:
        return self.dataset.load_faces(index)

    def __getattr__(self, name: str):
        if name == "dataset":  # not set yet (unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.dataset, name)


@dataclass(frozen=True)
class _OnDevice:
    """The tables and masks of one device."""

    bilinear_pixels: torch.Tensor
    bilinear_index: torch.Tensor  # [T, P] int64
    bilinear_weight: torch.Tensor  # [T, P] float64
    nearest_pixels: torch.Tensor
    nearest_index: torch.Tensor  # [P] int64
    valid: torch.Tensor
    outside: torch.Tensor | None
    label_lut: torch.Tensor
    mean: torch.Tensor
    std: torch.Tensor


class DeviceRemap:
    """Finish a batch of :class:`CubeFaces` samples on its device, as the worker path would have served it.

    Args:
        remap: The dataset's remap (its camera and face size; its tables are the worker path's).
        valid: ``bool [H, W]`` pixels that carry data (the dataset's ``valid_mask``).
        outside: ``bool [H, W]`` pixels beyond a padded calibration's sensor, or ``None``.
        label_lut: ``uint8 [256]`` raw id -> training id.
        ignore_index: Label of pixels without one.
        max_depth: Depth beyond this is invalid.
    """

    def __init__(
        self,
        remap: CubemapToFisheye,
        valid: torch.Tensor,
        outside: torch.Tensor | None,
        label_lut: torch.Tensor,
        ignore_index: int,
        max_depth: float,
    ) -> None:
        self.remap = remap
        self.height, self.width = remap.camera.height, remap.camera.width
        self.cx, self.cy = float(remap.camera.cx), float(remap.camera.cy)
        self.valid, self.outside, self.label_lut = valid, outside, label_lut
        self.ignore_index, self.max_depth = int(ignore_index), float(max_depth)
        self._devices: dict[torch.device, _OnDevice] = {}

    def key(self) -> tuple:
        """What the tables depend on: two datasets with the same key finish each other's batches."""
        return (self.remap.camera.key(), self.remap.face_size, rotation_key(self.remap.rotation))

    def _on(self, device: torch.device) -> _OnDevice:
        if device not in self._devices:
            bilinear, nearest = self.remap.table("bilinear"), self.remap.table("nearest")
            self._devices[device] = _OnDevice(
                bilinear_pixels=bilinear.pixels.to(device),
                bilinear_index=bilinear.index.T.contiguous().long().to(device),
                bilinear_weight=bilinear.weight.T.contiguous().double().to(device),
                nearest_pixels=nearest.pixels.to(device),
                nearest_index=nearest.index[:, 0].long().to(device),
                valid=self.valid.to(device),
                outside=None if self.outside is None else self.outside.to(device),
                label_lut=self.label_lut.to(device),
                mean=torch.tensor(IMAGENET_MEAN, device=device).view(1, 3, 1, 1),
                std=torch.tensor(IMAGENET_STD, device=device).view(1, 3, 1, 1),
            )
        return self._devices[device]

    def __call__(self, batch: dict) -> dict:
        """The finished batch (``image``, ``valid_mask`` and the task's keys); a batch without faces as it is."""
        if CUBE_KEYS["rgb"] not in batch:
            return batch
        faces = batch[CUBE_KEYS["rgb"]]
        on = self._on(faces.device)
        out = {k: v for k, v in batch.items() if k not in CUBE_KEYS.values() and k != AUGMENT_KEY}
        b, h, w = faces.shape[0], self.height, self.width
        rgb = self._bilinear(faces, on).view(b, h, w, 3).permute(0, 3, 1, 2)
        label = depth = None
        if CUBE_KEYS["seg"] in batch:
            raw = self._nearest(batch[CUBE_KEYS["seg"]], on, self.ignore_index).view(b, h, w)
            label = on.label_lut[raw.long()]
        if CUBE_KEYS["depth"] in batch:
            depth = self._nearest(batch[CUBE_KEYS["depth"]].float(), on, 0.0).view(b, 1, h, w)
            depth = depth.masked_fill_(~((depth > 0) & (depth <= self.max_depth)), 0.0)
        if on.outside is not None:  # a padded calibration: the bands beyond its sensor show nothing
            rgb = rgb.masked_fill(on.outside, 0)
            label = None if label is None else label.masked_fill(on.outside, self.ignore_index)
            depth = None if depth is None else depth.masked_fill(on.outside, 0.0)
        if AUGMENT_KEY in batch:
            maps = [m for m in (None if label is None else label[:, None].float(), depth) if m is not None]
            fills = [f for f, m in ((float(self.ignore_index), label), (0.0, depth)) if m is not None]
            stacked = torch.cat(maps, 1) if maps else rgb.new_zeros((b, 0, h, w), dtype=torch.float32)
            image, valid, moved = augment_batch(
                rgb, on.valid, stacked, fills, batch[AUGMENT_KEY], self.cx, self.cy
            )
            if label is not None:
                label = moved[:, 0].to(label.dtype)
            if depth is not None:
                depth = moved[:, -1:]
        else:
            image, valid = rgb.float().div_(255.0), on.valid.expand(b, h, w).clone()
        if label is not None:
            out["label"] = label.long()
        if depth is not None:
            out["depth"] = depth
        if "sparse_depth" in out:  # the worker left it unmasked: the moved mask exists only now
            out["sparse_depth"] = out["sparse_depth"] * valid[:, None]
        out["image"] = image.sub_(on.mean).div_(on.std)
        out["valid_mask"] = valid
        return out

    def _bilinear(self, faces: torch.Tensor, on: _OnDevice) -> torch.Tensor:
        """``uint8 [B, 5, S, S, 3]`` -> ``uint8 [B, H * W, 3]`` by the bilinear table.

        The CPU kernel accumulates ``0.5 + sum w_t x_t`` in float32 with fused multiply-adds, then floors; each step
        here is that fused multiply-add (the product and sum exact in float64, one rounding to float32), so the
        8-bit result is the kernel's.
        """
        b = faces.shape[0]
        src = faces.reshape(b, -1, 3)
        acc = torch.full((b, on.bilinear_pixels.numel(), 3), 0.5, device=faces.device)
        for index, weight in zip(on.bilinear_index, on.bilinear_weight, strict=True):
            acc = (acc.double() + src.index_select(1, index).double() * weight[None, :, None]).float()
        out = torch.zeros(b, self.height * self.width, 3, dtype=torch.uint8, device=faces.device)
        out[:, on.bilinear_pixels] = acc.floor_().clamp_(0, 255).to(torch.uint8)
        return out

    def _nearest(self, faces: torch.Tensor, on: _OnDevice, fill: float) -> torch.Tensor:
        """``[B, 5, S, S]`` -> ``[B, H * W]`` by the nearest table (values copied), ``fill`` off the table."""
        b = faces.shape[0]
        out = torch.full((b, self.height * self.width), fill, dtype=faces.dtype, device=faces.device)
        out[:, on.nearest_pixels] = faces.reshape(b, -1).index_select(1, on.nearest_index)
        return out


__all__ = ["AUGMENT_KEY", "CUBE_KEYS", "CubeFaces", "DeviceRemap"]
