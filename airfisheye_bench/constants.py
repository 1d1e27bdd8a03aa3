"""Constants several layers share, kept at the bottom so that none of them imports another for a number, and
where the Hydra configs are.

The configs are the top-level ``configs/`` folder of the repository; a wheel ships the same files as the package
``airfisheye_bench.configs`` (``setup.py`` maps one onto the other).

Example:
    >>> [round(m / s, 3) for m, s in zip(IMAGENET_MEAN, IMAGENET_STD)]
    [2.118, 2.036, 1.804]
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

__all__ = ["IMAGENET_MEAN", "IMAGENET_STD", "config_dir"]

#: Per-channel RGB mean and standard deviation of ImageNet, in ``[0, 1]`` units: every encoder of the zoo was
#: pretrained on images normalised as ``(rgb / 255 - mean) / std``, so the datamodules feed them the same.
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


@cache
def config_dir() -> Path:
    """The folder of the Hydra configs (``train.yaml``, ``evaluate.yaml``, ``model/``, ...).

    A checkout (run in place or installed editable) reads the repository's ``configs/``; an installed wheel reads
    the copy inside the package.

    Example:
        >>> (config_dir() / "train.yaml").is_file()
        True
    """
    package = Path(__file__).resolve().parent
    checkout = package.parent / "configs"
    return checkout if (checkout / "train.yaml").is_file() else package / "configs"
