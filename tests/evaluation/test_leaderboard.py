"""The leaderboard: collection, validation, ranking, paper rows, rendering, files and the command line."""

from __future__ import annotations

import csv
import io
import json
import os
import re
import sys
from pathlib import Path

import pytest

import airfisheye_bench.evaluation.leaderboard as lb
from airfisheye_bench.cli import leaderboard
from airfisheye_bench.evaluation import (
    LeaderboardError,
    build_leaderboard,
    collect_results,
    find_results,
    load_entry,
    paper_baselines,
    write_results,
)
from airfisheye_bench.specs import all_tasks
from tests.helpers.commands import exit_status

HASH_A = "a1b2c3d4" + "0" * 56
HASH_B = "ffee0011" + "1" * 56
PROJECT_ROOT = Path(__file__).resolve().parents[2]


def _write(root: Path, run: str, task: str, metrics: dict, **kw) -> Path:
    """A results.json in ``root/run/`` on dataset ``synth`` (manifest HASH_A) unless told otherwise."""
    kw.setdefault("dataset", {"root": "/data/synth", "name": "synth", "manifest_sha256": HASH_A})
    kw.setdefault("model", {"name": "deeplabv3plus", "config": {"encoder_name": "resnet18"}})
    return write_results(root / run / "results.json", task, kw.pop("split", "test"), metrics, **kw)


def _groups(board, task: str) -> list[list[tuple[int | None, str]]]:
    table = next(t for t in board.tables if t.task == task)
    return [[(rank, e.run) for rank, e in g.rows] for g in table.groups]


