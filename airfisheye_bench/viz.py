"""Colour maps and qualitative panels (image | ground truth | prediction | error) as uint8 RGB arrays.

A task's panel (:func:`task_panel`) titles its columns ("RGB", "ground truth", "prediction", "error"; completion
adds "sparse input") and, for depth, ends with colour bars labelled in metres (range and absolute error). Text is
drawn with Pillow's bundled font: nothing here needs matplotlib, so training writes panels with what it imports.
"""

from __future__ import annotations

import functools
import io
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from PIL import Image, ImageDraw, ImageFont

from airfisheye_bench.atomic import atomic_write_bytes
from airfisheye_bench.constants import IMAGENET_MEAN, IMAGENET_STD
from airfisheye_bench.specs import get_task
from airfisheye_bench.specs.formats import LabelMaps

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


#: Column titles of each task's panel rows (:func:`panel_row` draws the tiles in this order).
#: Column titles of the model inputs after the image (other keys are titled by their name).
INPUT_TITLES = {"image": "RGB", "sparse_depth": "sparse input"}
#: Absolute depth error drawn full red in the error tile (metres).
ERROR_SCALE_M = 10.0
_INK, _PAPER = (0, 0, 0), (255, 255, 255)


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


def make_panel(
    rows: list[list[np.ndarray]],
    gap: int = 2,
    titles: Sequence[str] | None = None,
    legends: Sequence[np.ndarray] = (),
) -> np.ndarray:
    """Tile rows of equally sized ``uint8 [H, W, 3]`` tiles into one image with ``gap`` white pixels between.

    Args:
        rows: The tiles, one list per row.
        gap: White pixels between tiles.
        titles: Column titles, drawn above the first row (one per column).
        legends: Strips (e.g. :func:`depth_colorbar`) stacked under the tiles, left-aligned.

    Example:
        >>> tile = np.zeros((8, 8, 3), np.uint8)
        >>> make_panel([[tile, tile], [tile, tile]]).shape
        (18, 18, 3)
        >>> titled = make_panel([[tile, tile]], titles=["RGB", "prediction"])
        >>> titled.shape[0] > 8 and titled.shape[1] == 18
        True
    """
    h, w = rows[0][0].shape[:2]
    cols = max(len(r) for r in rows)
    canvas = np.full((len(rows) * (h + gap) - gap, cols * (w + gap) - gap, 3), 255, np.uint8)
    for i, row in enumerate(rows):
        for j, tile in enumerate(row):
            canvas[i * (h + gap) : i * (h + gap) + h, j * (w + gap) : j * (w + gap) + w] = tile
    parts = [canvas]
    if titles is not None:
        parts.insert(0, _title_strip(titles, w, gap, canvas.shape[1]))
    for legend in legends:
        strip = np.full((legend.shape[0] + gap, canvas.shape[1], 3), 255, np.uint8)
        width = min(legend.shape[1], canvas.shape[1])
        strip[gap:, :width] = legend[:, :width]
        parts.append(strip)
    return np.concatenate(parts, axis=0)


def task_panel(
    task: str,
    rows: list[list[np.ndarray]],
    max_depth: float = 120.0,
    gap: int = 2,
    classes: Sequence[tuple[str, Sequence[int]]] = (),
) -> np.ndarray:
    """A task's panel: :func:`panel_row` rows under their column titles, with the colour bars of its tiles.

    Depth and completion panels end with the range colour bar (log scale, 1 m to ``max_depth``) and the absolute
    error bar (0 to :data:`ERROR_SCALE_M` m), both labelled in metres; a segmentation panel with the class colours
    (``classes``: ``(name, rgb)`` in id order, :func:`class_legend`) and a line saying what the error tile's
    colours mean.

    Example:
        >>> tile = np.zeros((64, 64, 3), np.uint8)
        >>> panel = task_panel("depth", [[tile] * 4, [tile] * 4])
        >>> panel.shape[1], panel.shape[0] > 2 * 64 + 2
        (262, True)
    """
    width = len(rows[0]) * (rows[0][0].shape[1] + gap) - gap
    if isinstance(get_task(task).prediction, LabelMaps):
        legends = [class_legend(width, classes)] if classes else []
        legends.append(_text_strip("error: red = wrong class, black = right, dark grey = unlabelled", width))
    else:
        legends = [depth_colorbar(width, max_depth), error_colorbar(width, ERROR_SCALE_M)]
    return make_panel(rows, gap=gap, titles=panel_titles(task), legends=legends)


