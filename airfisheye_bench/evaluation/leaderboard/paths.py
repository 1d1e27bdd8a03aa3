"""How the leaderboard shows a path: a run's relative to the ``runs=`` folder, a dataset's as its name and short
content hash, the home folder as ``~``, anything else by its last two parts; so a shared page or table shows no
one's local layout.

Example:
    >>> shown = ShownPaths("/data/logs").with_dataset("/cache/quickstart-v2", "quickstart (content 8b04c5ff)")
    >>> shown("/data/logs/seg/runs/a/results.json"), shown("/cache/quickstart-v2"), shown("/srv/x.ckpt")
    ('seg/runs/a/results.json', 'quickstart (content 8b04c5ff)', '/srv/x.ckpt')
    >>> shown("/scratch/alice/runs/r3/checkpoints/last.ckpt")  # outside runs=: its last two parts
    '…/checkpoints/last.ckpt'
    >>> shown("/cache/quickstart-v2/splits/test.txt"), shown("sha256:ab"), shown(None)
    ('quickstart (content 8b04c5ff)/splits/test.txt', 'sha256:ab', None)
    >>> shown.within({"paths": ["/data/logs/a", 3]})
    {'paths': ['a', 3]}
    >>> shown.text("/data/logs/b/results.json: missing 'split'")
    "b/results.json: missing 'split'"
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["ShownPaths"]


class ShownPaths:
    """Absolute paths as the leaderboard shows them.

    Args:
        runs_root: The folder the results were collected from (``runs=``): paths under it are shown relative to
            it; ``None``: no such folder.
        dataset: ``(root, label)`` of the dataset an entry was measured on: a path under its root is shown as its
            label (the dataset's name and content hash, :attr:`~.collect.LeaderboardEntry.dataset_label`) and
            the rest of the path (:meth:`with_dataset`).
    """

    def __init__(self, runs_root: str | Path | None = None, dataset: tuple[str, str] | None = None) -> None:
        root = _folder(runs_root) if runs_root is not None else ""
        self.root = root if root != "/" else ""  # results from all over one disk: nothing to be relative to
        # As recorded, not resolved: the folder was on the machine that measured the entry.
        self.dataset = (os.path.normpath(dataset[0]), dataset[1]) if dataset is not None else None
        self.home = str(Path.home()).rstrip("/")  # "" for a home folder of "/"

    def with_dataset(self, root: str | None, label: str) -> ShownPaths:
        """These paths, and ``root`` (an entry's ``dataset.root``; ``None``: unknown) shown as ``label``: one
        dataset per entry, since a folder may have held other data when another entry was measured."""
        return ShownPaths(self.root or None, (root, label) if root else None)

    def __call__(self, value: Any) -> Any:
        if not isinstance(value, str) or not value.startswith("/"):
            return value
        path = os.path.normpath(value)
        if self.dataset and _under(path, self.dataset[0]):
            return self.dataset[1] + path[len(self.dataset[0]) :]
        if self.root and _under(path, self.root):
            return os.path.relpath(path, self.root)
        if self.home and _under(path, self.home):
            return "~" + path[len(self.home) :]
        parts = path.split("/")
        return "…/" + "/".join(parts[-2:]) if len(parts) > 3 else value

    def text(self, text: str) -> str:
        """``text`` (a message) with the paths inside it shortened as :meth:`__call__` does."""
        if self.dataset and self.dataset[0] != "/":
            text = text.replace(self.dataset[0] + "/", self.dataset[1] + "/")
        if self.root:
            text = text.replace(self.root + "/", "")
        if self.home:
            text = text.replace(self.home + "/", "~/")
        return text

    def within(self, value: Any) -> Any:
        """``value`` with every path string inside it (dicts and lists, recursively) shortened."""
        if isinstance(value, Mapping):
            return {k: self.within(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [self.within(v) for v in value]
        return self(value)


def _folder(path: str | Path) -> str:
    return str(Path(path).expanduser().resolve())


def _under(path: str, root: str) -> bool:
    return root not in ("", "/") and (path == root or path.startswith(root + "/"))
