"""README "Your own camera": ``python train.py task=completion data.preset=tiny trainer=debug
data.camera.calibration=<a Kalibr camchain with a ds camera>`` trains (here on the session's tiny dataset)."""

from __future__ import annotations

import json
from pathlib import Path

from omegaconf import open_dict

from airfisheye_bench.io.calibration_files import load_camera
from airfisheye_bench.training import train
from tests.io import calibration_fixtures as fx
from tests.training.test_configs import compose_train
from tests.training.test_train import tiny_run_overrides


def test_training_with_a_kalibr_double_sphere_camchain(tiny_dataset: Path, tmp_path: Path) -> None:
    camchain = fx.write_kalibr_camchain(tmp_path / "camchain.yaml", "ds", cameras=1)
    cfg = compose_train(
        [*tiny_run_overrides("completion", tiny_dataset), f"data.camera.calibration={camchain}"]
    )
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path / "run")
    results = train(cfg)
    assert "rmse" in results["metrics"]
    record = json.loads((tmp_path / "run" / "results.json").read_text())
    assert record["config"]["camera"] == load_camera(camchain).resized(64, 64).to_dict()
    assert record["config"]["data"]["camera"]["calibration"] == str(camchain)
    # The double sphere lens sees beyond 190 degrees in the frame's corners: the rings reach its rim.
    assert max(float(k.split("_")[1].split("/")[0].split("-")[1]) for k in record["breakdown"]) > 95
    assert list((tmp_path / "run" / "panels").glob("epoch_*.png"))
