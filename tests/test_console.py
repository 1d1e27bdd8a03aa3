"""What a fresh run and an evaluation print (real processes: the console handlers and warning filters are what is
tested): each log message once, no warning that is not the user's business, the table logged. The console is
captured, as a redirected one (a file, nohup, SLURM): progress lines, no progress-bar frames, colour codes or model
summary table."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.helpers.commands import EVALUATE, TRAIN, run_command
from tests.helpers.runs import tiny_run_overrides

pytestmark = pytest.mark.integration  # trains, evaluates or exports: seconds per test

# A warning as Python prints it (`file.py:12: UserWarning: ...`) or as Lightning does (`file.py:12: ...`).
WARNING_LINE = re.compile(r"^\S+\.py:\d+: ", re.MULTILINE)
LOG_LINE = re.compile(r"^\[[\d\- :,]+\]\[[\w.]+\]\[\w+\] - (.*)$", re.MULTILINE)


#: A Kalibr camchain: the served camera comes from a calibration file, which each split resolves.
CAMCHAIN = """cam0:
  camera_model: ds
  distortion_model: none
  distortion_coeffs: []
  intrinsics: [-0.17, 0.59, 158.3, 158.3, 254.9, 256.9]
  resolution: [512, 512]
"""


@pytest.fixture(scope="module")  # built once: --dist loadscope runs a module on one worker (pyproject.toml)
def fresh_train(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Path]:
    """A fresh ``python train.py`` run in its own process (the console is what is tested): its console output and
    run directory, shared by the tests below. The callbacks are the default ones (the progress bar too), the
    logging interval is longer than the tiny epoch (a fresh run's trainer.log_every_n_steps on a small dataset),
    the lens a calibration file's."""
    folder = tmp_path_factory.mktemp("console")
    camchain = folder / "camchain.yaml"
    camchain.write_text(CAMCHAIN)
    args = [
        *(a for a in tiny_run_overrides("seg", tiny_dataset) if not a.startswith("callbacks.")),
        "trainer.log_every_n_steps=50",
        f"data.camera.calibration={camchain}",
        f"hydra.run.dir={folder / 'run'}",
    ]
    run = folder / "run"
    train = run_command(TRAIN, args)
    output = train.stdout + train.stderr
    assert train.returncode == 0, output[-3000:]
    return output, run


def test_a_fresh_train_prints_no_warning_that_is_not_the_users_business(
    fresh_train: tuple[str, Path],
) -> None:
    output, _ = fresh_train
    assert not WARNING_LINE.findall(output), output
    assert "INFO: " not in output  # Lightning's own console handler: its messages came twice
    assert "litlogger" not in output  # Lightning's advertisement of its cloud logger


def test_a_redirected_train_prints_no_terminal_only_output(fresh_train: tuple[str, Path]) -> None:
    """No progress-bar frame, colour code or model summary table, no line longer than a log line with a path; the
    served camera said once, the model's size in one line."""
    output, _ = fresh_train
    lines = output.splitlines()
    assert max(len(line) for line in lines) <= 300, max(lines, key=len)[:500]
    assert "\x1b" not in output  # no colour codes
    assert not re.search(r"[━┃│┏└]", output), output  # rich's bar and table characters
    # tqdm's bar: its frames' carriage returns are read as line ends here (text mode), its percentages stay.
    assert not re.search(r"\d+%\|", output), output
    assert "Trainable params" not in output and "Total params" not in output
    assert sum("camera from" in line for line in lines) == 1, output
    assert sum("model deeplabv3plus: " in line and "parameters" in line for line in lines) == 1, output


def test_a_fresh_train_prints_each_message_once(fresh_train: tuple[str, Path]) -> None:
    output, run = fresh_train
    logged = LOG_LINE.findall((run / "train.log").read_text())
    assert any("Seed set to" in m for m in logged)  # Lightning's messages reach the log file too
    for message in logged:
        assert output.count(message) == 1, message


def test_a_fresh_train_logs_an_epoch_line_and_a_compact_test_table(fresh_train: tuple[str, Path]) -> None:
    """Not a terminal (captured): a progress line per epoch, on the console and in train.log; the test metrics as a
    compact table in train.log, the per-ring, per-class values only in results.json."""
    output, run = fresh_train
    logged = LOG_LINE.findall((run / "train.log").read_text())
    epoch_lines = [m for m in logged if m.startswith("epoch 1/1: train/loss")]
    assert len(epoch_lines) == 1 and "val/mIoU" in epoch_lines[0], logged
    log_text = (run / "train.log").read_text()
    assert "test results (seg, best checkpoint)" in log_text and "mIoU by incidence-angle ring" in log_text
    assert "ring_0-30/IoU/" not in output + log_text and "test/ring_0-30" not in output


@pytest.fixture(scope="module")
def seg_run(tiny_runs) -> Path:
    """The session's tiny seg run (read-only)."""
    return tiny_runs("seg")


def test_evaluate_prints_its_table_once_and_no_warning(seg_run: Path, tmp_path: Path) -> None:
    run = seg_run
    evaluated = run_command(EVALUATE, [f"ckpt_path={run}", f"hydra.run.dir={tmp_path / 'eval'}"])
    assert evaluated.returncode == 0, evaluated.stderr[-3000:]
    assert not WARNING_LINE.findall(evaluated.stdout + evaluated.stderr), evaluated.stderr
    log = (tmp_path / "eval" / "evaluate.log").read_text()
    table = evaluated.stdout.strip()
    assert "mIoU" in table and table in log  # the printed table, in the command's log
