"""``python train.py task=seg|depth|completion [group=option ...] [key=value ...]``

Composes ``configs/train.yaml``; see the README for the config groups and the paper recipes
(``experiment=paper/seg|depth|completion``).
"""

from __future__ import annotations

from pathlib import Path

import hydra
from omegaconf import DictConfig

CONFIG_DIR = str(Path(__file__).resolve().parent / "configs")


@hydra.main(version_base="1.3", config_path=CONFIG_DIR, config_name="train")
def main(cfg: DictConfig) -> float | None:
    from airfisheye_bench.training import train

    results = train(cfg)
    metric = results.get("metrics", {}).get(cfg.task.primary_metric) if results else None
    return float(metric) if metric is not None else None


if __name__ == "__main__":
    main()