def class_legend(width: int, classes: Sequence[tuple[str, Sequence[int]]]) -> np.ndarray:
    """A key of the label colours: a swatch and the name of every class, left to right, wrapped at ``width``.

    Example:
        >>> key = class_legend(200, [("sky", (70, 130, 180)), ("road", (128, 64, 128)), ("vegetation", (0, 90, 0))])
        >>> key.shape[1], key.dtype.name, bool((key == (70, 130, 180)).all(-1).any())
        (200, 'uint8', True)
    """
    font = _font()
    line = _line_height()
    swatch = line - 4
    entries = [
        (name, tuple(int(c) for c in rgb), swatch + 4 + math.ceil(font.getlength(name)))
        for name, rgb in classes
    ]
    lines: list[list[tuple[str, tuple[int, ...], int]]] = [[]]
    used = 2
    for entry in entries:
        if lines[-1] and used + entry[2] > width:
            lines.append([])
            used = 2
        lines[-1].append(entry)
        used += entry[2] + 12
    image = Image.new("RGB", (width, len(lines) * line), _PAPER)
    draw = ImageDraw.Draw(image)
    for row, items in enumerate(lines):
        x, y = 2, row * line
        for name, rgb, size in items:
            draw.rectangle([x, y + 2, x + swatch - 1, y + 1 + swatch], fill=rgb, outline=_INK)
            draw.text((x + swatch + 4, y + 1), name, fill=_INK, font=font)
            x += size + 12
    return np.asarray(image).copy()


def panel_titles(task: str) -> tuple[str, ...]:
    """Column titles of a task's panel, one per tile of :func:`panel_row`: the inputs, then the outputs.

    Example:
        >>> panel_titles("completion")
        ('RGB', 'sparse input', 'ground truth', 'prediction', 'error')
    """
    inputs = (INPUT_TITLES.get(key, key.replace("_", " ")) for key in get_task(task).inputs)
    return (*inputs, "ground truth", "prediction", "error")


def depth_colorbar(width: int, max_depth: float = 120.0) -> np.ndarray:
    """The colour bar of :func:`colorize_depth`: range from 1 m to ``max_depth`` on its log scale, ticks in metres.

    Example:
        >>> bar = depth_colorbar(300, 120.0)
        >>> bar.shape[1], bar.dtype.name
        (300, 'uint8')
    """
    max_depth = max(float(max_depth), 1.0 + 1e-6)
    label = "range (m)"
    left = _label_width(label)
    n = max(width - left - 12, 2)
    colors = colorize_depth(np.geomspace(1.0, max_depth, n), max_depth).reshape(-1, 3)
    ticks = [d for d in (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000) if d < max_depth] + [max_depth]
    positions = [math.log(d) / math.log(max_depth) * (n - 1) for d in ticks]
    return _colorbar(width, label, colors, list(zip(positions, (f"{d:g}" for d in ticks), strict=True)))


def error_colorbar(width: int, scale: float = ERROR_SCALE_M) -> np.ndarray:
    """The colour bar of :func:`colorize_error` for absolute depth error: 0 to ``scale`` metres (and beyond).

    Example:
        >>> error_colorbar(300).shape[1]
        300
    """
    label = "|error| (m)"
    left = _label_width(label)
    n = max(width - left - 12, 2)
    colors = colorize_error(np.linspace(0.0, scale, n), np.ones(n, bool), scale).reshape(-1, 3)
    ticks = [(0.0, "0"), ((n - 1) / 2, f"{scale / 2:g}"), (n - 1.0, f"{scale:g}+")]
    return _colorbar(width, label, colors, ticks)


@functools.cache
def _font() -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    return ImageFont.load_default()


def _label_width(text: str) -> int:
    return math.ceil(_font().getlength(text)) + 8


def _title_strip(titles: Sequence[str], tile_width: int, gap: int, width: int) -> np.ndarray:
    """One line of column titles, each centred over its column (and cut at the column's edge)."""
    font = _font()
    height = _line_height()
    strip = np.full((height + gap, width, 3), 255, np.uint8)
    for j, title in enumerate(titles):
        x0 = j * (tile_width + gap)
        cell = Image.new("RGB", (tile_width, height), _PAPER)
        text_width = font.getlength(title)
        ImageDraw.Draw(cell).text((max(0.0, (tile_width - text_width) / 2), 1), title, fill=_INK, font=font)
        strip[:height, x0 : x0 + tile_width] = np.asarray(cell)[:, : max(0, min(tile_width, width - x0))]
    return strip


