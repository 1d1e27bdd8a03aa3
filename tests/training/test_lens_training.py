"""docs/training.md ("Training across lenses"): ``python train.py task=depth data.preset=tiny trainer=debug
data.camera.lenses=[...] data.camera.jitter=...`` trains and tests (here on the session's tiny dataset at 32^2)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from omegaconf import open_dict

from airfisheye_bench.training import train
from tests.helpers.configs import compose_train
from tests.helpers.runs import tiny_run_overrides

pytestmark = pytest.mark.integration  # trains: seconds


def test_training_across_drawn_lenses(tiny_dataset: Path, tmp_path: Path) -> None:
    cfg = compose_train(
        [
            *tiny_run_overrides("depth", tiny_dataset, size=32),
            "data.camera.lenses=[{model:equidistant,fov_deg:190},"
            "{model:kannala_brandt,fov_deg:180,k:[0,0.01,0,0],weight:2}]",
            "data.camera.jitter={focal:0.05,principal_point_px:1,distortion:0.05}",
            "+model.n_query_channels=32",  # the mini-ViT's queries fit the 16^2 features of a 32^2 image
        ]
    )
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path / "run")
    results = train(cfg)
    assert "rmse" in results["metrics"]
    record = json.loads((tmp_path / "run" / "results.json").read_text())
    assert record["config"]["data"]["camera"]["lenses"][1]["model"] == "kannala_brandt"
    assert record["config"]["camera"]["model"] == "equidistant"  # the first lens: evaluation sample 0's
