"""``python train.py task=seg|depth|completion [group=option ...] [key=value ...]``

Composes ``configs/train.yaml``; see the README for the config groups and the paper recipes
(``experiment=paper/seg|depth|completion``). Resume a run with
``python train.py ckpt_path=last hydra.run.dir=<run dir>``.
"""

from __future__ import annotations

from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from airfisheye_bench.config_checks import check_common_values
from airfisheye_bench.errors import report_user_errors
from airfisheye_bench.runs import register_resolvers, resume_config

CONFIG_DIR = str(Path(__file__).resolve().parent / "configs")
register_resolvers()


@hydra.main(version_base="1.3", config_path=CONFIG_DIR, config_name="train")
@report_user_errors  # a user error: one line on stderr, exit status 2 (README, "When something goes wrong")
def main(cfg: DictConfig) -> float | None:
    # `ckpt_path=last hydra.run.dir=<run>` alone resumes with the run's saved configuration, not the defaults.
    cfg = resume_config(cfg, HydraConfig.get().overrides.task)
    # A mistyped value is answered at once, before the seconds of importing Lightning.
    check_common_values(cfg)
    from airfisheye_bench.training import train

    results = train(cfg)
    metric = results.get("metrics", {}).get(cfg.task.primary_metric) if results else None
    return float(metric) if metric is not None else None


if __name__ == "__main__":
    main()
