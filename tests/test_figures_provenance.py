"""Every result file under ``docs/figures/`` names where it comes from: a full, clean commit and the command that
wrote it, at its top level or under ``provenance`` (``docs/results.md`` cites numbers only from such files), and the
identity of the data it read: a dataset's content SHA-256 (``dataset``, ``datasets`` or ``content_sha256``), or a
real file's SHA-256 (``scan``)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FIGURES = sorted((ROOT / "docs" / "figures").rglob("*.json"))
_FULL_COMMIT = re.compile(r"[0-9a-f]{40}")
_SHA256 = re.compile(r"[0-9a-f]{64}")
_IDENTITY_KEYS = {"dataset", "datasets", "content_sha256", "scan"}

#: The figures that read no data files, and what they measure instead.
READS_NO_DATA = {
    "test_suite.json": "the test suites' wall times",
    "test_suite_coverage.json": "the test suites' wall times and coverage",
    "occlusion_memory.json": "occlusion methods' memory on a scene built in memory from its name and seed",
    "camera_input_steps.json": "model steps on random tensors and a lens's ray map computed from its model",
}

#: Records of data generated inside the run on a lent GPU machine before the run hashed what it generated; each names
#: how the data were made instead. The code hashes it since (``gpu_campaign.generate_data``, ``bench_cpu_contention``).
GENERATED_NOT_HASHED = {
    "campaign_nvidia-h200_b076001.json": "data.generator: the generator's command line",
    "campaign_nvidia-h200.json": "data.generator: the generator's command line",
    "contention_seg.json": "data: the tiny preset",
    "contention_depth.json": "data: the tiny preset",
}


@pytest.mark.parametrize("path", FIGURES, ids=lambda p: str(p.relative_to(ROOT / "docs" / "figures")))
def test_a_figure_names_a_clean_full_commit_and_its_command(path: Path) -> None:
    data = json.loads(path.read_text())
    source = data if "commit" in data else data.get("provenance", {})
    commit, command = source.get("commit"), source.get("command")
    assert isinstance(commit, str) and _FULL_COMMIT.fullmatch(commit), f"{path}: commit {commit!r}"
    assert isinstance(command, str) and "python " in command, f"{path}: command {command!r}"


def _identities(node: object, under_identity_key: bool = False) -> set[str]:
    """Every SHA-256 held (at any depth) under one of :data:`_IDENTITY_KEYS`."""
    if isinstance(node, dict):
        return set().union(
            *(_identities(v, under_identity_key or k in _IDENTITY_KEYS) for k, v in node.items())
        )
    if isinstance(node, list):
        return set().union(*(_identities(v, under_identity_key) for v in node))
    return {node} if under_identity_key and isinstance(node, str) and _SHA256.fullmatch(node) else set()


@pytest.mark.parametrize(
    "path",
    [p for p in FIGURES if p.name not in READS_NO_DATA | GENERATED_NOT_HASHED.keys()],
    ids=lambda p: str(p.relative_to(ROOT / "docs" / "figures")),
)
def test_a_figure_names_the_data_it_read(path: Path) -> None:
    assert _identities(json.loads(path.read_text())), (
        f"{path}: no dataset content SHA-256 (or real file SHA-256) under {sorted(_IDENTITY_KEYS)}"
    )


def test_the_figures_said_to_read_no_data_exist() -> None:
    """An exemption outlives no file: each name of :data:`READS_NO_DATA` is a figure here."""
    assert set(READS_NO_DATA) <= {p.name for p in FIGURES}


@pytest.mark.parametrize("name", sorted(GENERATED_NOT_HASHED))
def test_a_record_of_unhashed_data_says_how_they_were_made(name: str) -> None:
    (path,) = [p for p in FIGURES if p.name == name]
    data = json.loads(path.read_text())["data"]
    made = data["generator"] if isinstance(data, dict) else data
    assert "preset=tiny" in made or "tiny preset" in made, f"{path}: {made!r}"


def test_the_identity_finder() -> None:
    digest = "a" * 64
    assert _identities({"dataset": {"root": "/x", "content_sha256": digest}}) == {digest}
    assert _identities({"datasets": [digest]}) == {digest}
    assert _identities({"results": [{"sha256": digest}]}) == set()  # a file checksum outside an identity key
    assert _identities({"dataset": {"name": "tiny"}}) == set()


def test_there_are_figures() -> None:
    assert len(FIGURES) > 10
