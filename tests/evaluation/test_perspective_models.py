"""A perspective model on the fisheye (``views=``, docs/evaluation.md "Perspective models on fisheye"): a tiny
pinhole depth model trained with ``data.camera.model=pinhole`` is scored on the fisheye test split through the cube
views, from its checkpoint and from its ONNX export, and predicts fisheye footage; the wrapping predictor blends
outputs as documented; what cannot work is refused in one line."""

from __future__ import annotations

import contextlib
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from omegaconf import open_dict
from PIL import Image

from airfisheye_bench.cli import export
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation.command import evaluate
from airfisheye_bench.evaluation.perspective import perspective_predictor
from airfisheye_bench.geometry.cameras import ideal_camera
from airfisheye_bench.io.calibration_files import save_camera
from airfisheye_bench.training import train
from tests.helpers.commands import PREDICT, run_in_process
from tests.helpers.configs import compose_eval, compose_train
from tests.helpers.runs import tiny_run_overrides

FISHEYE = ideal_camera(64, 64, 190.0)
PINHOLE = ideal_camera(32, 32, 90.0, "pinhole")


class FakePredictor:
    """A model of ``task`` whose output is ``make(view_batch)``: what the wrapper does with it is then known."""

    def __init__(self, task: str, make) -> None:
        self.task, self.make, self.batches = task, make, []

    def output(self, batch: dict) -> torch.Tensor:
        self.batches.append(batch)
        return self.make(batch)

    def identity(self) -> dict[str, Any]:
        return {"source": "fake"}


def _batch(**extra: torch.Tensor) -> dict:
    return {"image": torch.rand(2, 3, 64, 64), **extra}


# ---------------------------------------------------------------------------------------------- the wrapper
def test_depth_outputs_are_range_in_the_fisheye() -> None:
    """A model that sees 10 m in every view pixel: as range that is 10 m in every valid fisheye pixel; as z along
    each view's axis it is 10 / d_v.z (the cube's corners' rays: sqrt(3) times further)."""
    flat = FakePredictor("depth", lambda b: torch.full((b["image"].shape[0], 1, 32, 32), 10.0))
    as_range = perspective_predictor(flat, FISHEYE, PINHOLE, "cube")(_batch())
    valid = FISHEYE.valid_mask()
    assert as_range.shape == (2, 1, 64, 64) and flat.batches[0]["image"].shape == (10, 3, 32, 32)
    torch.testing.assert_close(as_range[:, 0][:, valid], torch.full((2, int(valid.sum())), 10.0))
    as_z = perspective_predictor(flat, FISHEYE, PINHOLE, "cube", view_depth="z")(_batch())[0, 0]
    rays = FISHEYE.ray_grid(torch.float64)
    dominant = rays.abs().amax(-1)  # d_v.z of the face the ray lies in
    torch.testing.assert_close(as_z[valid], (10.0 / dominant[valid]).float(), rtol=2e-2, atol=0)
    assert as_z[valid].max() < 10.0 * math.sqrt(3) + 1e-3


def test_logits_are_blended_as_probabilities_and_their_argmax_taken() -> None:
    """A seg model that answers the index of the view it is shown: each fisheye pixel gets the face it lies in."""

    def by_view(b: dict) -> torch.Tensor:
        count = b["image"].shape[0]
        logits = torch.zeros(count, 5, 32, 32)
        logits[torch.arange(count), torch.arange(count) % 5] = 8.0
        return logits

    labels = perspective_predictor(FakePredictor("seg", by_view), FISHEYE, PINHOLE, "cube")(_batch())
    rays = FISHEYE.ray_grid(torch.float64)
    x, y, z = rays.unbind(-1)
    face = torch.where(
        (z.abs() >= x.abs()) & (z.abs() >= y.abs()),
        0,
        torch.where(x.abs() >= y.abs(), torch.where(x < 0, 1, 2), torch.where(y < 0, 3, 4)),
    )
    valid = FISHEYE.valid_mask()
    assert labels.shape == (2, 64, 64) and labels.dtype == torch.int64
    assert (labels[0][valid] == face[valid]).float().mean() > 0.97  # all but the seams' ties


