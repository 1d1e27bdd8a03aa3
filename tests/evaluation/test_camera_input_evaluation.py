"""``airfisheye-evaluate`` and ``airfisheye-predict`` of a camera-aware model (``model.camera_input=rays``): the
ray map of the data's lens is fed to the checkpoint and to its ONNX files (as an input, or baked in), which give the
training run's test metrics; flip TTA mirrors the image, not the lens's map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf
from PIL import Image

from airfisheye_bench.evaluation.command import evaluate
from airfisheye_bench.evaluation.predictors import CheckpointPredictor
from airfisheye_bench.tasks.checkpoint import load_task
from datamodules.config import instantiate_datamodule
from tests.helpers.commands import PREDICT, run_in_process
from tests.helpers.configs import compose_eval

pytestmark = pytest.mark.integration  # trains, exports, evaluates: seconds per test


@pytest.fixture(scope="module")
def depth_rays(tiny_rays_runs) -> Path:
    return tiny_rays_runs("depth")


@pytest.fixture(scope="module")
def onnx_files(tiny_rays_exports) -> dict[str, Path]:
    files = {}
    for kind, baked in (("input", False), ("baked", True)):
        path, code, printed = tiny_rays_exports("depth", baked)
        assert code == 0, printed
        files[kind] = path
    return files


def _evaluate(tmp_path: Path, name: str, *args: str) -> dict:
    return evaluate(compose_eval([*args, "num_workers=0", "num_panels=0"], tmp_path / name))


def test_checkpoint_and_onnx_files_give_the_training_metrics(
    depth_rays: Path, onnx_files: dict[str, Path], tmp_path: Path
) -> None:
    trained = json.loads((depth_rays / "results.json").read_text())["metrics"]
    ckpt = _evaluate(tmp_path, "ckpt", f"ckpt_path={depth_rays}")
    for key, value in trained.items():  # the same checkpoint, data, rays and metric code as the test stage
        assert ckpt["metrics"][key] == pytest.approx(value, abs=1e-6), key
    assert ckpt["config"]["data"]["camera_input"] == "rays"
    for kind, path in onnx_files.items():
        record = _evaluate(tmp_path, kind, f"onnx_path={path}")
        # The data serve the map only where the file takes it.
        assert record["config"]["data"]["camera_input"] == ("none" if kind == "baked" else "rays")
        for key, value in ckpt["metrics"].items():  # within the export's parity tolerance
            assert record["metrics"][key] == pytest.approx(value, rel=1e-3, abs=1e-4), (kind, key)
    flipped = _evaluate(tmp_path, "ckpt_tta", f"ckpt_path={depth_rays}", "tta=flip")
    onnx_flipped = _evaluate(tmp_path, "onnx_tta", f"onnx_path={onnx_files['input']}", "tta=flip")
    for key, value in flipped["metrics"].items():
        assert onnx_flipped["metrics"][key] == pytest.approx(value, rel=1e-3, abs=1e-4), key


def test_flip_tta_keeps_the_ray_map(depth_rays: Path) -> None:
    module = load_task(depth_rays)
    datamodule = instantiate_datamodule(OmegaConf.load(depth_rays / "config.yaml").data, "validate")
    batch = next(iter(datamodule.val_dataloader()))
    image, rays = batch["image"], batch["rays"]
    with torch.no_grad():
        expected = 0.5 * (module.net(image, rays) + module.net(image.flip(-1), rays).flip(-1))
    predicted = CheckpointPredictor(module, tta="flip")(batch)
    torch.testing.assert_close(predicted, expected)
    with pytest.raises(ValueError, match="needs rays"):
        CheckpointPredictor(module)({k: v for k, v in batch.items() if k != "rays"})


def test_predict_feeds_the_ray_map_of_the_model_camera(
    depth_rays: Path, onnx_files: dict[str, Path], tmp_path: Path
) -> None:
    rng = np.random.default_rng(0)
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(2):
        Image.fromarray(rng.integers(0, 256, (64, 64, 3), dtype=np.uint8)).save(frames / f"f{i}.png")
    depths = {}
    for kind, model in (("ckpt", depth_rays), *onnx_files.items()):
        out = tmp_path / kind
        outcome = run_in_process(
            PREDICT,
            [f"ckpt_path={model}", f"input={frames}", f"out={out}", "depth_format=npy", "progress=false"],
        )
        assert outcome.returncode == 0, outcome.stderr[-3000:]
        depths[kind] = np.load(out / "depth" / "f0.npy")
    assert (depths["ckpt"] > 0).any()
    # The checkpoint fed the map of its camera, the first file the same map as its input, the second its constant.
    for kind in onnx_files:
        np.testing.assert_allclose(depths[kind], depths["ckpt"], rtol=2e-3, atol=1e-4, err_msg=kind)
