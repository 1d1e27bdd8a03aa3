"""The package works installed from its wheel, outside the checkout: configs ship inside it, every script runs.

The wheel is built offline from a copy of the packaged files (``pip wheel --no-deps --no-build-isolation``) and
installed without dependencies into a virtual environment that sees the system's packages (torch, Lightning,
...). Every console script is then run from a temporary folder that is not the checkout.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGED = ("pyproject.toml", "setup.py", "README.md", "airfisheye_bench", "datamodules", "models", "configs")
SCRIPTS = {
    # console script -> options its --help must list
    "airfisheye-train": ("task", "model", "trainer", "ckpt_path"),
    "airfisheye-evaluate": ("ckpt_path", "onnx_path", "predictions", "split"),
    "airfisheye-generate": ("preset", "out", "verify"),
    "airfisheye-inspect": ("root", "deep", "limit"),
    "airfisheye-transcode": ("src", "dst", "jpeg_quality", "link"),
    "airfisheye-export": ("ckpt_path", "out", "quantize", "data.<key>"),
    "airfisheye-leaderboard": ("runs", "out", "paper", "html"),
}


def _run(argv: list[str], cwd: Path, env: dict[str, str], timeout: int = 600) -> subprocess.CompletedProcess:
    done = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, (
        f"{argv} failed ({done.returncode}):\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    )
    return done


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    """A virtual environment with the wheel installed (no dependencies: they come from the system)."""
    tmp = tmp_path_factory.mktemp("wheel")
    source = tmp / "source"
    for name in PACKAGED:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, source / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            source.mkdir(exist_ok=True)
            shutil.copy2(src, source / name)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PROJECT_ROOT", "HYDRA_FULL_ERROR")}
    env["PIP_NO_INDEX"] = "1"  # no network: nothing may be fetched
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-cache-dir",
          "-w", str(tmp / "dist"), str(source)], tmp, env)  # fmt: skip
    (wheel,) = (tmp / "dist").glob("airfisheye_bench-*.whl")
    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], tmp, env)
    _run([str(venv / "bin" / "python"), "-m", "pip", "install", "--no-deps", str(wheel)], tmp, env)
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["AIRFISHEYE_DATA"] = str(tmp / "data")  # the tiny preset is generated into this cache
    work = tmp / "work"  # not the checkout: nothing may be read from there
    work.mkdir()
    return work, env


@pytest.mark.slow
def test_the_wheel_holds_the_configs_and_is_what_runs(installed: tuple[Path, dict[str, str]]) -> None:
    work, env = installed
    probe = (
        "import airfisheye_bench, datamodules, models; from airfisheye_bench.constants import config_dir; "
        "print(airfisheye_bench.__file__); print(datamodules.__file__); print(config_dir())"
    )
    package, data, configs = _run(["python", "-c", probe], work, env).stdout.split()
    venv = Path(env["PATH"].split(os.pathsep)[0]).parent
    for path in (package, data, configs):
        assert Path(path).is_relative_to(venv), path  # the installed copy, not the checkout
    assert (Path(configs) / "train.yaml").is_file() and (Path(configs) / "model" / "nlspn.yaml").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("script", sorted(SCRIPTS))
def test_every_console_script_answers_help(script: str, installed: tuple[Path, dict[str, str]]) -> None:
    work, env = installed
    for flag in ("--help", "-h"):
        out = _run([script, flag], work, env).stdout
        assert all(name in out for name in SCRIPTS[script]), out


@pytest.mark.slow
def test_train_runs_outside_the_checkout(installed: tuple[Path, dict[str, str]]) -> None:
    work, env = installed
    _run(["airfisheye-train", "task=seg", "data.preset=tiny", "trainer=debug"], work, env)
    (results,) = (work / "logs" / "seg" / "runs").glob("*/results.json")
    record = json.loads(results.read_text())
    assert record["task"] == "seg" and 0.0 <= record["metrics"]["mIoU"] <= 1.0
    assert (results.parent / "config.yaml").is_file() and (
        results.parent / "checkpoints" / "last.ckpt"
    ).is_file()