def _csv_rows(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


# ------------------------------------------------------------------------------------------------ ranking


def test_segmentation_is_ranked_by_miou_higher_first_with_shared_ranks(tmp_path: Path) -> None:
    _write(tmp_path, "low", "seg", {"mIoU": 0.21, "pixel_acc": 0.6})
    _write(tmp_path, "high", "seg", {"mIoU": 0.45, "pixel_acc": 0.8})
    _write(tmp_path, "tie_a", "seg", {"mIoU": 0.30, "pixel_acc": 0.7})
    _write(tmp_path, "tie_b", "seg", {"mIoU": 0.30, "pixel_acc": 0.7})
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    assert _groups(board, "seg") == [[(1, "high"), (2, "tie_a"), (2, "tie_b"), (4, "low")]]
    assert board.tables[0].primary == "mIoU" and board.tables[0].higher_is_better


def test_rows_that_print_the_same_share_a_rank_in_every_rendering(tmp_path: Path) -> None:
    # 4.2001 and 4.2004 both print as 4.200: one rank, whatever the hidden digits; then 4 (competition ranking).
    for run, rmse in (("a", 4.2004), ("b", 3.9), ("c", 4.2001), ("d", 5.0)):
        _write(tmp_path, run, "depth", {"rmse": rmse})
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    assert _groups(board, "depth") == [[(1, "b"), (2, "a"), (2, "c"), (4, "d")]]
    ranks = {row["run"]: row["rank"] for row in _csv_rows(board.to_csv())}
    assert ranks == {"a": "2", "b": "1", "c": "2", "d": "4"}
    printed = [line for line in board.to_markdown().splitlines() if "| 4.200 |" in line]
    assert len(printed) == 2 and all(line.startswith("| 2 |") for line in printed)
    from airfisheye_bench.evaluation.leaderboard.html import render_html

    html_ranks = re.findall(
        r'<td class="num" data-value="(\d)">\d</td><td class="run" data-value="\w">\w</td><td class="text">(?:<a [^>]*>)?deeplab',
        render_html(board),
    )
    assert html_ranks == ["1", "2", "2", "4"]


def test_percent_metrics_tie_on_the_printed_percentage(tmp_path: Path) -> None:
    for run, miou in (("x", 0.51234), ("y", 0.51181), ("z", 0.5)):
        _write(tmp_path, run, "seg", {"mIoU": miou})
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    assert _groups(board, "seg") == [[(1, "x"), (1, "y"), (3, "z")]]  # 51.2 and 51.2


@pytest.mark.parametrize("task", ["depth", "completion"])
def test_depth_tasks_are_ranked_by_rmse_lower_first(tmp_path: Path, task: str) -> None:
    for run, rmse, abs_rel in (("mid", 8.0, 0.05), ("best", 4.5, 0.30), ("worst", 15.0, 0.01)):
        _write(tmp_path, run, task, {"rmse": rmse, "abs_rel": abs_rel})
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    # Sorted by RMSE, not by AbsRel (which would give the reverse order).
    assert _groups(board, task) == [[(1, "best"), (2, "mid"), (3, "worst")]]
    assert not board.tables[0].higher_is_better


def test_results_on_different_datasets_or_splits_are_ranked_apart(tmp_path: Path) -> None:
    _write(tmp_path, "a_good", "seg", {"mIoU": 0.5})
    _write(tmp_path, "a_bad", "seg", {"mIoU": 0.1})
    # Same dataset name, regenerated (other manifest): a different dataset.
    other = {"name": "synth", "manifest_sha256": HASH_B}
    _write(tmp_path, "b_only", "seg", {"mIoU": 0.3}, dataset=other)
    _write(tmp_path, "a_val", "seg", {"mIoU": 0.9}, split="val")
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    assert _groups(board, "seg") == [[(1, "a_good"), (2, "a_bad")], [(1, "a_val")], [(1, "b_only")]]
    titles = [g.title for g in board.tables[0].groups]
    assert titles == [
        "synth (manifest a1b2c3d4), test split",
        "synth (manifest a1b2c3d4), val split",
        "synth (manifest ffee0011), test split",
    ]
    md = board.to_markdown()
    assert all(f"### {title}" in md for title in titles)


def test_the_same_content_written_by_another_encoder_is_one_dataset(tmp_path: Path) -> None:
    # Two installations wrote the same arrays with other PNG bytes: other manifests, one content identity.
    content = "c0ffee" * 10 + "abcd"
    _write(
        tmp_path,
        "here",
        "seg",
        {"mIoU": 0.5},
        dataset={"name": "synth", "manifest_sha256": HASH_A, "content_sha256": content},
    )
    _write(
        tmp_path,
        "there",
        "seg",
        {"mIoU": 0.4},
        dataset={"name": "synth", "manifest_sha256": HASH_B, "content_sha256": content},
    )
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    assert _groups(board, "seg") == [[(1, "here"), (2, "there")]]
    assert [g.title for g in board.tables[0].groups] == ["synth (content c0ffeec0), test split"]
    assert {r["content_sha256"] for r in _csv_rows(board.to_csv())} == {content}


def test_every_rendering_says_the_content_hash_groups_the_rows(tmp_path: Path) -> None:
    """One wording, in the markdown and the page: the content hash (``content_sha256``) names a dataset, the
    manifest hash only stands in for results written before it."""
    from airfisheye_bench.evaluation.leaderboard.html import render_html

    _write(tmp_path, "old", "seg", {"mIoU": 0.5})  # no content hash: grouped by its manifest's
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    assert lb.GROUPING in board.to_markdown() and "(`content_sha256`" in lb.GROUPING
    assert "### synth (manifest a1b2c3d4), test split" in board.to_markdown()
    page = render_html(board)
    assert "content hash (<code>content_sha256</code>" in page and "(<code>manifest_sha256</code>" in page
    assert "synth (manifest a1b2c3d4), test split" in page


# ------------------------------------------------------------------------------------------------ paper rows


def test_paper_rows_are_included_by_default_in_their_own_group(tmp_path: Path) -> None:
    _write(tmp_path, "mine", "seg", {"mIoU": 0.9})
    board = build_leaderboard(collect_results([tmp_path]))
    assert [t.task for t in board.tables] == ["seg", "depth", "completion"]
    seg = board.tables[0]
    # Even a higher mIoU on synthetic data does not outrank the paper: each is first in its own group.
    assert _groups(board, "seg") == [[(1, "paper IV-A")], [(1, "mine")]]
    assert seg.groups[0].title.startswith("AirFisheye (released), test split")
    paper_row = seg.groups[0].rows[0][1]
    assert paper_row.paper and paper_row.source == "paper (released AirFisheye)" and paper_row.split == "test"

    md = board.to_markdown()
    assert "| 1 | DeepLabV3+ / ResNet50 | paper | paper (released AirFisheye) | test | – | 51.2 | – |" in md
    assert (
        "| AdaBins / ResNet50 | paper | paper (released AirFisheye) | test | – | 0.1320 | 2.575 | 13.324 | 0.270 | 0.865 |"
        in md
    )
    assert (
        "| NLSPN / ResNet34 | paper | paper (released AirFisheye) | test | – | 0.0834 | 6.971 | 2.377 | 0.934 |"
        in md
    )
    assert "| 1 | deeplabv3plus / resnet18 | – | ours (synth) | test | – | 90.0 |" in md


def test_paper_rows_hold_the_design_table_as_fractions() -> None:
    by_task = {e.task: e for e in paper_baselines()}
    assert dict(by_task["seg"].metrics) == {"mIoU": 0.512}
    assert by_task["depth"].metrics["rmse"] == 13.324 and by_task["depth"].metrics["delta3"] == 0.972
    assert (
        by_task["completion"].metrics["abs_rel"] == 0.0834 and by_task["completion"].metrics["mae"] == 2.377
    )
    # Not reported by the paper: absent, not zero.
    assert "pixel_acc" not in by_task["seg"].metrics and "sq_rel" not in by_task["completion"].metrics
    assert all(e.paper and e.path is None for e in paper_baselines())


def test_paper_rows_can_be_left_out(tmp_path: Path) -> None:
    _write(tmp_path, "mine", "depth", {"rmse": 3.0})
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    assert [t.task for t in board.tables] == ["depth"]
    assert not any(e.paper for t in board.tables for g in t.groups for _, e in g.rows)
    assert "paper (released AirFisheye)" not in board.to_markdown() + board.to_csv()
    assert "plus the paper's baselines" not in board.to_markdown()


# ------------------------------------------------------------------------------------------ NaN and null


def test_nan_and_null_values_are_missing_and_rank_last(tmp_path: Path) -> None:
    _write(tmp_path, "ok", "depth", {"rmse": 9.0, "abs_rel": 0.2, "delta1": float("nan")})
    _write(tmp_path, "no_rmse", "depth", {"rmse": float("nan"), "abs_rel": 0.1})
    # A hand-written file with JSON's non-standard NaN / Infinity literals is read the same way.
    hand = tmp_path / "hand" / "results.json"
    hand.parent.mkdir()
    record = json.loads((tmp_path / "ok" / "results.json").read_text())
    hand.write_text(
        json.dumps(record)
        .replace('"rmse": 9.0', '"rmse": NaN')
        .replace('"abs_rel": 0.2', '"abs_rel": Infinity')
    )

    assert json.loads((tmp_path / "no_rmse" / "results.json").read_text())["metrics"]["rmse"] is None
    entry = load_entry(hand)
    assert entry.metrics["rmse"] is None and entry.metrics["abs_rel"] is None

    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    assert _groups(board, "depth") == [[(1, "ok"), (None, "hand"), (None, "no_rmse")]]
    md = board.to_markdown()
    assert (
        "| 1 | deeplabv3plus / resnet18 | – | ours (synth) | test | – | 0.2000 | – | 9.000 | – | – | – | – |"
        in md
    )
    assert "| – | deeplabv3plus / resnet18 | – | ours (synth) | test | – | 0.1000 | – | – |" in md
    rows = {r["run"]: r for r in _csv_rows(board.to_csv())}
    assert rows["no_rmse"]["rank"] == "" and rows["no_rmse"]["rmse"] == "" and rows["ok"]["delta1"] == ""


# ------------------------------------------------------------------------------------------- invalid files


def _bad_files(root: Path) -> list[Path]:
    bad = {
        "truncated": "{",
        "missing_keys": json.dumps({"version": 1, "task": "seg"}),
        "unknown_task": json.dumps({"version": 1, "task": "pose", "split": "test", "metrics": {}}),
        "text_metric": json.dumps(
            {"version": 1, "task": "seg", "split": "test", "metrics": {"mIoU": "high"}}
        ),
        "future_version": json.dumps({"version": 99, "task": "seg", "split": "test", "metrics": {}}),
        "not_an_object": json.dumps([{"version": 1}]),
    }
    paths = []
    for name, text in bad.items():
        path = root / name / "results.json"
        path.parent.mkdir(parents=True)
        path.write_text(text)
        paths.append(path)
    return paths


def test_invalid_files_are_all_listed_in_one_error(tmp_path: Path) -> None:
    _write(tmp_path, "good", "seg", {"mIoU": 0.4})
    bad = _bad_files(tmp_path)
    with pytest.raises(LeaderboardError) as info:
        collect_results([tmp_path])
    assert len(info.value.problems) == len(bad)
    message = str(info.value)
    assert message.startswith(f"{len(bad)} invalid results.json file(s)")
    for path in bad:
        assert str(path) in message
    assert "'pose'" in message and "metrics.mIoU is 'high'" in message and "unsupported version 99" in message


def test_invalid_files_can_be_skipped_with_a_warning(tmp_path: Path) -> None:
    _write(tmp_path, "good", "seg", {"mIoU": 0.4})
    bad = _bad_files(tmp_path)
    with pytest.warns(UserWarning) as caught:
        entries = collect_results([tmp_path], skip_invalid=True)
    assert [e.run for e in entries] == ["good"]
    warned = " ".join(str(w.message) for w in caught)
    assert all(str(path) in warned for path in bad)


# ---------------------------------------------------------------------------------------------- collection


def test_files_and_directories_are_collected_recursively_once(tmp_path: Path) -> None:
    deep = _write(tmp_path / "logs" / "seg" / "runs", "2025-01-01_00-00-00", "seg", {"mIoU": 0.2})
    other = _write(tmp_path / "elsewhere", "x", "depth", {"rmse": 3.0})
    (tmp_path / "logs" / "notes.json").write_text("{}")  # only results.json files are picked up in folders
    found = find_results([tmp_path / "logs", deep, other])
    assert found == sorted([deep, other])


def test_a_run_tracked_with_mlflow_is_collected_once(tmp_path: Path) -> None:
    """``logger=mlflow`` keeps a copy of ``results.json`` among the run's artifacts in its store under the run
    (``<run>/mlflow/mlflow.db``, ``<run>/mlflow/artifacts/<experiment>/<run id>/artifacts/``): one run, not two."""
    run = _write(tmp_path / "logs" / "seg" / "runs", "2025-01-01_00-00-00", "seg", {"mIoU": 0.2})
    store = run.parent / "mlflow"
    store.mkdir()
    (store / "mlflow.db").write_bytes(b"SQLite format 3\0")
    copy = store / "artifacts" / "1" / "0123abcd" / "artifacts" / "results.json"
    copy.parent.mkdir(parents=True)
    copy.write_bytes(run.read_bytes())
    legacy = run.parent / "mlruns" / "0" / "abcd" / "artifacts" / "results.json"  # a file store of MLflow 2
    legacy.parent.mkdir(parents=True)
    legacy.write_bytes(run.read_bytes())
    assert find_results([tmp_path / "logs"]) == [run]
    assert find_results([copy]) == [copy]  # a file given by name is taken as it is


def test_missing_paths_and_empty_folders_are_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nope: no such file or directory"):
        find_results([tmp_path / "nope"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match=r"no results\.json found under .*empty"):
        find_results([tmp_path / "empty"])


def test_model_label_and_run_identity(tmp_path: Path) -> None:
    smp = {"name": "smp", "config": {"name": "smp", "arch": "unet", "encoder_name": "resnet34"}}
    assert load_entry(_write(tmp_path, "r1", "seg", {"mIoU": 0.1}, model=smp)).model == "smp-unet / resnet34"
    named = {"name": "nlspn", "run_name": "nlspn-18steps", "config": {}}
    entry = load_entry(_write(tmp_path, "r2", "completion", {"rmse": 1.0}, model=named))
    assert (entry.model, entry.run) == ("nlspn", "nlspn-18steps")
    bare = load_entry(_write(tmp_path, "r3", "depth", {"rmse": 1.0}, model={}, dataset={}))
    assert (bare.model, bare.run, bare.source, bare.manifest_sha256) == (
        "unknown model",
        "r3",
        "ours (unknown dataset)",
        None,
    )


def test_rim_column_is_the_outermost_ring_of_the_primary_metric(tmp_path: Path) -> None:
    rings = {"ring_0-30/rmse": 1.0, "ring_60-80/rmse": 2.0, "ring_80-95/rmse": 7.25, "ring_80-95/mae": 5.0}
    _write(tmp_path, "ringed", "depth", {"rmse": 3.0}, breakdown={**rings, "range_0-10/rmse": 0.5})
    board = build_leaderboard(collect_results([tmp_path]))
    depth = next(t for t in board.tables if t.task == "depth")
    assert depth.rim_key == "ring_80-95/rmse"
    assert "rim 80-95° RMSE (m)" in board.to_markdown() and "| 7.250 | ringed |" in board.to_markdown()
    # Tasks whose results have no ring breakdown get no rim column.
    assert next(t for t in board.tables if t.task == "seg").rim_key is None
    headers = [line for line in board.to_markdown().splitlines() if line.startswith("| rank")]
    assert [("rim" in h) for h in headers] == [False, True, True, False]  # seg, depth x2, completion


# ------------------------------------------------------------------------------------------------- outputs


def test_markdown_has_one_section_per_task_with_order_and_units(tmp_path: Path) -> None:
    _write(tmp_path, "s", "seg", {"mIoU": 0.2441, "pixel_acc": 0.6937})
    md = build_leaderboard(collect_results([tmp_path])).to_markdown()
    assert md.startswith("# AirFisheye-bench leaderboard\n")
    assert "1 result(s) plus the paper's baselines" in md and "printed in %" in md
    sections = [line for line in md.splitlines() if line.startswith("## ")]
    assert sections == [
        "## Semantic segmentation (seg)",
        "## Monocular depth (depth)",
        "## Depth completion (completion)",
    ]
    assert "Sorted by mIoU (%), higher is better;" in md and "Sorted by RMSE (m), lower is better;" in md
    assert "| 24.4 | 69.4 |" in md  # fractions printed as percentages, one decimal like the paper
    header = "| rank | model | evaluated | source | split | camera | mIoU (%) | pixel acc (%) | run |"
    assert header in md and "|---:|---|---|---|---|---|---:|---:|---|" in md


def test_csv_round_trips_every_value(tmp_path: Path) -> None:
    metrics = {
        "abs_rel": 0.28213456789,
        "sq_rel": 3.1,
        "rmse": 15.512345678901234,
        "rmse_log": 0.41,
        "delta1": 0.516,
        "delta2": 0.7,
        "delta3": 0.81,
    }
    _write(tmp_path, "d", "depth", metrics, breakdown={"ring_80-95/rmse": 21.5})
    _write(tmp_path, "s", "seg", {"mIoU": 0.3, "pixel_acc": 0.7, "IoU/sky": 0.9})
    board = build_leaderboard(collect_results([tmp_path]))
    text = board.to_csv()
    assert text.splitlines()[0] == ",".join(lb.csv_columns())
    assert set(lb.csv_columns()) >= {m for spec in all_tasks() for m in spec.metric_keys}
    rows = _csv_rows(text)
    assert [r["task"] for r in rows] == ["seg", "seg", "depth", "depth", "completion"]
    mine = next(r for r in rows if r["run"] == "d")
    assert {k: float(mine[k]) for k in metrics} == metrics  # exact floats, no rounding
    assert (mine["rim_key"], float(mine["rim_value"])) == ("ring_80-95/rmse", 21.5)
    assert (mine["rank"], mine["dataset"], mine["manifest_sha256"]) == ("1", "synth", HASH_A)
    assert mine["primary_metric"] == "rmse" and mine["path"].endswith("results.json")
    paper = next(r for r in rows if r["task"] == "completion")
    assert paper["source"] == "paper (released AirFisheye)" and float(paper["abs_rel"]) == 0.0834
    assert paper["sq_rel"] == "" and paper["path"] == ""


def test_write_is_atomic_and_leaves_no_temporaries(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _write(tmp_path / "runs", "s", "seg", {"mIoU": 0.3})
    board = build_leaderboard(collect_results([tmp_path / "runs"]))
    out = tmp_path / "out" / "nested"
    md, table = board.write(out)
    assert sorted(p.name for p in out.iterdir()) == ["leaderboard.csv", "leaderboard.md"]
    assert md.read_text() == board.to_markdown() and table.read_text() == board.to_csv()

    # A write that fails half-way keeps the previous files whole and leaves no temporary behind.
    def fail(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="disk full"):
        build_leaderboard([], paper=True).write(out)
    assert sorted(p.name for p in out.iterdir()) == ["leaderboard.csv", "leaderboard.md"]
    assert md.read_text() == board.to_markdown()


# -------------------------------------------------------------------------------------------- command line


def test_main_writes_both_files_and_prints_the_markdown(tmp_path: Path, capsys) -> None:
    _write(tmp_path / "a", "s", "seg", {"mIoU": 0.3})
    other = _write(tmp_path / "b", "d", "depth", {"rmse": 4.0})
    out = tmp_path / "board"
    assert leaderboard([f"runs=[{tmp_path / 'a'},{other}]", f"out={out}"]) == 0
    printed = capsys.readouterr()
    assert printed.out == (out / "leaderboard.md").read_text()
    assert "| 1 | deeplabv3plus / resnet18 | – | ours (synth) | test | – | 30.0 |" in printed.out
    assert "paper IV-A" in printed.out and str(out / "leaderboard.csv") in printed.err
    assert {r["run"] for r in _csv_rows((out / "leaderboard.csv").read_text())} >= {"s", "d"}

    assert leaderboard([f"runs={tmp_path / 'a'}", f"out={out}", "paper=false"]) == 0
    assert "paper (released AirFisheye)" not in (out / "leaderboard.md").read_text()


def test_main_errors(tmp_path: Path, capsys) -> None:
    assert exit_status(leaderboard, []) == 2 and "runs= is required" in capsys.readouterr().err
    assert exit_status(leaderboard, ["runs=x", "colour=red"]) == 2
    assert "unknown option 'colour'" in capsys.readouterr().err
    assert exit_status(leaderboard, ["runs=x", "paper=maybe"]) == 2
    assert "paper=maybe: expected a boolean" in capsys.readouterr().err
    assert exit_status(leaderboard, ["runs=a,b"]) == 2 and "runs=[a,b]" in capsys.readouterr().err
    assert exit_status(leaderboard, ["runs=x", "html=page.txt"]) == 2
    assert "html=page.txt: expected an .html file name" in capsys.readouterr().err
    assert leaderboard([f"runs={tmp_path / 'missing'}"]) == 1
    assert "missing: no such file or directory" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert leaderboard([f"runs={tmp_path / 'empty'}"]) == 1
    assert "no results.json found" in capsys.readouterr().err

    _write(tmp_path / "runs", "good", "seg", {"mIoU": 0.3})
    bad = _bad_files(tmp_path / "runs")
    out = tmp_path / "board"
    assert leaderboard([f"runs={tmp_path / 'runs'}", f"out={out}"]) == 1
    err = capsys.readouterr().err
    assert all(str(p) in err for p in bad) and "skip_invalid=true" in err
    assert not out.exists()  # nothing written when the input is rejected

    assert leaderboard([f"runs={tmp_path / 'runs'}", f"out={out}", "skip_invalid=true"]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("warning: skipped invalid results.json") == len(bad)
    assert "| good |" in captured.out

    only_bad = tmp_path / "only_bad"
    _bad_files(only_bad)
    assert leaderboard([f"runs={only_bad}", "skip_invalid=true", f"out={out}"]) == 1
    assert "no valid results.json" in capsys.readouterr().err


DEBUG_TRAINER = {"max_epochs": 1, "limit_train_batches": 2, "limit_val_batches": 1, "limit_test_batches": 1}


def test_runs_of_the_debug_trainer_are_left_out_unless_asked(tmp_path: Path, capsys) -> None:
    """The install check (``trainer=debug``) tests on one batch: its row is no result. Its ``config.trainer``
    (what training writes into ``results.json``) tells it; the command leaves it out with a note, and
    ``include_debug=true`` ranks it, marked."""
    _write(tmp_path / "runs", "real", "seg", {"mIoU": 0.2}, config={"trainer": {"max_epochs": 8}})
    _write(tmp_path / "runs", "smoke", "seg", {"mIoU": 0.3}, config={"trainer": DEBUG_TRAINER})
    entries = collect_results([tmp_path / "runs"])  # the library keeps every row, marked
    assert {e.run: e.debug for e in entries} == {"real": False, "smoke": True}
    out = tmp_path / "board"
    assert leaderboard([f"runs={tmp_path / 'runs'}", f"out={out}", "paper=false"]) == 0
    printed = capsys.readouterr()
    assert "left out 1 row(s) of runs trained with trainer=debug" in printed.err
    assert "include_debug=true" in printed.err
    assert [r["run"] for r in _csv_rows((out / "leaderboard.csv").read_text())] == ["real"]
    assert leaderboard([f"runs={tmp_path / 'runs'}", f"out={out}", "paper=false", "include_debug=true"]) == 0
    printed = capsys.readouterr()
    assert "left out" not in printed.err and "| 1 | deeplabv3plus / resnet18 |" in printed.out
    assert "| smoke [trainer=debug] |" in printed.out and "| real |" in printed.out
    (tmp_path / "runs" / "real" / "results.json").unlink()
    assert leaderboard([f"runs={tmp_path / 'runs'}", f"out={out}"]) == 1  # nothing else: said so
    err = capsys.readouterr().err
    assert "include_debug=true" in err and "no valid results.json to rank" in err


def test_the_run_column_reads_task_model_and_start_time(tmp_path: Path) -> None:
    """A folder named by train.py (``<date>_<time>_<pid>-<random>``) is shown as what a person reads; the CSV keeps
    the folder's name, and the HTML page has it as the cell's tooltip and sort key."""
    from airfisheye_bench.evaluation.leaderboard.html import render_html

    folder = "2026-12-01_10-22-33_1234-ab12"
    _write(tmp_path / "seg" / "runs", folder, "seg", {"mIoU": 0.3})
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    assert "| seg · deeplabv3plus · 2026-12-01 10:22:33 |" in board.to_markdown()
    assert folder not in board.to_markdown()
    assert [r["run"] for r in _csv_rows(board.to_csv())] == [folder]
    page = render_html(board)
    assert (
        f'data-value="{folder}"><span title="{folder}">seg · deeplabv3plus · 2026-12-01 10:22:33</span>'
        in page
    )


def test_console_script_is_declared_and_runs(tmp_path: Path, monkeypatch, capsys) -> None:
    # Python 3.10 has no tomllib: the [project.scripts] line is checked as text.
    pyproject = (PROJECT_ROOT / "pyproject.toml").read_text()
    assert 'airfisheye-leaderboard = "airfisheye_bench.cli:leaderboard"' in pyproject
    from airfisheye_bench import cli

    _write(tmp_path / "runs", "s", "seg", {"mIoU": 0.3})
    monkeypatch.setattr(
        sys, "argv", ["airfisheye-leaderboard", f"runs={tmp_path / 'runs'}", f"out={tmp_path / 'o'}"]
    )
    assert (
        cli.leaderboard() == 0 and (tmp_path / "o" / "leaderboard.md").is_file()
    )  # the script's exit status
    assert "# AirFisheye-bench leaderboard" in capsys.readouterr().out


# ------------------------------------------------------------------------------------------------ row labels


@pytest.mark.parametrize(
    ("model", "evaluated", "run"),
    [
        (  # train.py's test stage
            {
                "source": "checkpoint",
                "stage": "training",
                "checkpoint": "/r/checkpoints/epoch_003.ckpt",
                "run_name": "r",
            },
            "checkpoint epoch_003 (training test)",
            "r",
        ),
        (
            {
                "source": "checkpoint",
                "checkpoint": "/r/checkpoints/last.ckpt",
                "tta": "flip",
                "run_name": "r",
            },
            "checkpoint last, flip TTA",
            "r",
        ),
        (
            {"source": "onnx", "onnx": "/m/model.onnx", "precision": "fp32", "run_name": "adabins-r18"},
            "ONNX fp32",
            "adabins-r18",
        ),
        (
            {"source": "onnx", "onnx": "/m/model.int8.onnx", "precision": "int8", "run_name": "adabins-r18"},
            "ONNX int8",
            "adabins-r18",
        ),
        ({"source": "predictions", "predictions": "/p/mine", "run_name": "mine"}, "predictions", "mine"),
        # Written before the labels: train.py recorded no source, an int8 model only its file name, and the run
        # is the checkpoint's run directory, else the results folder.
        ({"checkpoint": "/r/checkpoints/epoch_001.ckpt"}, "checkpoint epoch_001 (training test)", "r"),
        (
            {"source": "onnx", "onnx": "/m/model.int8.onnx", "source_checkpoint": "/q/checkpoints/a.ckpt"},
            "ONNX int8",
            "q",
        ),
        ({"source": "onnx", "onnx": "/m/model.onnx"}, "ONNX", "folder"),
        ({"name": "deeplabv3plus"}, "", "folder"),
    ],
)
def test_rows_say_what_was_evaluated_and_which_run(
    tmp_path: Path, model: dict, evaluated: str, run: str
) -> None:
    entry = load_entry(_write(tmp_path, "folder", "depth", {"rmse": 4.0}, model={"name": "adabins", **model}))
    assert (entry.evaluated, entry.run) == (evaluated, run)
    board = build_leaderboard([entry], paper=False)
    row = _csv_rows(board.to_csv())[0]
    assert (row["evaluated"], row["run"]) == (evaluated, run)
    assert f"| {evaluated or '–'} | ours (synth) |" in board.to_markdown()


def test_onnx_and_its_checkpoint_are_two_rows_of_one_run(tmp_path: Path) -> None:
    for folder, model in (
        ("eval1", {"source": "checkpoint", "checkpoint": "/logs/runs/r18/checkpoints/epoch_002.ckpt"}),
        ("eval2", {"source": "onnx", "onnx": "/x/model.onnx", "precision": "fp32"}),
        ("eval3", {"source": "onnx", "onnx": "/x/model.int8.onnx", "precision": "int8"}),
    ):
        _write(
            tmp_path, folder, "depth", {"rmse": 4.0}, model={"name": "adabins", "run_name": "r18", **model}
        )
    rows = _csv_rows(build_leaderboard(collect_results([tmp_path]), paper=False).to_csv())
    assert sorted((r["run"], r["evaluated"], r["rank"]) for r in rows) == [
        ("r18", "ONNX fp32", "1"),
        ("r18", "ONNX int8", "1"),
        ("r18", "checkpoint epoch_002", "1"),
    ]


def test_the_served_camera_is_shown(tmp_path: Path) -> None:
    camera = {"model": "double_sphere", "width": 512, "height": 512, "fx": 158.3, "fy": 158.3, "cx": 255.0,
              "cy": 256.9, "xi": -0.17, "alpha": 0.59}  # fmt: skip
    _write(tmp_path, "ds", "seg", {"mIoU": 0.3, "pixel_acc": 0.7}, config={"camera": camera})
    _write(tmp_path, "old", "seg", {"mIoU": 0.2, "pixel_acc": 0.6})  # written before the camera was recorded
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    rows = {r["run"]: r for r in _csv_rows(board.to_csv())}
    assert (rows["ds"]["camera"], rows["old"]["camera"]) == ("double_sphere 512x512", "")
    md = board.to_markdown()
    assert (
        "| test | double_sphere 512x512 | 30.0 | 70.0 | ds |" in md
        and "| test | – | 20.0 | 60.0 | old |" in md
    )


def test_paths_are_shown_relative_to_the_runs_folder_given_in_any_form(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """``runs=logs`` (relative to the working folder) or absolute: the CSV path and the invalid files listed in the
    markdown read the same, relative to the runs folder."""
    _write(tmp_path / "logs", "good", "seg", {"mIoU": 0.3})
    _bad_files(tmp_path / "logs")
    monkeypatch.chdir(tmp_path)
    for runs in ("logs", str(tmp_path / "logs")):
        assert leaderboard([f"runs={runs}", "out=board", "skip_invalid=true", "paper=false"]) == 0
        md = (tmp_path / "board" / "leaderboard.md").read_text()
        assert "- truncated/results.json: " in md and str(tmp_path) not in md
        rows = _csv_rows((tmp_path / "board" / "leaderboard.csv").read_text())
        assert [r["path"] for r in rows] == ["good/results.json"]
    capsys.readouterr()


def test_a_sweep_trial_shows_what_its_sweep_chose(tmp_path: Path) -> None:
    """``model.sweep_overrides`` (a multirun job's) beside the run's name in the markdown, in its own CSV column."""
    chosen = ["task.module.optimizer.lr=0.001", "model.encoder_name=resnet34"]
    for job, lr, miou in (("0", "0.001", 0.4), ("1", "0.01", 0.3)):
        model = {"name": "deeplabv3plus", "run_name": f"sweep-a/{job}", "sweep_overrides": [f"task.module.optimizer.lr={lr}", chosen[1]]}  # fmt: skip
        _write(tmp_path / "sweep-a", job, "seg", {"mIoU": miou}, model=model)
    _write(tmp_path, "single", "seg", {"mIoU": 0.2})
    board = build_leaderboard(collect_results([tmp_path]), paper=False)
    md = board.to_markdown()
    assert "| sweep-a/0 (task.module.optimizer.lr=0.001 model.encoder_name=resnet34) |" in md
    assert "| sweep-a/1 (task.module.optimizer.lr=0.01 model.encoder_name=resnet34) |" in md
    assert "| single |" in md
    rows = {r["run"]: r["overrides"] for r in _csv_rows(board.to_csv())}
    assert rows["sweep-a/0"] == " ".join(chosen) and rows["single"] == ""
    bad = _write(tmp_path / "bad", "x", "seg", {"mIoU": 0.1}, model={"sweep_overrides": "lr=1"})
    with pytest.raises(ValueError, match=r"model\.sweep_overrides is 'lr=1', not a list"):
        load_entry(bad)
