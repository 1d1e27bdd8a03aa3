"""``scripts/report_panels.py``: the panel drawn is the wanted frame's, and the record names each run's training,
checkpoint, evaluation and data (on fake run folders: nothing is trained or evaluated)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from airfisheye_bench.errors import ConfigError, MissingFileError
from airfisheye_bench.studies import report_panels
from airfisheye_bench.viz import spread_indices

FRAME = "town/traj01/000000"
IDS = [f"town/traj00/{i:06d}" for i in range(7)] + [FRAME] + [f"town/traj01/{i:06d}" for i in range(1, 30)]
DATASET = {"name": "fake", "content_sha256": "d" * 64}


def _run(root: Path, task: str, record: str) -> Path:
    """A run folder of ``task`` with a checkpoint and its training record (beside it or inside it)."""
    run = root / task / "seed0"
    (run / "checkpoints").mkdir(parents=True)
    (run / "checkpoints" / "epoch_003.ckpt").write_bytes(b"")
    trained = {"commit": "c" * 40, "command": ["python", "train.py", f"task={task}", "seed=0"]}
    if record == "beside":
        (root / task / "seed0.train.json").write_text(json.dumps(trained))
    else:
        trained["command"] = " ".join(trained["command"])
        (run / "benchmark.json").write_text(json.dumps(trained))
    return run


def _fake_evaluation(task_of: dict[Path, str], calls: list[list[str]]):
    """An evaluation that writes what the real one does: ``results.json`` and the first panels of the spread."""

    def evaluate(run: Path, num_panels: int, out: Path) -> dict:
        calls.append(report_panels.evaluation_argv(run, num_panels, out))
        (out / "panels").mkdir(parents=True)
        for i in spread_indices(len(IDS), num_panels):
            (out / "panels" / report_panels.panel_file(IDS[i])).write_bytes(
                f"{task_of[run]} {IDS[i]}".encode()
            )
        checkpoint = run / "checkpoints" / "epoch_003.ckpt"
        results = {
            "task": task_of[run],
            "split": "test",
            "dataset": DATASET,
            "model": {"checkpoint": str(checkpoint)},
        }
        (out / "results.json").write_text(json.dumps(results))
        return results

    return evaluate


def test_each_task_gets_its_runs_panel_of_the_frame_and_a_record_of_where_it_comes_from(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    runs = {"seg": _run(tmp_path, "seg", "beside"), "completion": _run(tmp_path, "completion", "inside")}
    calls: list[list[str]] = []
    monkeypatch.setattr(report_panels, "split_ids", lambda run: IDS)
    monkeypatch.setattr(report_panels, "_evaluate", _fake_evaluation({r: t for t, r in runs.items()}, calls))
    out = tmp_path / "figures"
    out.mkdir()
    argv = [f"--run=seg={runs['seg']}", f"--run=completion={runs['completion']}", f"--frame={FRAME}"]

    record = report_panels.draw(runs, FRAME, out, argv)

    assert json.loads((out / "panels.json").read_text()) == record
    assert record["provenance"]["command"] == "python scripts/report_panels.py " + " ".join(argv)
    num_panels = report_panels.panels_to_reach(IDS, FRAME)
    assert 7 in spread_indices(len(IDS), num_panels) and 7 not in spread_indices(len(IDS), num_panels - 1)
    assert [c[2] for c in calls] == [f"num_panels={num_panels}"] * 2
    for task, run in runs.items():
        assert (out / f"panel_{task}.png").read_bytes() == f"{task} {FRAME}".encode()
        entry = record["tasks"][task]
        assert entry["trained"]["commit"] == "c" * 40
        assert entry["trained"]["command"] == f"python train.py task={task} seed=0"
        assert entry["checkpoint"] == "epoch_003.ckpt" and entry["dataset"] == DATASET
        assert entry["evaluation"]["command"] == (
            f"python scripts/evaluate.py ckpt_path={run} num_panels={num_panels} out=<temporary folder>"
        )
        assert entry["frame"] == FRAME and entry["panel"] == f"panel_{task}.png"
    assert record["tasks"]["seg"]["trained"]["record"].endswith("seed0.train.json")
    assert record["tasks"]["completion"]["trained"]["record"].endswith("benchmark.json")


def test_a_run_of_another_task_or_a_frame_outside_the_split_is_refused(tmp_path: Path) -> None:
    run = _run(tmp_path, "depth", "inside")
    results = {"task": "depth", "split": "test", "dataset": DATASET, "model": {"checkpoint": "x.ckpt"}}
    with pytest.raises(ConfigError, match=r"seg=.*a depth model"):
        report_panels.task_record("seg", run, results, 4, FRAME, "panel_seg.png")
    with pytest.raises(ConfigError, match="--frame town/traj09/000000"):
        report_panels.panels_to_reach(IDS, "town/traj09/000000")
    with pytest.raises(MissingFileError, match="no panel of"):
        report_panels.copy_panel(tmp_path, FRAME, tmp_path / "panel.png")
    assert report_panels.training_record(tmp_path / "nowhere") is None


@pytest.mark.parametrize(
    ("specs", "message"),
    [
        (["seg"], "expected task=<run dir>"),
        (["pose=x"], "unknown task"),
        (["seg=a", "seg=b"], "twice"),
        ([], "at least"),
    ],
)
def test_run_arguments_are_checked(specs: list[str], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        report_panels.parse_runs(specs)
