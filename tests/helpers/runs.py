"""Tiny training runs: the overrides of a seconds-long run, and runs trained once per test session and shared.

A trained run is what the evaluate, export, deploy, leaderboard and resume tests start from. Training one takes
seconds, so each task's run is trained once per session (:func:`shared_run`) into a folder that every pytest-xdist
worker of the session sees, under a lock: the first worker to ask trains it, the others wait and reuse it. A test
that changes a run works on a copy (:func:`copy_run`). Each task's run is exported to ONNX once as well
(:func:`shared_export`).
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from collections.abc import Sequence
from pathlib import Path

from omegaconf import open_dict

from airfisheye_bench.atomic import exclusive_lock
from tests.helpers.configs import compose_train

SMALL = {
    "seg": ["model.encoder_name=resnet18"],
    "depth": ["model.encoder_name=resnet18", "model.patch_size=2", "model.n_bins=32"],
    "completion": ["model.encoder_name=resnet18", "model.prop_steps=2"],
}

#: Written last into a shared run folder: the run finished (a folder without it is trained again).
DONE = "returned.json"


def tiny_run_overrides(task: str, root: Path, size: int = 64) -> list[str]:
    """Overrides of a seconds-long run: debug trainer, the tiny dataset at ``size``^2, one process, small model."""
    return [
        f"task={task}",
        "trainer=debug",
        f"data.root={root}",
        f"data.camera.size={size}",
        "data.batch_size=2",
        "data.num_workers=0",
        "data.persistent_workers=false",
        "callbacks.rich_progress_bar=null",
        *SMALL[task],
    ]


def shared_run_overrides(task: str, root: Path) -> list[str]:
    """The configuration of every shared run: :func:`tiny_run_overrides` and the CSV logger."""
    return [*tiny_run_overrides(task, root), "logger=csv"]


def shared_run(task: str, dataset: Path, folder: Path, extra: Sequence[str] = ()) -> Path:
    """The run of :func:`shared_run_overrides` (and the ``extra`` overrides) in ``folder``, trained by the first
    caller of the session.

    ``folder/returned.json`` holds what ``train(cfg)`` returned. Read-only: :func:`copy_run` before changing it.
    """
    from airfisheye_bench.training import train

    with exclusive_lock(folder.with_name(folder.name + ".lock")):
        if not (folder / DONE).is_file():
            shutil.rmtree(folder, ignore_errors=True)  # an interrupted attempt
            cfg = compose_train([*shared_run_overrides(task, dataset), *extra])
            with open_dict(cfg):
                cfg.paths.output_dir = str(folder)
            returned = train(cfg)
            (folder / DONE).write_text(json.dumps(returned, default=float))
    return folder


def copy_run(run: Path, to: Path) -> Path:
    """A copy of a run folder that a test may change (its checkpoints, config and logs)."""
    shutil.copytree(run, to)
    return to


def shared_export(task: str, run: Path, folder: Path, extra: Sequence[str] = ()) -> tuple[Path, int, str]:
    """``airfisheye-export ckpt_path=<run>/checkpoints/last.ckpt out=<folder>/<task>.onnx repeats=1 [extra]``
    through the command's main, once per session: ``(the ONNX file, the exit status, what it printed)``. Read-only."""
    from airfisheye_bench.cli import export

    out = folder / f"{task}.onnx"
    record = folder / "command.json"
    with exclusive_lock(folder.with_name(folder.name + ".lock")):
        if not record.is_file():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir(parents=True)
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                try:
                    code = export(
                        [f"ckpt_path={run / 'checkpoints' / 'last.ckpt'}", f"out={out}", "repeats=1", *extra]
                    )
                except SystemExit as stop:
                    code = int(stop.code or 0)
            record.write_text(json.dumps({"code": code, "stdout": printed.getvalue()}))
    done = json.loads(record.read_text())
    return out, done["code"], done["stdout"]