def _text_strip(text: str, width: int) -> np.ndarray:
    strip = Image.new("RGB", (width, _line_height()), _PAPER)
    ImageDraw.Draw(strip).text((2, 1), text, fill=_INK, font=_font())
    return np.asarray(strip).copy()


def _line_height() -> int:
    bottom = _font().getbbox("Ag(|")[3]
    return int(bottom) + 3


def _colorbar(width: int, label: str, colors: np.ndarray, ticks: list[tuple[float, str]]) -> np.ndarray:
    """``label`` then a gradient of ``colors`` with tick marks and their labels under it."""
    font = _font()
    line = _line_height()
    bar_height = 8
    image = Image.new("RGB", (width, bar_height + 3 + line), _PAPER)
    draw = ImageDraw.Draw(image)
    left = _label_width(label)
    draw.text((2, 0), label, fill=_INK, font=font)
    n = len(colors)
    gradient = np.repeat(colors[None, :, :], bar_height, axis=0)
    image.paste(Image.fromarray(np.ascontiguousarray(gradient)), (left, 0))
    last_end = -1e9
    for position, text in ticks:
        x = left + position
        draw.line([(x, bar_height), (x, bar_height + 2)], fill=_INK)
        text_width = font.getlength(text)
        start = min(max(x - text_width / 2, left), left + n - text_width)
        if start > last_end + 3:  # labels that would overlap the previous one are left out
            draw.text((start, bar_height + 2), text, fill=_INK, font=font)
            last_end = start + text_width
    return np.asarray(image).copy()


def spread_indices(total: int, count: int) -> list[int]:
    """``count`` indices spread evenly over ``range(total)`` (the centre of each of ``count`` equal stretches).

    A split lists its frames flight by flight, so the panel frames cover the split's flights, not the first frames
    of the first flight.

    Example:
        >>> spread_indices(100, 4), spread_indices(3, 5), spread_indices(10, 0)
        ([12, 37, 62, 87], [0, 1, 2], [])
    """
    count = max(0, min(count, total))
    return [int((i + 0.5) * total / count) for i in range(count)]


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
    """One qualitative row for sample ``index`` of a batch: image | (other inputs) | ground truth | prediction | error.

    What is drawn follows the task's spec: its model inputs after the image (e.g. completion's sparse depth, drawn as
    range maps), its target, and its prediction as labels or as a range map (``spec.prediction``).

    The columns are :func:`panel_titles` of the task; :func:`task_panel` assembles rows with their titles.

    Args:
        task: A registered task name (``seg``, ``depth``, ``completion``).
        batch: A collated batch (normalised ``image``, ``valid_mask``, the task's target and inputs).
        prediction: Labels ``[B, H, W]`` or range ``[B, 1, H, W]``.
        index: Sample of the batch to draw.
        palette: ``uint8 [N, 3]`` class colours (label predictions).
        max_depth: Far end of the depth colour map in metres.

    Returns:
        Tiles ``uint8 [H, W, 3]``. The error tile is red where a label is wrong (seg), or the absolute depth error
        with red at :data:`ERROR_SCALE_M` (10 m) or more; pixels without ground truth are dark grey.
    """
    image = denormalize(batch["image"][index], IMAGENET_MEAN, IMAGENET_STD)
    valid = batch["valid_mask"][index].bool().cpu()
    spec = get_task(task)
    tiles = [image] + [colorize_depth(batch[key][index, 0].cpu(), max_depth) for key in spec.inputs[1:]]
    if isinstance(spec.prediction, LabelMaps):
        if palette is None:
            raise ValueError(f"panel_row({task!r}) needs the class palette")
        gt = batch[spec.target][index].cpu()
        pred = torch.where(valid, prediction[index].cpu(), 255)
        wrong = (pred != gt).float()
        return [
            *tiles,
            colorize_labels(gt, palette),
            colorize_labels(pred, palette),
            colorize_error(wrong, gt != 255, scale=1.0),
        ]
    gt = batch[spec.target][index, 0].cpu()
    pred = prediction[index, 0].detach().cpu() * valid
    return [
        *tiles,
        colorize_depth(gt, max_depth),
        colorize_depth(pred, max_depth),
        colorize_error((pred - gt).abs(), gt > 0, scale=ERROR_SCALE_M),
    ]
