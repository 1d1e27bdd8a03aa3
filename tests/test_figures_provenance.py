"""Every result file under ``docs/figures/`` names where it comes from: a full, clean commit and the command that
wrote it, at its top level or under ``provenance`` (``docs/results.md`` cites numbers only from such files)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FIGURES = sorted((ROOT / "docs" / "figures").rglob("*.json"))
_FULL_COMMIT = re.compile(r"[0-9a-f]{40}")


@pytest.mark.parametrize("path", FIGURES, ids=lambda p: str(p.relative_to(ROOT / "docs" / "figures")))
def test_a_figure_names_a_clean_full_commit_and_its_command(path: Path) -> None:
    data = json.loads(path.read_text())
    source = data if "commit" in data else data.get("provenance", {})
    commit, command = source.get("commit"), source.get("command")
    assert isinstance(commit, str) and _FULL_COMMIT.fullmatch(commit), f"{path}: commit {commit!r}"
    assert isinstance(command, str) and "python " in command, f"{path}: command {command!r}"


def test_there_are_figures() -> None:
    assert len(FIGURES) > 10