def test_completion_gets_its_lidar_points_in_the_views() -> None:
    """The sparse range map goes into the views point by point: a model that returns its sparse input sees every
    point, and its output, back in the fisheye, holds them where they were."""
    sparse = torch.zeros(2, 1, 64, 64)
    sparse[:, 0, 20:44:6, 12:52:8] = 15.0
    echo = FakePredictor("completion", lambda b: b["sparse_depth"])
    out = perspective_predictor(echo, FISHEYE, PINHOLE, "cube")(_batch(sparse_depth=sparse))
    seen = echo.batches[0]["sparse_depth"]
    assert seen.shape == (10, 1, 32, 32) and set(seen.unique().tolist()) == {0.0, 15.0}
    assert (out[sparse > 0] > 0).all()


def test_what_cannot_be_seen_through_views_is_refused() -> None:
    flat = FakePredictor("depth", lambda b: torch.ones(b["image"].shape[0], 1, 32, 32))
    with pytest.raises(ConfigError, match="trained for a equidistant camera"):
        perspective_predictor(flat, FISHEYE, ideal_camera(32, 32, 190.0), "cube")
    with pytest.raises(ConfigError, match=r"leave .* % of the fisheye's valid pixels unseen"):
        perspective_predictor(flat, FISHEYE, PINHOLE, [[0, 0], [90, 0]])
    with pytest.raises(ConfigError, match=r"views='ring': expected cube"):
        perspective_predictor(flat, FISHEYE, PINHOLE, "ring")
    with pytest.raises(ConfigError, match="view_depth='disparity'"):
        perspective_predictor(flat, FISHEYE, PINHOLE, "cube", view_depth="disparity")


# ---------------------------------------------------------------------------------------------- a trained model


