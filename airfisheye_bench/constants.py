"""Facts every layer may use: where the Hydra configs are.

The configs are the top-level ``configs/`` folder of the repository; a wheel ships the same files as the package
``airfisheye_bench.configs`` (``setup.py`` maps one onto the other).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path


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
