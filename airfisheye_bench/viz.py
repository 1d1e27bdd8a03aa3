"""Colour maps and qualitative panels (image | ground truth | prediction | error) as uint8 RGB arrays."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from airfisheye_bench.atomic import atomic_write_bytes
from airfisheye_bench.constants import IMAGENET_MEAN, IMAGENET_STD

# Anchor colours of a perceptually ordered map (near = yellow, far = dark purple), interpolated to 256 entries.
_ANCHORS = np.array(
    [
        [252, 253, 191],
        [254, 176, 120],
        [241, 96, 93],
        [183, 55, 121],
        [114, 31, 129],
        [44, 17, 95],
        [0, 0, 4],
    ],
    dtype=np.float64,
)
DEPTH_COLORMAP = np.stack(
    [np.interp(np.linspace(0, 1, 256), np.linspace(0, 1, len(_ANCHORS)), _ANCHORS[:, c]) for c in range(3)],
    -1,
).astype(np.uint8)


def denormalize(image: torch.Tensor, mean, std) -> np.ndarray:
    """``[3, H, W]`` normalised float -> ``uint8 [H, W, 3]``."""
    mean_t = torch.as_tensor(mean, dtype=image.dtype, device=image.device).view(3, 1, 1)
    std_t = torch.as_tensor(std, dtype=image.dtype, device=image.device).view(3, 1, 1)
    rgb = (image * std_t + mean_t).clamp(0, 1)
    return (rgb.permute(1, 2, 0).cpu().numpy() * 255 + 0.5).astype(np.uint8)


def colorize_labels(label: torch.Tensor | np.ndarray, palette: np.ndarray) -> np.ndarray:
    """``[H, W]`` class ids -> ``uint8 [H, W, 3]`` with ``palette [N, 3]`` (255 = ignore and ids >= N are black)."""
    ids = np.asarray(label.cpu() if isinstance(label, torch.Tensor) else label).astype(np.int64).clip(0, 255)
    pal = np.zeros((256, 3), np.uint8)
    pal[: min(len(palette), 256)] = np.asarray(palette, np.uint8)[:256]
    pal[255] = 0
    return pal[ids]


def colorize_depth(depth: torch.Tensor | np.ndarray, max_depth: float) -> np.ndarray:
    """``[H, W]`` or ``[1, H, W]`` range in metres -> ``uint8 [H, W, 3]``; 0 (invalid) is black.

    The colour follows log range from 1 m (light yellow) to ``max_depth`` (dark purple): a drone sees most of its scene
    between 10 and 120 m, where an inverse-depth scale would put everything in the last few colours.
    """
    d = np.asarray(
        depth.detach().cpu() if isinstance(depth, torch.Tensor) else depth, dtype=np.float64
    ).squeeze()
    valid = d > 0
    t = np.zeros_like(d)
    t[valid] = np.log(np.clip(d[valid], 1.0, max_depth)) / np.log(max(max_depth, 1.0 + 1e-9))  # 0 near, 1 far
    # The far end stops short of the map's black, which marks pixels without depth.
    out = DEPTH_COLORMAP[(t.clip(0, 1) * 0.85 * 255).astype(np.int64)]
    out[~valid] = 0
    return out


def colorize_error(
    error: torch.Tensor | np.ndarray, valid: torch.Tensor | np.ndarray, scale: float
) -> np.ndarray:
    """Absolute error ``[H, W]`` -> ``uint8 [H, W, 3]`` (black = 0, red = ``scale`` or more; invalid = dark grey)."""
    e = np.asarray(
        error.detach().cpu() if isinstance(error, torch.Tensor) else error, dtype=np.float64
    ).squeeze()
    v = np.asarray(valid.cpu() if isinstance(valid, torch.Tensor) else valid, dtype=bool).squeeze()
    t = (e / max(scale, 1e-9)).clip(0, 1)
    out = np.stack([255 * t, 64 * (1 - t) * t * 4, np.zeros_like(t)], -1).astype(np.uint8)
    out[~v] = 32
    return out


def make_panel(rows: list[list[np.ndarray]], gap: int = 2) -> np.ndarray:
    """Tile rows of equally sized ``uint8 [H, W, 3]`` tiles into one image with ``gap`` white pixels between."""
    h, w = rows[0][0].shape[:2]
    cols = max(len(r) for r in rows)
    canvas = np.full((len(rows) * (h + gap) - gap, cols * (w + gap) - gap, 3), 255, np.uint8)
    for i, row in enumerate(rows):
        for j, tile in enumerate(row):
            canvas[i * (h + gap) : i * (h + gap) + h, j * (w + gap) : j * (w + gap) + w] = tile
    return canvas


def save_png(path: str | Path, image: np.ndarray) -> Path:
    """Write ``uint8 [H, W, 3]`` as PNG atomically."""
    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    path = Path(path)
    atomic_write_bytes(path, buf.getvalue())
    return path


def panel_row(
    task: str,
    batch: dict,
    prediction: torch.Tensor,
    index: int,
    palette: np.ndarray | None = None,
    max_depth: float = 120.0,
) -> list[np.ndarray]:
    """One qualitative row for sample ``index`` of a batch: image | (sparse input) | ground truth | prediction | error.

    Args:
        task: ``seg``, ``depth`` or ``completion``.
        batch: A collated batch (normalised ``image``, ``valid_mask``, and ``label`` or ``depth``, plus
            ``sparse_depth`` for completion).
        prediction: Labels ``[B, H, W]`` (seg) or depth ``[B, 1, H, W]``.
        index: Sample of the batch to draw.
        palette: ``uint8 [N, 3]`` class colours (seg).
        max_depth: Far end of the depth colour map in metres.

    Returns:
        Tiles ``uint8 [H, W, 3]``. The error tile is red where a label is wrong (seg), or the absolute depth error
        with red at 10 m or more; pixels without ground truth are dark grey.
    """
    image = denormalize(batch["image"][index], IMAGENET_MEAN, IMAGENET_STD)
    valid = batch["valid_mask"][index].bool().cpu()
    if task == "seg":
        if palette is None:
            raise ValueError("panel_row('seg') needs the class palette")
        gt = batch["label"][index].cpu()
        pred = torch.where(valid, prediction[index].cpu(), 255)
        wrong = (pred != gt).float()
        return [
            image,
            colorize_labels(gt, palette),
            colorize_labels(pred, palette),
            colorize_error(wrong, gt != 255, scale=1.0),
        ]
    gt = batch["depth"][index, 0].cpu()
    pred = prediction[index, 0].detach().cpu() * valid
    tiles = [
        image,
        colorize_depth(gt, max_depth),
        colorize_depth(pred, max_depth),
        colorize_error((pred - gt).abs(), gt > 0, scale=10.0),
    ]
    if task == "completion":
        tiles.insert(1, colorize_depth(batch["sparse_depth"][index, 0].cpu(), max_depth))
    return tiles
