"""The qualitative panels of ``docs/results.md`` (section 7), drawn from recorded runs.

    python scripts/report_panels.py --run seg=<run dir> --run depth=<run dir> --run completion=<run dir> \\
        [--frame modular_houses/traj03/000000] [--out docs/figures]

For each ``--run task=<run dir>`` the project's evaluation scores the run's checkpoint on the test split
(``python scripts/evaluate.py ckpt_path=<run dir> num_panels=N out=<temporary folder>``), with ``N`` the fewest
panels whose frames, spread over the split (:func:`~airfisheye_bench.viz.spread_indices`), include ``--frame``
(:func:`panels_to_reach`). That frame's panel becomes ``<out>/panel_<task>.png``, and ``<out>/panels.json`` records,
per task, the run and its own training record (``<run dir>.train.json`` beside it, or ``benchmark.json`` /
``provenance.json`` inside it: commit and command), the checkpoint, the evaluation command, the dataset identity of
its ``results.json`` and the frame; and the script's own provenance (commit, command, machine). The checkout must be
clean: the record names the commit that drew the panels.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from airfisheye_bench.atomic import atomic_write_bytes, atomic_write_json
from airfisheye_bench.errors import ConfigError, MissingFileError, UserError, report_user_errors
from airfisheye_bench.evaluation.trained import run_datamodule
from airfisheye_bench.runs import resolve_checkpoint, run_config
from airfisheye_bench.studies.provenance import REPO, git_commit, provenance
from airfisheye_bench.viz import spread_indices

__all__ = [
    "DEFAULT_FRAME",
    "FORMAT",
    "TASKS",
    "evaluation_argv",
    "main",
    "panel_file",
    "panels_to_reach",
    "parse_runs",
    "split_ids",
    "task_record",
    "training_record",
]

FORMAT = "airfisheye-report-panels/1"
#: The tasks of section 7, in its order.
TASKS = ("seg", "depth", "completion")
#: The frame section 7 shows: the quick start's first test frame.
DEFAULT_FRAME = "modular_houses/traj03/000000"
#: A run's training record inside its folder (``scripts/quickstart_benchmark.py``, ``scripts/occlusion_ablation.py``);
#: ``scripts/lens_study.py`` writes ``<run dir>.train.json`` beside it instead.
RECORDS_INSIDE = ("benchmark.json", "provenance.json")


def parse_runs(specs: Sequence[str]) -> dict[str, Path]:
    """``{task: run dir}`` of ``--run task=<run dir>`` arguments, in :data:`TASKS` order.

    Example:
        >>> {task: run.name for task, run in parse_runs(["depth=runs/d", "seg=runs/s"]).items()}
        {'seg': 's', 'depth': 'd'}
    """
    runs: dict[str, Path] = {}
    for spec in specs:
        task, sep, folder = spec.partition("=")
        if not sep or not folder:
            raise ConfigError(f"--run {spec}: expected task=<run dir>, e.g. --run seg=logs/train/runs/<run>")
        if task not in TASKS:
            raise ConfigError(f"--run {spec}: unknown task {task!r}; expected one of {list(TASKS)}")
        if task in runs:
            raise ConfigError(f"--run {spec}: {task} given twice")
        runs[task] = Path(folder)
    if not runs:
        raise ConfigError("give at least one --run task=<run dir>")
    return {task: runs[task] for task in TASKS if task in runs}


def panels_to_reach(ids: Sequence[str], frame: str) -> int:
    """The fewest panels (``num_panels=``) whose frames, spread over the split ``ids``, include ``frame``.

    Example:
        >>> ids = [f"f{i}" for i in range(164)]
        >>> panels_to_reach(ids, "f0"), panels_to_reach(ids, "f20"), panels_to_reach(ids, "f163")
        (83, 4, 82)
    """
    try:
        index = list(ids).index(frame)
    except ValueError:
        raise ConfigError(f"--frame {frame}: not a frame of the split ({len(ids)} frames)") from None
    return next(n for n in range(1, len(ids) + 1) if index in spread_indices(len(ids), n))


def panel_file(frame: str) -> str:
    """The file name the evaluation gives ``frame``'s panel under ``panels/`` (``evaluation.command``)."""
    return frame.replace("/", "_") + ".png"


def split_ids(run: Path, split: str = "test") -> list[str]:
    """The frame ids of ``split`` in the data the run's checkpoint is evaluated on (its run's ``config.yaml``)."""
    config = run_config(resolve_checkpoint(run))
    if config is None:
        raise MissingFileError(
            f"{run}: no config.yaml beside the checkpoints; give a run directory of train.py"
        )
    return list(run_datamodule(config.data.copy()).split_dataset(split).sample_ids)


