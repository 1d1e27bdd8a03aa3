"""Re-using a run's data config: overrides and the datamodule."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from airfisheye_bench.errors import ConfigError
from datamodules import AirFisheyeDataModule
from datamodules.config import apply_data_overrides, instantiate_datamodule, parse_data_overrides


def test_command_line_overrides_are_parsed_as_yaml() -> None:
    parsed = parse_data_overrides(
        ["data.camera.size=128", "data.root=/data/af", "+data.camera.k=[0.1,0,0,0]", "data.augment=null"]
    )
    assert parsed == {"camera.size": 128, "root": "/data/af", "camera.k": [0.1, 0, 0, 0], "augment": None}
    with pytest.raises(ValueError, match=re.escape("data.<key>=<value>")):
        parse_data_overrides(["camera.size=128"])


def test_overrides_extend_sections_but_not_the_top_level() -> None:
    data = OmegaConf.create({"task": "depth", "camera": {"size": 512}, "size_ref": "${camera.size}"})
    cfg = apply_data_overrides(data, {"camera.model": "equisolid"}, task="depth")
    assert cfg.camera == {"size": 512, "model": "equisolid"} and cfg.size_ref == 512  # resolved copy
    assert "model" not in data.camera  # the input is untouched
    with pytest.raises(ValueError, match=re.escape("unknown override data.cammera.size")):
        apply_data_overrides(data, {"cammera.size": 64})
    with pytest.raises(ValueError, match="task=seg model"):
        apply_data_overrides(data, task="seg")


def test_instantiate_builds_a_single_process_datamodule(tiny_dataset: Path) -> None:
    data = OmegaConf.create(
        {
            "_target_": "datamodules.AirFisheyeDataModule",
            "task": "seg",
            "root": str(tiny_dataset),
            "camera": {"size": 32},
            "num_workers": 2,
            "persistent_workers": True,
        }
    )
    dm = instantiate_datamodule(data, "validate")
    assert isinstance(dm, AirFisheyeDataModule) and dm.val_dataloader().num_workers == 0
    data.root = str(tiny_dataset / "missing")
    # The datamodule's own message, not re-wrapped: it names the key and the fix already.
    with pytest.raises(ConfigError, match=r"data\.root='.*missing' is not a folder; point it at a dataset"):
        instantiate_datamodule(data, "validate")
