"""Qualitative panels: titled columns, depth colour bars in metres, frames spread over the split."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from airfisheye_bench.evaluation.evaluator import evaluate_predictions
from airfisheye_bench.metrics.scorer import TaskScorer
from airfisheye_bench.specs import get_task
from airfisheye_bench.viz import (
    DEPTH_COLORMAP,
    ERROR_SCALE_M,
    colorize_depth,
    depth_colorbar,
    error_colorbar,
    make_panel,
    panel_row,
    panel_titles,
    spread_indices,
    task_panel,
)

SIZE = 64


def _batch(task: str, frames: int = 2, sample_ids: list[str] | None = None) -> dict:
    depth = torch.linspace(1.0, 100.0, SIZE * SIZE).view(1, 1, SIZE, SIZE).repeat(frames, 1, 1, 1)
    batch = {
        "image": torch.zeros(frames, 3, SIZE, SIZE),
        "valid_mask": torch.ones(frames, SIZE, SIZE, dtype=torch.bool),
        "depth": depth,
        "label": torch.zeros(frames, SIZE, SIZE, dtype=torch.long),
        "sparse_depth": depth * (torch.rand_like(depth) < 0.05),
        "sample_id": sample_ids or [f"env/traj/{i:06d}" for i in range(frames)],
    }
    return batch


def _rows(task: str) -> list[list[np.ndarray]]:
    batch = _batch(task)
    prediction = batch["label"] if task == "seg" else batch["depth"] * 1.1
    palette = np.arange(13 * 3, dtype=np.uint8).reshape(13, 3) * 6
    return [panel_row(task, batch, prediction, i, palette=palette) for i in range(2)]


@pytest.mark.parametrize("task", ["seg", "depth", "completion"])
def test_every_column_has_a_title_above_it(task: str) -> None:
    rows = _rows(task)
    assert len(rows[0]) == len(panel_titles(task))  # one title per tile panel_row draws
    untitled = make_panel(rows)
    panel = task_panel(task, rows)
    assert panel.shape[1] == untitled.shape[1]
    # The tiles sit under a title strip; each column's strip holds dark text, the gaps stay white.
    top = panel.shape[0] - untitled.shape[0] - _legend_height(task, untitled.shape[1])
    assert top > 0 and (panel[top : top + untitled.shape[0]] == untitled).all()
    for j in range(len(panel_titles(task))):
        cell = panel[:top, j * (SIZE + 2) : j * (SIZE + 2) + SIZE]
        assert (cell.max(-1) < 128).any(), f"column {j} ({panel_titles(task)[j]}) has no title"


def _legend_height(task: str, width: int) -> int:
    if task == "seg":
        return (
            task_panel("seg", [[np.zeros((SIZE, SIZE, 3), np.uint8)] * 4]).shape[0]
            - (make_panel([[np.zeros((SIZE, SIZE, 3), np.uint8)] * 4], titles=panel_titles("seg")).shape[0])
        )
    return depth_colorbar(width).shape[0] + error_colorbar(width).shape[0] + 4  # each under a 2 px gap


@pytest.mark.parametrize("task", ["depth", "completion"])
def test_depth_panels_end_with_colour_bars_in_metres(task: str) -> None:
    rows = _rows(task)
    panel = task_panel(task, rows, max_depth=120.0)
    width = panel.shape[1]
    bar, error = depth_colorbar(width, 120.0), error_colorbar(width)
    assert (panel[-error.shape[0] :] == error).all()
    assert (panel[-error.shape[0] - 2 - bar.shape[0] : -error.shape[0] - 2] == bar).all()


def test_depth_colour_bar_shows_the_tiles_colours_at_its_ticks() -> None:
    max_depth, width = 120.0, 400
    bar = depth_colorbar(width, max_depth)
    # The gradient row: colours of colorize_depth's map (the label's grey text aside), light near, dark far.
    colours = {tuple(c) for c in DEPTH_COLORMAP}
    painted = [tuple(c) for c in bar[2] if len(set(c)) > 1]
    assert len(painted) > width // 2 and set(painted) <= colours
    assert painted[0] == tuple(colorize_depth(np.array([1.0]), max_depth).reshape(3))
    assert painted[-1] == tuple(colorize_depth(np.array([max_depth]), max_depth).reshape(3))
    # Near is the light end, far the dark one, as in the tiles.
    first, last = np.asarray(painted[0], float), np.asarray(painted[-1], float)
    assert first.sum() > last.sum()
    # Tick labels (dark text) under the gradient.
    assert (bar[10:].max(-1) < 128).any()


def test_error_colour_bar_spans_the_error_tiles_scale() -> None:
    bar = error_colorbar(300, ERROR_SCALE_M)
    reds = bar[2, :, 0].astype(int)
    assert reds.max() == 255  # full red at ERROR_SCALE_M, as colorize_error draws it


@pytest.mark.parametrize(("total", "count"), [(100, 4), (7, 3), (5, 5), (3, 8), (1, 4), (0, 4), (10, 0)])
def test_spread_indices_cover_the_split_evenly(total: int, count: int) -> None:
    picks = spread_indices(total, count)
    assert len(picks) == min(total, count) == len(set(picks)) and picks == sorted(picks)
    assert all(0 <= i < total for i in picks)
    if picks:  # one pick in each of len(picks) equal stretches
        stretch = total / len(picks)
        assert [math.floor(i / stretch) for i in picks] == list(range(len(picks)))


class _Frames(torch.utils.data.Dataset):
    """Three flights of four frames each, listed flight by flight as a split lists them."""

    def __init__(self) -> None:
        self.sample_ids = [f"env/flight{f}/{i:06d}" for f in range(3) for i in range(4)]

    def __len__(self) -> int:
        return len(self.sample_ids)

    def __getitem__(self, index: int) -> dict:
        batch = _batch("depth", 1, [self.sample_ids[index]])
        return {k: v[0] for k, v in batch.items()}


def test_evaluation_panels_are_spread_over_the_flights() -> None:
    scorer = TaskScorer(get_task("depth").make_metric, depth_edges_m=None)
    model = _StandIn(lambda batch: batch["depth"] * 1.05, "depth")
    result = evaluate_predictions(
        model, _Frames(), scorer, torch.zeros(SIZE, SIZE), batch_size=4, num_panels=3
    )
    flights = [sample_id.split("/")[1] for sample_id, _ in result.panels]
    assert flights == ["flight0", "flight1", "flight2"]


class _StandIn:
    """A predictor made of a function of the batch."""

    def __init__(self, fn, task: str) -> None:
        self.fn, self.task = fn, task

    def __call__(self, batch: dict) -> torch.Tensor:
        return self.fn(batch)


def test_training_panels_are_spread_over_the_validated_frames() -> None:
    from airfisheye_bench.tasks import SegmentationTask

    model = {"name": "deeplabv3plus", "encoder_name": "resnet18", "encoder_weights": None}
    task = SegmentationTask(model, class_names=["sky", "ground"], num_panels=3)
    ids = _Frames().sample_ids
    datamodule = SimpleNamespace(
        split_dataset=lambda split: SimpleNamespace(sample_ids=ids), eval_batch_size=2
    )
    task._trainer = SimpleNamespace(datamodule=datamodule, num_val_batches=[math.inf])
    assert sorted(id_.split("/")[1] for id_ in task._panel_frames()) == ["flight0", "flight1", "flight2"]
    # With limit_val_batches the panel frames are spread over the frames that are validated.
    task._panel_ids = None
    task._trainer = SimpleNamespace(datamodule=datamodule, num_val_batches=[2])
    assert task._panel_frames() <= set(ids[:4]) and len(task._panel_frames()) == 3


def test_a_segmentation_panel_has_a_key_of_its_class_colours() -> None:
    rows = _rows("seg")
    palette = np.arange(13 * 3, dtype=np.uint8).reshape(13, 3) * 6
    classes = [(f"class{i}", palette[i].tolist()) for i in range(13)]
    plain, keyed = task_panel("seg", rows), task_panel("seg", rows, classes=classes)
    assert keyed.shape[1] == plain.shape[1] and keyed.shape[0] > plain.shape[0]
    key = keyed[plain.shape[0] - _legend_height("seg", plain.shape[1]) :]
    for _, rgb in classes:  # every class has its swatch under the tiles
        assert (key == np.asarray(rgb, np.uint8)).all(-1).sum() >= 9, rgb
