"""A fourth task is one spec (plus its model, loss and module): every layer that needs only facts finds them there.

The toy task ``height`` (a 1-channel regression in metres, here trained on the tiny dataset's range maps as a stand-in
for a height map) is registered by this test alone; no library file knows it.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import lightning as L
import numpy as np
import pytest
import torch
from torch import Tensor, nn

import models.registry
from airfisheye_bench.evaluation import (
    build_leaderboard,
    collect_results,
    read_prediction,
    validate_submission,
    write_results,
    write_submission,
)
from airfisheye_bench.evaluation.leaderboard import csv_columns
from airfisheye_bench.evaluation.predictors import to_prediction
from airfisheye_bench.export.deploy import parity_tolerance
from airfisheye_bench.metrics import DEFAULT_DEPTH_EDGES_M, DepthMetrics
from airfisheye_bench.metrics.scorer import TaskScorer
from airfisheye_bench.runs.deployment import deployment_metadata, parse_deployment_metadata
from airfisheye_bench.specs import (
    RANGE,
    ExportSpec,
    MetricColumn,
    MetricOptions,
    TaskSpec,
    UnknownTaskError,
    get_task,
    register_task,
    task_names,
    unregister_task,
)
from airfisheye_bench.tasks import BenchmarkTask
from airfisheye_bench.viz import panel_row
from datamodules import AirFisheyeDataModule
from datamodules.dataset import AirFisheyeDataset, CameraConfig


def _height_metric(options: MetricOptions) -> DepthMetrics:
    return DepthMetrics(min_depth=options.min_depth, max_depth=options.max_depth)


HEIGHT = TaskSpec(
    name="height",
    title="Height above ground",
    inputs=("image",),
    target="depth",  # the stand-in target: the dataset's range maps
    output="height",
    metric=_height_metric,
    columns=(MetricColumn("rmse", "RMSE (m)"), MetricColumn("delta1", "δ1", higher_is_better=True)),
    primary_metric="rmse",
    prediction=RANGE,
    export=ExportSpec(metadata=("max_depth",), atol=1e-3, rtol=1e-2, headline=("rmse",)),
)


@pytest.fixture
def height(monkeypatch: pytest.MonkeyPatch) -> Iterator[TaskSpec]:
    """``height`` registered for one test, with a tiny model registered for it."""
    monkeypatch.setattr(models.registry, "_MODELS", dict(models.registry._MODELS))
    monkeypatch.setattr(models.registry, "_MODEL_TASKS", dict(models.registry._MODEL_TASKS))
    register_task(HEIGHT)
    models.registry.register_model("tiny_height", task="height")(TinyHeightNet)
    try:
        yield HEIGHT
    finally:
        unregister_task("height")


class TinyHeightNet(nn.Module):
    """One convolution to a non-negative map; the zoo's calling convention (``forward`` / ``forward_with_aux``)."""

    def __init__(self) -> None:
        super().__init__()
        self.conv = nn.Conv2d(3, 1, 3, padding=1)

    def forward_with_aux(self, image: Tensor) -> dict[str, Tensor]:
        return {"height": nn.functional.softplus(self.conv(image)) * 10.0}

    def forward(self, image: Tensor) -> Tensor:
        return self.forward_with_aux(image)["height"]


class HeightTask(BenchmarkTask):
    """The task module: only the spec name and the loss; inputs, target, metric and panels come from the spec."""

    task = "height"

    def loss_terms(self, outputs: dict[str, Tensor], batch: dict) -> dict[str, Tensor]:
        valid = batch["depth"] > 0
        return {"loss": (outputs["height"] - batch["depth"]).abs()[valid].mean()}


def test_registry_lists_and_rejects(height: TaskSpec) -> None:
    assert task_names() == ("seg", "depth", "completion", "height")
    assert get_task("height") is height
    with pytest.raises(ValueError, match="already registered"):
        register_task(replace(height, title="another"))
    with pytest.raises(UnknownTaskError, match="registered tasks: seg, depth, completion, height"):
        get_task("normals")
    with pytest.raises(ValueError, match="primary_metric 'mae' is not one of its columns"):
        replace(height, name="bad", primary_metric="mae")


def test_scorer_and_breakdowns(height: TaskSpec) -> None:
    scorer = TaskScorer(
        lambda: height.make_metric(max_depth=80.0),
        ring_edges_deg=(0, 45, 95),
        depth_edges_m=DEFAULT_DEPTH_EDGES_M if height.depth_breakdown else None,
    )
    gt = torch.full((1, 1, 2, 2), 10.0)
    pred = to_prediction("height", torch.tensor([[[10.0, 12.0], [12.0, 10.0]]]))
    scorer.update(pred, gt, theta=torch.tensor([[10.0, 50.0], [50.0, 10.0]]))
    result = scorer.compute()
    assert result["metrics"]["rmse"] == pytest.approx(np.sqrt(2.0))
    assert result["breakdown"]["ring_45-95/rmse"] == pytest.approx(2.0)
    assert any(k.startswith("range_") for k in result["breakdown"])


