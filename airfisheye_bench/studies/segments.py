"""A study's training run in segments: a session's end kills a training, the next session resumes it exactly
(``ckpt_path=last``: see docs/training.md, "Resume and DDP") and the run's record says that it did.

The segments are kept beside the run, not in it (``train.py`` owns the run's folder): ``<run>.segments.json``, one
entry per start with the commit it trained from (taken when it starts), its ``train.py`` arguments, when it started
and, once it has ended, its wall time. A segment killed before it could write its wall time has none, and the run's
running time is then unknown (``None``), never counted as 0. A run that holds a checkpoint but no segments was cut
before its segments were kept: its first segment is recorded as unknown (commit and wall time ``None``).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.studies.ablation_records import running_time

__all__ = ["resume_argv", "segments_path", "train_in_segments"]


def segments_path(run_dir: Path) -> Path:
    """Where the segments of the run in ``run_dir`` are kept: beside it, ``<run>.segments.json``."""
    return run_dir.parent / f"{run_dir.name}.segments.json"


def resume_argv(argv: Sequence[str], run_dir: Path) -> list[str]:
    """``argv`` (``python train.py <overrides>``), or the command that resumes it when ``run_dir`` holds its last
    checkpoint: the resume takes the run's own ``config.yaml``, so no override is repeated.

    Example:
        >>> import tempfile
        >>> run = Path(tempfile.mkdtemp()) / "seed0"
        >>> resume_argv(["python", "train.py", "seed=0", f"hydra.run.dir={run}"], run)[2:] == ["seed=0", f"hydra.run.dir={run}"]
        True
        >>> (run / "checkpoints").mkdir(parents=True); (run / "checkpoints" / "last.ckpt").write_bytes(b"")
        0
        >>> resume_argv(["python", "train.py", "seed=0", f"hydra.run.dir={run}"], run)[2:] == ["ckpt_path=last", f"hydra.run.dir={run}"]
        True
    """
    if (run_dir / "checkpoints" / "last.ckpt").is_file():
        return [argv[0], argv[1], "ckpt_path=last", f"hydra.run.dir={run_dir}"]
    return list(argv)


def train_in_segments(
    argv: Sequence[str], run_dir: Path, commit: str, runner: Callable[[list[str]], int | None]
) -> tuple[dict[str, Any], int | None]:
    """Train (or resume) the run of ``argv`` in ``run_dir`` with ``runner`` as one more segment; return the run's
    provenance over its segments (the first segment's commit, the running time, each segment's commit and wall
    time) and what ``runner`` returned. The segment is written down before it starts, so a kill leaves it."""
    path = segments_path(run_dir)
    segments: list[dict[str, Any]] = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else []
    argv = resume_argv(argv, run_dir)
    if not segments and "ckpt_path=last" in argv:  # cut before its segments were kept
        segments.append({"commit": None, "argv": None, "wall_s": None})
    segments.append({"commit": commit, "argv": argv[2:], "started": time.time()})
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(segments, indent=2) + "\n")
    returned = runner(argv)
    segments[-1]["wall_s"] = round(time.time() - segments[-1]["started"], 1)
    atomic_write_text(path, json.dumps(segments, indent=2) + "\n")
    wall = running_time(segments)
    return {
        "commit": segments[0]["commit"],
        "wall_s": None if wall is None else round(wall, 1),
        "segments": [{"commit": s["commit"], "wall_s": s.get("wall_s")} for s in segments],
    }, returned
