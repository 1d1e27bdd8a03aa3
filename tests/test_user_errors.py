"""Bad inputs to the real commands end in one line, ``error: <message naming the key or file>``, exit status 2.

Each row of the tables runs a console command as a subprocess (the way a user meets it) and checks the exit
status, that the message names the key or file, and that no traceback is printed. The fast rows run
concurrently in one module fixture; the rows that need a corrupted dataset load frames in a DataLoader worker
and are ``slow``.
"""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader, Dataset

from airfisheye_bench.errors import EXIT_USER_ERROR, ConfigError, report_user_errors, user_message
from airfisheye_bench.io.errors import DatasetFormatError
from tests.doctests import assert_doctests_pass
from tests.training.test_train import tiny_run_overrides

ROOT = Path(__file__).resolve().parents[1]
TRAIN = "train.py"
EVALUATE = "scripts/evaluate.py"
EXPORT = "scripts/export_onnx.py"


@dataclass(frozen=True)
class Outcome:
    returncode: int
    stdout: str
    stderr: str


def run_command(script: str, args: list[str], debug: bool = False) -> Outcome:
    """Run ``python <script> <args>`` from the project root as a user would (``HYDRA_FULL_ERROR`` unset)."""
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    if debug:
        env["HYDRA_FULL_ERROR"] = "1"
    done = subprocess.run(
        [sys.executable, script, *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300
    )
    return Outcome(done.returncode, done.stdout, done.stderr)


def assert_one_line_error(outcome: Outcome, *names: str) -> str:
    """Exit status 2, no traceback, and exactly one ``error:`` line naming every one of ``names``."""
    output = outcome.stdout + outcome.stderr
    errors = [line for line in outcome.stderr.splitlines() if line.startswith("error: ")]
    assert outcome.returncode == EXIT_USER_ERROR, output[-3000:]
    assert "Traceback" not in output, output[-3000:]
    assert len(errors) == 1, outcome.stderr[-3000:]
    for name in names:
        assert name in errors[0], errors[0]
    return errors[0]


# ------------------------------------------------------------------------------------ fast rows (no dataset)
def _fast_rows(tmp: Path, dataset: Path) -> dict[str, tuple[str, list[str], tuple[str, ...]]]:
    """Row name -> (script, arguments, strings the message must contain)."""
    garbage = tmp / "garbage.bin"
    garbage.write_bytes(b"\x80\x04 this is not a checkpoint")
    onnx = tmp / "garbage.onnx"
    onnx.write_bytes(b"not a protobuf at all \xff\xff\xff")
    a_file = tmp / "a_file"
    a_file.write_text("x")
    train = [*tiny_run_overrides("seg", dataset)]
    return {
        "max_epochs": (
            TRAIN,
            [*train, "trainer.max_epochs=abc", f"hydra.run.dir={tmp}/r1"],
            ("trainer.max_epochs",),
        ),
        "camera_size": (
            TRAIN,
            [*train, "data.camera.size=abc", f"hydra.run.dir={tmp}/r2"],
            ("data.camera.size",),
        ),
        "lens_model": (
            TRAIN,
            [
                *tiny_run_overrides("seg", dataset),
                "data.root=null",
                "data.preset=tiny",
                f"paths.data_dir={tmp}/cache",
                "data.camera.model=fisheye9000",
                f"hydra.run.dir={tmp}/r3",
            ],
            ("data.camera.model", "fisheye9000", "equidistant"),
        ),
        "onnx_garbage": (EVALUATE, [f"onnx_path={onnx}", f"hydra.run.dir={tmp}/e1"], (str(onnx), "ONNX")),
        "ckpt_garbage": (EVALUATE, [f"ckpt_path={garbage}", f"hydra.run.dir={tmp}/e2"], (str(garbage),)),
        "export_proc": (EXPORT, [f"ckpt_path={garbage}", "out=/proc/x.onnx"], ("out=/proc/x.onnx",)),
        "export_sys": (EXPORT, [f"ckpt_path={garbage}", "out=/sys/x.onnx"], ("out=/sys/x.onnx",)),
        "export_parent_file": (
            EXPORT,
            [f"ckpt_path={garbage}", f"out={a_file}/x.onnx"],
            (f"{a_file}/x.onnx", f"{a_file} is a file"),
        ),
        "export_ckpt_garbage": (EXPORT, [f"ckpt_path={garbage}", f"out={tmp}/x.onnx"], (str(garbage),)),
    }


@dataclass(frozen=True)
class FastRows:
    tmp: Path
    outcomes: dict[str, Outcome]
    names: dict[str, tuple[str, ...]]


@pytest.fixture(scope="module")
def fast_rows(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> FastRows:
    """Every fast row run once, three at a time (the commands spend most of their time importing)."""
    tmp = tmp_path_factory.mktemp("user_errors")
    rows = _fast_rows(tmp, tiny_dataset)
    with ThreadPoolExecutor(max_workers=3) as pool:
        futures = {name: pool.submit(run_command, script, args) for name, (script, args, _) in rows.items()}
    return FastRows(
        tmp,
        {name: future.result() for name, future in futures.items()},
        {name: names for name, (_, _, names) in rows.items()},
    )


@pytest.mark.parametrize(
    "row",
    [
        "max_epochs",
        "camera_size",
        "lens_model",
        "onnx_garbage",
        "ckpt_garbage",
        "export_proc",
        "export_sys",
        "export_parent_file",
        "export_ckpt_garbage",
    ],
)
def test_fast_rows(row: str, fast_rows: FastRows) -> None:
    message = assert_one_line_error(fast_rows.outcomes[row], *fast_rows.names[row])
    if row in ("ckpt_garbage", "export_ckpt_garbage"):
        assert "weights_only" not in message  # PyTorch's advice to unpickle anything is not repeated
    if row == "lens_model":  # refused before the dataset was generated
        assert not any((fast_rows.tmp / "cache").rglob("dataset.yaml"))
    if row.startswith("export_"):
        assert not list(fast_rows.tmp.glob("*x.onnx*"))


def test_debug_switch_shows_the_traceback(tiny_dataset: Path, tmp_path: Path) -> None:
    args = [*tiny_run_overrides("seg", tiny_dataset), "trainer.max_epochs=abc", f"hydra.run.dir={tmp_path}"]
    outcome = run_command(TRAIN, args, debug=True)
    assert outcome.returncode != 0
    assert "Traceback" in outcome.stderr and "ConfigError: trainer.max_epochs='abc'" in outcome.stderr


# ------------------------------------------------------------------------------------- the wrapper in-process
@pytest.mark.parametrize(
    "module",
    [
        "airfisheye_bench.errors",
        "airfisheye_bench.constants",
        "airfisheye_bench.atomic",
        "airfisheye_bench.config_checks",
    ],
)
def test_docstring_examples(module: str) -> None:
    assert_doctests_pass(module)


def test_wrapper_exits_2_on_user_errors_and_reraises_bugs(capsys: pytest.CaptureFixture[str]) -> None:
    @report_user_errors
    def fails(error: Exception) -> None:
        raise error

    with pytest.raises(SystemExit) as stop:
        fails(ConfigError("data.batch_size=0: expected an integer >= 1"))
    assert stop.value.code == EXIT_USER_ERROR
    assert capsys.readouterr().err == "error: data.batch_size=0: expected an integer >= 1\n"
    with pytest.raises(ZeroDivisionError):  # a bug keeps its traceback
        fails(ZeroDivisionError("division by zero"))
    with pytest.raises(ValueError, match="not a user error"):  # a plain ValueError is not assumed to be one
        fails(ValueError("not a user error"))


class _BrokenFrames(Dataset):
    """Frame 1 is a corrupt file (a user error), frame 2 a bug."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __len__(self) -> int:
        return 3

    def __getitem__(self, index: int) -> torch.Tensor:
        if index == 1:
            raise DatasetFormatError(self.path, "cannot decode image (image file is truncated)")
        if index == 2:
            raise KeyError("a bug")
        return torch.zeros(1)


@pytest.mark.parametrize(
    ("index", "expected"),
    [(1, lambda path: f"{path}: cannot decode image (image file is truncated)"), (2, lambda path: None)],
)
def test_loader_worker_errors_keep_their_message(
    index: int, expected: Callable[[Path], str | None], tmp_path: Path
) -> None:
    path = tmp_path / "rgb" / "000001.png"
    loader = DataLoader(torch.utils.data.Subset(_BrokenFrames(path), [index]), num_workers=1)
    with pytest.raises(Exception) as caught:
        next(iter(loader))
    assert user_message(caught.value) == expected(path)


# ------------------------------------------------------------------------------ slow rows (corrupt datasets)
def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 3])


def _pickled_npy(path: Path) -> None:
    np.save(path, np.array([{"points": "object"}], dtype=object), allow_pickle=True)


def _garbage_yaml(path: Path) -> None:
    path.write_text("fx: [1, 2\n  :: not yaml ::\n")


CORRUPTIONS: dict[str, tuple[str, str, Callable[[Path], None]]] = {
    # name: (task, the files to corrupt (a glob in the training trajectory of the tiny preset), corruption)
    "truncated_png": ("seg", "cubemap/front/rgb/*.png", _truncate),
    "truncated_npy": ("completion", "lidar/*.npy", _truncate),
    "pickled_npy": ("completion", "lidar/*.npy", _pickled_npy),
    "garbage_calib": ("seg", "calib.yaml", _garbage_yaml),
}


@pytest.mark.slow
@pytest.mark.parametrize("row", [*sorted(CORRUPTIONS), "missing_split"])
def test_corrupt_dataset_rows(row: str, tiny_dataset: Path, tmp_path: Path) -> None:
    root = tmp_path / "dataset"
    shutil.copytree(tiny_dataset, root)
    if row == "missing_split":
        task, targets = "seg", [root / "splits" / "val.txt"]
        targets[0].unlink()
    else:
        task, pattern, corrupt = CORRUPTIONS[row]
        trajectory = (root / "splits" / "train.txt").read_text().split()[0].rpartition("/")[0]
        targets = sorted((root / trajectory).glob(pattern))
        assert targets, f"the tiny preset has no {trajectory}/{pattern}"
        for target in targets:  # every frame: which ones a short run reads first depends on the shuffle
            corrupt(target)
    args = [
        *tiny_run_overrides(task, root),
        "data.num_workers=1",  # read frames in a loader worker, as a real run does
        "test=false",
        f"hydra.run.dir={tmp_path / 'run'}",
    ]
    message = assert_one_line_error(run_command(TRAIN, args))
    assert any(str(target) in message for target in targets), message


def test_pickle_free_checkpoint_message_is_ours(tmp_path: Path) -> None:
    """The in-process reader gives the same message the commands print (no advice to unpickle anything)."""
    from airfisheye_bench.errors import InputFileError
    from airfisheye_bench.runs import read_checkpoint

    path = tmp_path / "evil.ckpt"
    path.write_bytes(pickle.dumps(ConfigError("an arbitrary object"), protocol=2))
    with pytest.raises(InputFileError, match=r"evil\.ckpt: not a readable checkpoint") as caught:
        read_checkpoint(path)
    assert "weights_only" not in str(caught.value)