def test_results_and_leaderboard(height: TaskSpec, tmp_path: Path) -> None:
    path = write_results(tmp_path / "run" / "results.json", "height", "test", {"rmse": 2.0, "delta1": 0.9})
    assert json.loads(path.read_text())["primary_metric"] == "rmse"
    write_results(tmp_path / "run2" / "results.json", "height", "test", {"rmse": 1.0, "delta1": 0.8})
    board = build_leaderboard(collect_results([tmp_path]), paper=True)
    table = board.tables[-1]
    assert (table.task, table.primary, table.columns) == ("height", "rmse", ("rmse", "delta1"))
    assert [e.run for _, e in table.groups[0].rows] == ["run2", "run"]  # lower RMSE first
    assert "## Height above ground (height)" in board.to_markdown()
    assert set(height.metric_keys) <= set(csv_columns())
    assert board.to_csv().count("\nheight,") == 2


def test_submission_round_trip(height: TaskSpec, tmp_path: Path) -> None:
    ids = ["env/traj/000001", "env/traj/000002"]
    values = [np.full((4, 6), 3.5, np.float32), np.linspace(0, 50, 24, dtype=np.float32).reshape(4, 6)]
    for fmt in ("png", "npy"):
        root = write_submission(tmp_path / fmt, "height", zip(ids, values, strict=True), depth_format=fmt)
        files = validate_submission(root, "height", ids, (4, 6))
        assert {p.suffix for p in files.values()} == {f".{fmt}"}
        for sample_id, value in zip(ids, values, strict=True):
            decoded = read_prediction(files[sample_id], "height")
            assert decoded.shape == (1, 4, 6)
            np.testing.assert_allclose(decoded[0].numpy(), value, atol=1 / 512)


def test_export_contract(height: TaskSpec) -> None:
    assert parity_tolerance("height") == (1e-3, 1e-2)
    meta = deployment_metadata(
        task="height",
        model="tiny_height",
        model_config={"name": "tiny_height"},
        normalization={"mean": [0.5] * 3, "std": [0.25] * 3},
        camera={"model": "equidistant", "width": 8, "height": 6, "fov_deg": 190.0},
        data_config={"task": "height"},
        checkpoint_sha256="0" * 64,
        source_checkpoint="run/last.ckpt",
        max_depth=60.0,
    )
    decoded = parse_deployment_metadata(meta)
    assert (decoded["task"], decoded["output"], decoded["max_depth"]) == ("height", "height", 60.0)
    assert "min_depth" not in decoded


def test_dataset_serves_what_the_spec_names(height: TaskSpec, tiny_dataset: Path) -> None:
    ds = AirFisheyeDataset.from_root(tiny_dataset, "val", "height", camera=CameraConfig(size=32))
    assert sorted(ds[0]) == ["depth", "image", "sample_id", "valid_mask"]
    normals = replace(height, name="normals", target="normals")
    register_task(normals)
    try:
        with pytest.raises(ValueError, match=r"needs sample keys \['normals'\]"):
            AirFisheyeDataset.from_root(tiny_dataset, "val", "normals")
    finally:
        unregister_task("normals")


def test_training_loop_runs_the_toy_task(height: TaskSpec, tiny_dataset: Path, tmp_path: Path) -> None:
    datamodule = AirFisheyeDataModule(
        "height", root=tiny_dataset, camera={"size": 32}, batch_size=2, max_depth=60.0
    )
    module = HeightTask(
        {"name": "tiny_height"}, optimizer=lambda params: torch.optim.SGD(params, lr=1e-3), num_panels=1
    )
    trainer = L.Trainer(
        max_epochs=1,
        limit_train_batches=2,
        limit_val_batches=1,
        limit_test_batches=1,
        logger=False,
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        default_root_dir=tmp_path,
        accelerator="cpu",
    )
    trainer.fit(module, datamodule=datamodule)
    trainer.test(module, datamodule=datamodule, verbose=False)
    scores = module.test_results
    assert np.isfinite(scores["metrics"]["rmse"]) and "delta1" in scores["metrics"]
    assert any(k.startswith("ring_") for k in scores["breakdown"])
    assert list((tmp_path / "panels").glob("epoch_*.png"))
    batch = next(iter(datamodule.val_dataloader()))
    tiles = panel_row("height", batch, module.prediction(module.net.forward_with_aux(batch["image"])), 0)
    assert len(tiles) == 4 and tiles[0].shape == (32, 32, 3)
