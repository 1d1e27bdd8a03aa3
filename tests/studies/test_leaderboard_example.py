"""docs/evaluation.md's leaderboard example: the kept results.json files say where they come from, and the doc's block
is what airfisheye-leaderboard prints from them."""

from __future__ import annotations

import json
from pathlib import Path

from airfisheye_bench.cli.commands import leaderboard
from airfisheye_bench.evaluation import write_results
from airfisheye_bench.studies import leaderboard_example as example
from airfisheye_bench.studies.generated_blocks import block_in

ROOT = Path(__file__).resolve().parents[2]
RECORD = ROOT / example.RECORD
STEPS = [s for s in example.steps(Path("/work")) if s.results]


def test_keep_adds_the_provenance_and_the_step_and_changes_nothing_else(tmp_path: Path) -> None:
    written = write_results(tmp_path / "run" / "results.json", "depth", "test", {"rmse": 2.0})
    step = example.steps(tmp_path)[1]
    kept = example.keep(written, tmp_path / "kept", {"commit": "c" * 40, "command": "python x.py"}, step)
    record, original = json.loads(kept.read_text()), json.loads(written.read_text())
    assert kept == tmp_path / "kept" / "checkpoint" / "results.json"
    assert record.pop("provenance") == {"commit": "c" * 40, "command": "python x.py", "step": step.command()}
    assert record == original


def test_each_step_is_kept_with_its_command_and_the_tiny_data() -> None:
    for step in STEPS:
        record = json.loads((RECORD / step.name / "results.json").read_text())
        assert record["provenance"]["command"].startswith("python scripts/leaderboard_example.py")
        assert record["provenance"]["step"].split(" ")[:2] == ["python", step.argv[0]]
        assert record["dataset"]["name"] == "airfisheye-synthetic-tiny" and record["task"] == "depth"
    training = json.loads((RECORD / "training_test" / "results.json").read_text())["config"]["trainer"]
    assert training["max_epochs"] == 1 and not {"limit_train_batches", "fast_dev_run"} & set(
        training
    )  # a full epoch


def test_the_doc_block_is_what_the_leaderboard_prints_from_the_kept_files(tmp_path: Path) -> None:
    assert leaderboard([f"runs={RECORD}", f"out={tmp_path}", "paper=false"]) == 0
    printed = (tmp_path / "leaderboard.md").read_text()
    assert printed == (RECORD / "leaderboard.md").read_text(), (
        "run python scripts/leaderboard_example.py --report"
    )
    doc = (ROOT / "docs" / "evaluation.md").read_text()
    assert block_in(doc, example.BEGIN, example.END) == example.doc_block(printed)
