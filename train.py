"""Hydra entry point: ``python train.py task=seg|depth|completion [key=value ...]``.

Training itself is not wired yet: this composes the configuration and prints it, so config groups and overrides
can already be checked (``python train.py task=depth data.camera.size=256``).
"""

from __future__ import annotations

from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf

CONFIG_DIR = str(Path(__file__).resolve().parent / "configs")


@hydra.main(version_base="1.3", config_path=CONFIG_DIR, config_name="train")
def main(cfg: DictConfig) -> None:
    print(OmegaConf.to_yaml(cfg, resolve=False))


if __name__ == "__main__":
    main()
