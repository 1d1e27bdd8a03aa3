"""Hydra configs composed in-process (the compose API: no subprocess), as the applications compose them."""

from __future__ import annotations

from pathlib import Path

from hydra import compose, initialize_config_dir
from omegaconf import DictConfig, open_dict

from airfisheye_bench.constants import config_dir

CONFIG_DIR = str(config_dir())


def compose_train(overrides: list[str]) -> DictConfig:
    """``configs/train.yaml`` with ``overrides``; its output folder points nowhere (set it before training)."""
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        cfg = compose(config_name="train", overrides=overrides)
    with open_dict(cfg):
        cfg.paths.output_dir = "/tmp/unused"
    return cfg


def compose_eval(overrides: list[str], output_dir: Path) -> DictConfig:
    """``configs/evaluate.yaml`` with ``overrides``, writing into ``output_dir``."""
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        cfg = compose(config_name="evaluate", overrides=overrides)
    with open_dict(cfg):
        cfg.out = str(output_dir)  # output_dir, its former name, follows (${out})
    return cfg