@pytest.fixture(scope="module")
def pinhole_run(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``python train.py task=depth data.camera.model=pinhole data.camera.fov_deg=90`` on the tiny data at 64^2."""
    cfg = compose_train(
        [
            *tiny_run_overrides("depth", tiny_dataset),
            "data.camera.model=pinhole",
            "data.camera.fov_deg=90",
            "logger=csv",
        ]
    )
    run = tmp_path_factory.mktemp("pinhole") / "run"
    with open_dict(cfg):
        cfg.paths.output_dir = str(run)
    train(cfg)
    return run


@pytest.fixture(scope="module")
def pinhole_onnx(pinhole_run: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("pinhole_onnx") / "depth.onnx"
    with contextlib.redirect_stdout(io.StringIO()):
        try:
            code = export(
                [f"ckpt_path={pinhole_run / 'checkpoints' / 'last.ckpt'}", f"out={out}", "repeats=1"]
            )
        except SystemExit as stop:
            code = int(stop.code or 0)
    assert code == 0 and out.is_file()
    return out


@pytest.mark.integration
def test_a_pinhole_model_is_scored_on_the_fisheye_through_the_cube(
    pinhole_run: Path, pinhole_onnx: Path, tmp_path: Path
) -> None:
    trained = json.loads((pinhole_run / "results.json").read_text())
    assert trained["config"]["camera"]["model"] == "pinhole"  # trained and tested on its own views
    base = ["num_workers=0", "num_panels=1"]
    plain = evaluate(compose_eval([f"ckpt_path={pinhole_run}", *base], tmp_path / "plain"))
    assert plain["config"]["camera"]["model"] == "pinhole"  # without views=: its own camera, as before
    cube = evaluate(compose_eval([f"ckpt_path={pinhole_run}", "views=cube", *base], tmp_path / "cube"))
    assert cube["config"]["camera"] == {**FISHEYE.to_dict(), "width": 64, "height": 64}  # the release's lens
    views = cube["model"]["views"]
    assert views["spec"] == "cube" and views["view_depth"] == "range" and views["coverage"] == 1.0
    assert [v["name"] for v in views["views"]] == ["front", "left", "right", "up", "down"]
    assert views["view_camera"]["model"] == "pinhole" and views["view_camera"]["width"] == 64
    assert cube["config"]["evaluation"]["views"] == "cube" and cube["model"]["source"] == "checkpoint"
    assert all(math.isfinite(v) for v in cube["metrics"].values() if v is not None)
    assert any(k.startswith("ring_80-95/") for k in cube["breakdown"])  # scored out to the fisheye's edge
    assert len(list((tmp_path / "cube" / "panels").glob("*.png"))) == 1
    # The ONNX export carries the pinhole camera in its metadata: the same views, the same scores.
    onnx = evaluate(compose_eval([f"onnx_path={pinhole_onnx}", "views=cube", *base], tmp_path / "onnx"))
    assert onnx["model"]["source"] == "onnx" and onnx["model"]["views"]["view_camera"] == views["view_camera"]
    assert onnx["config"]["camera"] == cube["config"]["camera"]
    for key, value in cube["metrics"].items():
        assert onnx["metrics"][key] == pytest.approx(value, rel=1e-3, abs=1e-4), key
    # Without views= the ONNX model still refuses fisheye data, naming the cameras.
    with pytest.raises(ConfigError, match="exported for another camera"):
        evaluate(
            compose_eval([f"onnx_path={pinhole_onnx}", *base], tmp_path / "refused"),
            ["data.camera.model=equidistant", "data.camera.fov_deg=190"],
        )


@pytest.mark.integration
def test_views_refusals_are_one_line(pinhole_run: Path, tiny_runs, tmp_path: Path) -> None:
    base = ["num_workers=0", "num_panels=0"]
    with pytest.raises(ConfigError, match=r"views='ring': expected cube"):
        evaluate(compose_eval([f"ckpt_path={pinhole_run}", "views=ring", *base], tmp_path / "a"))
    with pytest.raises(ConfigError, match="give ckpt_path= or onnx_path="):
        evaluate(compose_eval(["task=depth", f"predictions={tmp_path}", "views=cube", *base], tmp_path / "b"))
    with pytest.raises(ConfigError, match="trained for a equidistant camera"):
        evaluate(compose_eval([f"ckpt_path={tiny_runs('depth')}", "views=cube", *base], tmp_path / "c"))
    with pytest.raises(ConfigError, match="unseen"):
        evaluate(compose_eval([f"ckpt_path={pinhole_run}", "views=[[0,0]]", *base], tmp_path / "d"))


@pytest.mark.integration
def test_a_pinhole_model_predicts_fisheye_footage(
    pinhole_run: Path, pinhole_onnx: Path, tmp_path: Path
) -> None:
    frames = tmp_path / "frames"
    frames.mkdir()
    rng = np.random.default_rng(0)
    for i in range(2):
        Image.fromarray(rng.integers(0, 256, (96, 96, 3), dtype=np.uint8)).save(frames / f"f{i}.png")
    lens = ideal_camera(96, 96, 185.0)
    save_camera(lens, tmp_path / "lens.yaml")
    for name, model in (("ckpt", pinhole_run), ("onnx", pinhole_onnx)):
        out = tmp_path / name
        done = run_in_process(
            PREDICT,
            [f"ckpt_path={model}", f"input={frames}", f"out={out}", f"camera={tmp_path / 'lens.yaml'}",
             "views=cube", "progress=false"],
        )  # fmt: skip
        assert done.returncode == 0, done.stderr
        record = json.loads((out / "predict.json").read_text())
        assert record["camera"] == lens.to_dict() and record["views"] == "cube"
        assert record["model"]["views"]["view_camera"]["model"] == "pinhole"
        depth = np.load(out / "depth" / "f0.npy") if (out / "depth" / "f0.npy").exists() else None
        png = np.asarray(Image.open(out / "depth" / "f0.png")) if depth is None else None
        values = depth if depth is not None else png
        assert values.shape == (96, 96) and (values[lens.valid_mask().numpy()] > 0).all()
        assert (values[~lens.valid_mask().numpy()] == 0).all()
    refused = run_in_process(
        PREDICT, [f"ckpt_path={pinhole_run}", f"input={frames}", f"out={tmp_path / 'x'}", "views=cube"]
    )
    assert refused.returncode == 2 and "give camera=<its calibration file>" in refused.stderr
