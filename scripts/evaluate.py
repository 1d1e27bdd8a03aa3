"""``python scripts/evaluate.py ckpt_path=... | onnx_path=... | task=... predictions=DIR [split=test]``.

Scores a checkpoint, an exported ONNX model or a folder of prediction files on a split with the paper's metrics,
writes ``results.json`` (the leaderboard format) and qualitative panels, and prints the table. See
``configs/evaluate.yaml`` for every option and :mod:`airfisheye_bench.evaluation.command` for the details.
"""

from __future__ import annotations

from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from airfisheye_bench.config_checks import check_common_values
from airfisheye_bench.errors import report_user_errors
from airfisheye_bench.runs import register_resolvers

CONFIG_DIR = str(Path(__file__).resolve().parents[1] / "configs")
register_resolvers()  # ${run_name:} in hydra.run.dir


@hydra.main(version_base="1.3", config_path=CONFIG_DIR, config_name="evaluate")
@report_user_errors  # a user error: one line on stderr, exit status 2
def main(cfg: DictConfig) -> None:
    check_common_values(cfg)  # a mistyped value is answered before the imports below
    from airfisheye_bench.evaluation.command import evaluate

    overrides = [o.lstrip("+") for o in HydraConfig.get().overrides.task if o.lstrip("+").startswith("data.")]
    evaluate(cfg, data_overrides=overrides)


if __name__ == "__main__":
    main()
