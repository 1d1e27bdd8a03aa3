"""docs/cameras.md (your own camera): ``python train.py task=completion data.preset=tiny trainer=debug
data.camera.calibration=<a Kalibr camchain with a ds camera>`` trains (here on the session's tiny dataset); the
exported ONNX model carries that camera, without the file, and evaluation holds data to it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from omegaconf import open_dict

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation.command import evaluate
from airfisheye_bench.io.calibration_files import load_camera
from airfisheye_bench.runs.deployment import read_deployment_metadata
from airfisheye_bench.training import train
from tests.helpers import calibration_fixtures as fx
from tests.helpers.configs import compose_eval, compose_train
from tests.helpers.file_access import opened_files
from tests.helpers.runs import tiny_run_overrides

pytestmark = pytest.mark.integration  # trains, evaluates or exports: seconds per test


@pytest.fixture(scope="module")
def ds_run(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("ds_run")
    camchain = fx.write_kalibr_camchain(tmp / "camchain.yaml", "ds", cameras=1)
    cfg = compose_train(
        [*tiny_run_overrides("completion", tiny_dataset), f"data.camera.calibration={camchain}"]
    )
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp / "run")
    with opened_files() as opened:
        results = train(cfg)
    assert "rmse" in results["metrics"]
    # The lens is read from the file once, where the datamodule is built; every split serves that one lens.
    assert opened.count(camchain.resolve()) == 1
    return tmp / "run", camchain


def test_training_with_a_kalibr_double_sphere_camchain(ds_run: tuple[Path, Path]) -> None:
    run, camchain = ds_run
    record = json.loads((run / "results.json").read_text())
    assert record["config"]["camera"] == load_camera(camchain).resized(64, 64).to_dict()
    assert record["config"]["data"]["camera"]["calibration"] == str(camchain)
    # The double sphere lens sees beyond 190 degrees in the frame's corners: the rings reach its rim.
    assert max(float(k.split("_")[1].split("/")[0].split("-")[1]) for k in record["breakdown"]) > 95
    assert list((run / "panels").glob("epoch_*.png"))


# A second ONNX export of the completion model (seconds of torch.export): end to end, slow. The default suite covers
# each step: the export through the command (tests/export/test_deploy.py::test_depth_tasks_export_through_the_cli),
# the exported data config carrying the lens instead of the file and the refusal of another camera
# (tests/evaluation/test_camera_mismatch.py), the inline lens serving the same camera
# (tests/datamodules/test_calibrated_camera.py::test_an_inline_camera_dict_serves_the_same_camera).
@pytest.mark.slow
def test_the_onnx_model_carries_the_camera_without_the_file(
    ds_run: tuple[Path, Path], tmp_path: Path
) -> None:
    from airfisheye_bench.export.deploy import export_deployment

    run, camchain = ds_run
    onnx_path = tmp_path / "completion.onnx"
    export_deployment(run, onnx_path, parity_samples=2, repeats=1)
    meta = read_deployment_metadata(onnx_path)
    lens = load_camera(camchain)
    assert meta["camera"] == lens.resized(64, 64).to_dict() and meta["image_size"] == [64, 64]
    assert meta["data_config"]["camera"]["calibration"] == lens.to_dict()
    moved = tmp_path / "elsewhere.yaml"
    shutil.move(camchain, moved)  # the evaluation machine does not have the training machine's file
    try:
        record = evaluate(compose_eval([f"onnx_path={onnx_path}", "num_panels=0"], tmp_path / "eval"))
        assert record["config"]["camera"] == meta["camera"]
        image_02 = fx.write_kitti360(tmp_path / "image_02.yaml")
        with pytest.raises(ConfigError, match=r"double_sphere 64x64 .* and unified 64x64 .* differ in"):
            evaluate(
                compose_eval([f"onnx_path={onnx_path}", "num_panels=0"], tmp_path / "other"),
                [f"data.camera.calibration={image_02}"],
            )
    finally:
        shutil.move(moved, camchain)