def training_record(run: Path) -> dict[str, Any] | None:
    """How ``run`` was trained: its record (``<run>.train.json`` beside it, else one of :data:`RECORDS_INSIDE`)
    with ``record`` naming the file and ``command`` as one string; ``None`` when it has none."""
    for path in (run.with_name(run.name + ".train.json"), *(run / name for name in RECORDS_INSIDE)):
        if path.is_file():
            record = json.loads(path.read_text(encoding="utf-8"))
            command = record.get("command")
            if isinstance(command, list):
                record["command"] = " ".join(command)
            return {"record": str(path), **record}
    return None


def evaluation_argv(run: Path, num_panels: int, out: str | Path) -> list[str]:
    """The evaluation's arguments after ``python``."""
    return ["scripts/evaluate.py", f"ckpt_path={run}", f"num_panels={num_panels}", f"out={out}"]


def task_record(
    task: str, run: Path, results: Mapping[str, Any], num_panels: int, frame: str, panel: str
) -> dict[str, Any]:
    """One task's entry of ``panels.json`` from its run and its evaluation's ``results.json``.

    Raises:
        ConfigError: the run's checkpoint is of another task.
    """
    if results.get("task") != task:
        raise ConfigError(f"--run {task}={run}: its checkpoint is a {results.get('task')} model")
    return {
        "run": str(run),
        "trained": training_record(run),
        "checkpoint": Path(results["model"]["checkpoint"]).name,
        "evaluation": {
            "command": "python " + " ".join(evaluation_argv(run, num_panels, "<temporary folder>")),
            "split": results["split"],
        },
        "dataset": results["dataset"],
        "frame": frame,
        "panel": panel,
    }


def copy_panel(evaluation_out: Path, frame: str, dest: Path) -> None:
    """Copy ``frame``'s panel of an evaluation's output folder to ``dest`` (written under a temporary name, then
    renamed)."""
    source = evaluation_out / "panels" / panel_file(frame)
    if not source.is_file():
        raise MissingFileError(f"{source}: the evaluation drew no panel of {frame}")
    atomic_write_bytes(dest, source.read_bytes())


def _evaluate(run: Path, num_panels: int, out: Path) -> dict[str, Any]:
    """Run the evaluation command on ``run`` in a subprocess; its ``results.json``."""
    argv = [sys.executable, *evaluation_argv(run, num_panels, out)]
    code = subprocess.run(argv, cwd=REPO, env=dict(os.environ)).returncode
    if code != 0:
        raise UserError(f"--run {run}: the evaluation failed (exit status {code}): {' '.join(argv)}")
    return json.loads((out / "results.json").read_text(encoding="utf-8"))


def draw(runs: Mapping[str, Path], frame: str, out: Path, argv: Sequence[str]) -> dict[str, Any]:
    """Evaluate each run, copy ``frame``'s panels to ``out`` and write ``out/panels.json``; the record."""
    record: dict[str, Any] = {
        "format": FORMAT,
        "provenance": provenance("scripts/report_panels.py", argv),
        "frame": frame,
    }
    tasks = {}
    with tempfile.TemporaryDirectory(prefix="report_panels_") as tmp:
        for task, run in runs.items():
            num_panels = panels_to_reach(split_ids(run), frame)
            evaluation_out = Path(tmp) / task
            print(f"{task}: evaluating {run} with num_panels={num_panels}", flush=True)
            results = _evaluate(run, num_panels, evaluation_out)
            panel = f"panel_{task}.png"
            tasks[task] = task_record(task, run, results, num_panels, frame, panel)
            copy_panel(evaluation_out, frame, out / panel)
            print(f"{task}: wrote {out / panel}", flush=True)
    record["tasks"] = tasks
    atomic_write_json(out / "panels.json", record)
    return record


@report_user_errors
def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--run", action="append", default=[], metavar="TASK=RUN_DIR", help="repeat per task")
    parser.add_argument("--frame", default=DEFAULT_FRAME, help="the test frame drawn")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "figures")
    args_list = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(args_list)
    runs = parse_runs(args.run)
    for task, run in runs.items():
        if not run.is_dir():
            raise MissingFileError(f"--run {task}={run}: no such run directory")
    if git_commit(REPO).endswith("+dirty"):
        raise UserError(
            "the checkout has uncommitted changes; commit them first (the record names the commit)"
        )
    draw(runs, args.frame, args.out, args_list)
    print(f"wrote {args.out / 'panels.json'}")
    return 0
