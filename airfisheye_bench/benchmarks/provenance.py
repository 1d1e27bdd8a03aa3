"""Where a study's numbers come from: the ``provenance`` block every JSON under ``docs/figures/`` carries.

A number in the docs is only as good as the file it is read from: the file names the commit that computed it (full,
``+dirty`` when tracked files differed, which the docs never cite), the command, the machine, and the dataset's
content identity when data were involved (:func:`airfisheye_bench.io.results.dataset_identity`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from airfisheye_bench.evaluation.quickstart import git_commit, machine
from airfisheye_bench.io.results import dataset_identity

__all__ = ["REPO", "provenance"]

#: The checkout the studies run from.
REPO = Path(__file__).resolve().parents[2]


def provenance(
    script: str,
    argv: Sequence[str] | None = None,
    dataset: str | Path | None = None,
    dataset_name: str | None = None,
) -> dict[str, Any]:
    """``{"commit", "command", "machine"[, "dataset"]}`` of a study run as ``python <script> <argv>``.

    Example:
        >>> p = provenance("scripts/x.py", ["--a", "1"])
        >>> p["command"], sorted(p)
        ('python scripts/x.py --a 1', ['command', 'commit', 'machine'])
    """
    args = list(sys.argv[1:] if argv is None else argv)
    out: dict[str, Any] = {
        "commit": git_commit(REPO),
        "command": " ".join(["python", script, *args]),
        "machine": machine(),
    }
    if dataset is not None:
        out["dataset"] = dataset_identity(dataset, dataset_name or Path(dataset).name)
    return out
