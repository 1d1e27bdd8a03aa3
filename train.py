"""``python train.py task=seg|depth|completion [group=option ...] [key=value ...]`` (``airfisheye-train``).

Composes ``configs/train.yaml``; see the README for the config groups, docs/training.md for the paper recipes
(``experiment=paper/seg|depth|completion``) and ``python train.py --help`` for the options. Resume a run with
``python train.py ckpt_path=last hydra.run.dir=<run dir>``. The application is
:func:`airfisheye_bench.cli.apps.train`.
"""

from airfisheye_bench.cli.apps import train

if __name__ == "__main__":
    train()
