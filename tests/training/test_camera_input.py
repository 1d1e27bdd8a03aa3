"""docs/training.md ("Camera-aware models"): ``python train.py task=... data.preset=tiny trainer=debug
model.camera_input=rays`` trains every task with the ray map of each sample's lens beside the image, and across drawn
lenses; the checkpoint rebuilds the camera-aware model; a config whose data do not serve what the model takes is
refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from omegaconf import open_dict

from airfisheye_bench.config_checks import check_train_config
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.tasks.checkpoint import load_task
from airfisheye_bench.training import train
from tests.helpers.configs import compose_train
from tests.helpers.runs import tiny_run_overrides

pytestmark = pytest.mark.integration  # trains: seconds


@pytest.mark.parametrize("task", ["seg", "depth", "completion"])
def test_every_task_trains_a_camera_aware_model(tiny_rays_runs, task: str) -> None:
    run = tiny_rays_runs(task)
    record = json.loads((run / "results.json").read_text())
    assert record["config"]["model"]["camera_input"] == "rays"
    assert record["config"]["data"]["camera_input"] == "rays"  # the data follow the model
    module = load_task(run / "checkpoints" / "last.ckpt")
    assert module.camera_input == "rays" and module.net.camera_input == "rays"
    assert all(v == v for v in record["metrics"].values() if isinstance(v, float))  # scored, no NaN loss


def test_a_camera_aware_model_trains_across_drawn_lenses(tiny_dataset: Path, tmp_path: Path) -> None:
    cfg = compose_train(
        [
            *tiny_run_overrides("depth", tiny_dataset, size=32),
            "model.camera_input=rays",
            "data.camera.lenses=[{model:equidistant,fov_deg:190},{model:equisolid,fov_deg:180}]",
            "data.camera.jitter={focal:0.05,principal_point_px:1}",
            "+model.n_query_channels=32",  # the mini-ViT's queries fit the 16^2 features of a 32^2 image
        ]
    )
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path / "run")
    results = train(cfg)
    assert results["metrics"]["rmse"] > 0


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["model.camera_input=ray"], r"model.camera_input.*none, rays"),
        (
            ["model.camera_input=rays", "data.camera_input=none"],
            r"model.camera_input=rays but data.camera_input=none.*drop data.camera_input",
        ),
    ],
)
def test_what_the_data_cannot_feed_is_refused(overrides: list[str], message: str) -> None:
    cfg = compose_train(["task=depth", *overrides])
    with pytest.raises(ConfigError, match=message):
        check_train_config(cfg)
