"""Console-script entry points (``airfisheye-train``, ``airfisheye-generate``, ...).

The Hydra configuration lives in ``configs/`` at the project root (the package is installed in editable mode,
as the README says), so every entry point composes the same files as ``python train.py``. Each command's main
function runs under :func:`airfisheye_bench.errors.report_user_errors`: a user error ends in one line,
``error: <message>``, and exit status 2. Each entry point imports its own command when called, so one command
does not pay for the others' imports (``airfisheye-inspect`` would load onnx and matplotlib otherwise); this top
layer is the one place a project module is imported inside a function (``tests/test_layers.py``).
"""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

PROJECT_ROOT = Path(__file__).resolve().parents[1]
CONFIG_DIR = PROJECT_ROOT / "configs"


def train() -> None:
    """``airfisheye-train``: the same as ``python train.py``."""
    sys.argv[0] = str(PROJECT_ROOT / "train.py")
    runpy.run_path(str(PROJECT_ROOT / "train.py"), run_name="__main__")


def evaluate() -> None:
    """``airfisheye-evaluate``: the same as ``python scripts/evaluate.py``."""
    script = PROJECT_ROOT / "scripts" / "evaluate.py"
    sys.argv[0] = str(script)
    runpy.run_path(str(script), run_name="__main__")


def generate() -> None:
    """``airfisheye-generate``: the same as ``python scripts/generate_synthetic.py``."""
    from airfisheye_bench.synth import cli as generate_command  # this command's own imports only

    sys.exit(generate_command.main(sys.argv[1:]))


def inspect() -> None:
    """``airfisheye-inspect root=DIR [deep=true]``: report missing or malformed files of a dataset."""
    from airfisheye_bench.io import inspect as inspect_command  # this command's own imports only

    sys.exit(inspect_command.main(sys.argv[1:]))


def transcode() -> None:
    """``airfisheye-transcode src=DIR dst=DIR [rgb=jpg] [depth=npy] [workers=N]``: re-encode a dataset's files."""
    from airfisheye_bench.io import transcode as transcode_command  # this command's own imports only

    sys.exit(transcode_command.main(sys.argv[1:]))


def leaderboard() -> None:
    """``airfisheye-leaderboard runs=DIR[,DIR] [out=leaderboard] [paper=true] [skip_invalid=false] [html=FILE]``."""
    from airfisheye_bench.evaluation import leaderboard_command  # this command's own imports only

    sys.exit(leaderboard_command.main(sys.argv[1:]))


def export() -> None:
    """``airfisheye-export ckpt_path=<ckpt or run dir> out=model.onnx [...]``: ``scripts/export_onnx.py``."""
    from airfisheye_bench.export import deploy as export_command  # this command's own imports only

    sys.exit(export_command.main(sys.argv[1:]))
