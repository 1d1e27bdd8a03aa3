"""Where a study's numbers come from: the ``provenance`` block every JSON under ``docs/figures/`` carries.

A number in the docs is only as good as the file it is read from: the file names the commit that computed it (full,
``+dirty`` when tracked files differed, which the docs never cite), the command, the machine, and the dataset's
content identity when data were involved (:func:`airfisheye_bench.runs.results.dataset_identity`). The commit and the
machine are :func:`git_commit` and :func:`machine`, which the quick-start record and the benchmarks write too; the
load average (:func:`load_average`) says what else the machine ran when the record was written, without which a
timing means little.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from airfisheye_bench.runs.results import dataset_identity

__all__ = ["REPO", "git_commit", "load_average", "machine", "provenance"]

#: The checkout the studies run from.
REPO = Path(__file__).resolve().parents[2]


def provenance(
    script: str,
    argv: Sequence[str] | None = None,
    dataset: str | Path | None = None,
    dataset_name: str | None = None,
) -> dict[str, Any]:
    """``{"commit", "command", "machine", "load_average"[, "dataset"]}`` of a study run as ``python <script> <argv>``.

    Example:
        >>> p = provenance("scripts/x.py", ["--a", "1"])
        >>> p["command"], sorted(p)
        ('python scripts/x.py --a 1', ['command', 'commit', 'load_average', 'machine'])
    """
    args = list(sys.argv[1:] if argv is None else argv)
    out: dict[str, Any] = {
        "commit": git_commit(REPO),
        "command": " ".join(["python", script, *args]),
        "machine": machine(),
        "load_average": load_average(),
    }
    if dataset is not None:
        out["dataset"] = dataset_identity(dataset, dataset_name or Path(dataset).name)
    return out


def git_commit(repo: str | Path) -> str:
    """``<sha>`` of ``repo``'s HEAD, ``<sha>+dirty`` when tracked files differ from it, ``unknown`` without git."""
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"], cwd=repo, capture_output=True, text=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return sha + ("+dirty" if dirty else "")


def machine() -> str:
    """What the record was made on: architecture, CPU model and cores, torch and numpy (data and kernels may
    differ between CPUs and library versions, so a record says where its numbers came from)."""
    return (
        f"{platform.machine()}, {_cpu_model()}, {_cpu_count()} CPU cores, torch {torch.__version__}, "
        f"numpy {np.__version__}"
    )


def load_average() -> list[float] | None:
    """The 1, 5 and 15 minute load averages now (``None`` where the system has none)."""
    return [round(x, 2) for x in os.getloadavg()] if hasattr(os, "getloadavg") else None


def _cpu_model() -> str:
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or "unknown CPU"


def _cpu_count() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def records_of_format(folder: str | Path, record_format: str) -> list[dict[str, Any]]:
    """The JSON records in ``folder`` whose ``format`` is ``record_format`` (other files ignored), by file name."""
    records = []
    for path in sorted(Path(folder).glob("*.json")):
        record = json.loads(path.read_text(encoding="utf-8"))
        if isinstance(record, dict) and record.get("format") == record_format:
            records.append(record)
    return records
