"""The package works installed from its wheel, outside the checkout: configs ship inside it, every script runs.

The wheel is built offline from a copy of the packaged files (``pip wheel --no-deps --no-build-isolation``) and
installed without dependencies into a virtual environment that sees the packages of the interpreter running the
tests (torch, Lightning, ...: the system's, or those of the venv the project is installed in). Every console script is then run from a temporary folder that is not the checkout.
"""

from __future__ import annotations

import json
import os
import shutil
import site
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
    "airfisheye-predict": ("ckpt_path", "input", "out", "allow_camera_mismatch"),
}


def _run(argv: list[str], cwd: Path, env: dict[str, str], timeout: int = 600) -> subprocess.CompletedProcess:
    done = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, (
        f"{argv} failed ({done.returncode}):\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    )
    return done


def _copy_source(target: Path) -> Path:
    """The files a wheel is built from, copied out of the checkout (no build folders left in it)."""
    for name in PACKAGED:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, target / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            target.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, target / name)
    return target


def _venv(path: Path, env: dict[str, str]) -> Path:
    """A virtual environment over the packages of the interpreter running the tests; without its own pip, so that
    interpreter's pip and setuptools (the versions ``pyproject.toml`` asks for) install into it.

    A venv is made from a base interpreter: inside a venv (the README's set-up) that is ``sys._base_executable``,
    whose ``--system-site-packages`` lack what the running venv installed (torch, Lightning, Hydra, pip), so a
    ``.pth`` file adds the running venv's site-packages after the new one's (the wheel's own copy comes first),
    as a site directory: its own ``.pth`` files are read too.
    """
    base = getattr(sys, "_base_executable", sys.executable)
    _run([base, "-m", "venv", "--system-site-packages", "--without-pip", str(path)], path.parent, env)
    if sys.prefix != sys.base_prefix:
        probe = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
        purelib = Path(_run([str(path / "bin" / "python"), "-c", probe], path.parent, env).stdout.strip())
        parent = [p for p in site.getsitepackages() if Path(p).is_relative_to(sys.prefix)]
        (purelib / "_tests_parent_venv.pth").write_text(
            "".join(f"import site; site.addsitedir({p!r})\n" for p in parent)
        )
    return path / "bin"


def _clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PROJECT_ROOT", "HYDRA_FULL_ERROR")}
    env["PIP_NO_INDEX"] = "1"  # no network: nothing may be fetched
    return env


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    """A virtual environment with the wheel installed (no dependencies: they come from the system)."""
    tmp = tmp_path_factory.mktemp("wheel")
    source = _copy_source(tmp / "source")
    env = _clean_env()
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-cache-dir",
          "-w", str(tmp / "dist"), str(source)], tmp, env)  # fmt: skip
    (wheel,) = (tmp / "dist").glob("airfisheye_bench-*.whl")
    bin_dir = _venv(tmp / "venv", env)
    _run([str(bin_dir / "python"), "-m", "pip", "install", "--no-deps", str(wheel)], tmp, env)
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
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


@pytest.mark.slow
def test_an_editable_install_reads_the_checkout_configs(tmp_path: Path) -> None:
    source = _copy_source(tmp_path / "source")
    env = _clean_env()
    bin_dir = _venv(tmp_path / "venv", env)
    _run([str(bin_dir / "python"), "-m", "pip", "install", "--no-deps", "--no-build-isolation", "--no-cache-dir",
          "-e", str(source)], tmp_path, env)  # fmt: skip
    work = tmp_path / "work"
    work.mkdir()
    probe = "from airfisheye_bench.constants import config_dir; print(config_dir())"
    assert _run([str(bin_dir / "python"), "-c", probe], work, env).stdout.strip() == str(source / "configs")
    assert "deep" in _run([str(bin_dir / "airfisheye-inspect"), "--help"], work, env).stdout
    assert "task" in _run([str(bin_dir / "airfisheye-train"), "--help"], work, env).stdout
