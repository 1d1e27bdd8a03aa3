"""A quick start ends with one line placing its test result against the README's table (the committed record)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from airfisheye_bench.runs import quickstart_record
from airfisheye_bench.runs.quickstart_record import load_record, quick_start_comparison, quick_start_line
from tests.helpers.commands import TRAIN, run_in_process
from tests.helpers.configs import compose_train
from tests.helpers.runs import tiny_run_overrides

RECORD = load_record()


def test_the_readme_command_is_the_tables_first_seed() -> None:
    """``python train.py task=<task>`` trains with seed 0, one of the seeds the record (the README's table) ran."""
    assert RECORD is not None, quickstart_record.RECORD
    for task, entry in RECORD["tasks"].items():
        assert entry["command"] == f"python train.py task={task}"
        assert compose_train([f"task={task}"]).seed == 0 and "0" in entry["seeds"]


@pytest.mark.parametrize("task", ["seg", "depth", "completion"])
def test_each_seed_of_the_record_reads_as_within_its_range(task: str) -> None:
    entry = RECORD["tasks"][task]
    content = RECORD["dataset"]["content_sha256"]
    line = quick_start_comparison(RECORD, task, entry["seeds"]["1"]["metrics"], 1, 1, content)
    primary, mean = entry["primary_metric"], entry["summary"][entry["primary_metric"]]["mean"]
    assert line.startswith("quick-start record (README table; seeds 0, 1, 2, 1 thread): ")
    assert f"{primary} {mean:.3f} ± " in line and "(seed 1: " in line
    assert "(seed 1, 1 thread): within the seeds' range" in line and "\n" not in line


def _hydra(overrides: list[str]) -> SimpleNamespace:
    """What ``quick_start_line`` reads of Hydra's running job: whether there is one, and its command line."""
    job = SimpleNamespace(overrides=SimpleNamespace(task=overrides))
    return SimpleNamespace(initialized=lambda: True, get=lambda: job)


def test_the_line_is_said_only_for_a_quick_start_with_a_record(monkeypatch: pytest.MonkeyPatch) -> None:
    content = RECORD["dataset"]["content_sha256"]
    metrics = {"mIoU": 0.5, "pixel_acc": 0.8}
    assert quick_start_line("seg", metrics, 0, 2, content) is None  # a library caller: no command line
    monkeypatch.setattr(quickstart_record, "HydraConfig", _hydra(["task=seg", "data.num_workers=0"]))
    line = quick_start_line("seg", metrics, 0, 2, content)
    assert "this run 0.500 (seed 0, 2 threads): above the seeds' range (better than every seed)" in line
    assert "not comparable" in quick_start_line("seg", metrics, 0, 2, "0" * 64)  # other data: said so
    monkeypatch.setattr(quickstart_record, "HydraConfig", _hydra(["task=seg", "data.preset=tiny"]))
    assert quick_start_line("seg", metrics, 0, 2, content) is None  # another run than the record's
    monkeypatch.setattr(quickstart_record, "HydraConfig", _hydra(["task=seg"]))
    monkeypatch.setattr(quickstart_record, "RECORD", quickstart_record.RECORD.with_name("absent.json"))
    assert quick_start_line("seg", metrics, 0, 2, content) is None  # an installed wheel: no docs/


@pytest.mark.integration
def test_train_py_ends_with_the_line(tiny_dataset, tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Through the command: the tiny run stands in for a quick start (the check of its command line is bypassed),
    and its data are not the record's, which the line says, in train.log too."""
    monkeypatch.setattr(quickstart_record, "is_quick_start", lambda overrides: True)
    run = tmp_path / "run"
    done = run_in_process(TRAIN, [*tiny_run_overrides("seg", tiny_dataset), f"hydra.run.dir={run}"])
    assert done.returncode == 0, done.stderr[-3000:]
    tiny = json.loads((run / "results.json").read_text())["dataset"]["content_sha256"]
    line = f"quick-start record (README table): not comparable, measured on other data (content 8cf07d19; this run's {tiny[:8]})"
    assert line in (run / "train.log").read_text()
