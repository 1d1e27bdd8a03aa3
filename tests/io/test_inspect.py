"""``inspect_dataset``: every kind of damage is reported with its file, nothing else is."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from airfisheye_bench.cli import inspect
from airfisheye_bench.dataset_tools.inspect import inspect_dataset
from airfisheye_bench.io import DatasetReader, write_label
from tests.helpers.commands import exit_status


@pytest.fixture
def copy(tiny_dataset: Path, tmp_path: Path) -> Path:
    root = tmp_path / "copy"
    shutil.copytree(tiny_dataset, root)
    return root


def test_a_clean_dataset_has_no_problems(tiny_dataset: Path, capsys) -> None:
    report = inspect_dataset(tiny_dataset, deep=True)
    assert report.ok, report.summary()
    assert report.samples == 12 and report.files > 12 * 15
    assert inspect([f"root={tiny_dataset}", "coverage=false"]) == 0
    assert "coverage" not in capsys.readouterr().out


@pytest.mark.integration  # the datamodule, twice, and the paper sensor's beams over two frames: seconds
def test_a_dataset_with_lidar_states_its_completion_coverage_per_ring(tiny_dataset: Path, capsys) -> None:
    """Sparse pixels per ground-truth pixel by ring, served at size= with every return and under each reading of the
    paper's density, beside the paper sensor modelled on each reading's image; over the tiny preset's two test
    frames (a few frames by default)."""
    assert inspect([f"root={tiny_dataset}", "size=64"]) == 0
    lines = capsys.readouterr().out.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("sparse LiDAR coverage"))
    assert lines[head].endswith("test split, 2 frames (every=1):")
    assert lines[head + 1].split() == [
        "ring", "native", "64^2", "paper_1536", "64^2", "paper_512", "64^2", "model", "1536^2", "model", "512^2"
    ]  # fmt: skip
    rows = {line.split()[0]: [float(v) for v in line.split()[1:]] for line in lines[head + 2 : head + 6]}
    assert list(rows) == ["ring_0-30", "ring_30-60", "ring_60-80", "ring_80-95"]
    for native, paper_1536, paper_512, model_1536, model_512 in rows.values():
        assert (
            0 < paper_1536 < paper_512 <= native <= 1
        )  # each reading keeps a subset, the 1536^2 one the smaller
        assert 0 < model_1536 < model_512 < 1
    assert "modelled, not measured" in " ".join(line.strip() for line in lines[head + 6 : head + 9])


def test_coverage_options_are_checked_before_the_scan(tmp_path: Path, capsys) -> None:
    assert exit_status(inspect, [f"root={tmp_path}", "every=0"]) == 2
    assert "every=0: expected a whole number >= 1" in capsys.readouterr().err
    assert exit_status(inspect, [f"root={tmp_path}", "size=-64"]) == 2


def test_damage_is_reported_with_the_file(copy: Path) -> None:
    reader = DatasetReader(copy)
    sids = reader.split("train")
    missing = reader.layout.cubemap(sids[0], "up", "rgb")
    missing.unlink()
    corrupt = reader.layout.cubemap(sids[1], "left", "seg")
    corrupt.write_bytes(b"\x89PNG garbage")
    resized = reader.layout.fisheye(sids[2], "rgb")
    Image.fromarray(np.zeros((10, 12, 3), np.uint8)).save(resized)
    bad_ids = reader.layout.fisheye(sids[3], "seg")
    label = reader.fisheye(sids[3], "seg")
    label[0, :3] = 201
    write_label(bad_ids, label)
    scan = reader.layout.lidar(sids[4])
    np.save(scan, np.zeros((5, 3), np.float32))
    flags = reader.layout.lidar_visible(sids[5])
    np.save(flags, np.zeros(3, bool))

    shallow = inspect_dataset(copy)
    deep = inspect_dataset(copy, deep=True)
    for report in (shallow, deep):
        paths = [p for p, _ in report.problems]
        assert str(missing) in paths
        assert str(corrupt) in paths
        assert any(p == str(resized) and "10" in m for p, m in report.problems)
        assert any(p == str(scan) and "[N, 4]" in m for p, m in report.problems)
        assert any(p == str(flags) for p, _ in report.problems)
    # Label values are only read in deep mode.
    assert not any(p == str(bad_ids) for p, _ in shallow.problems)
    assert any(p == str(bad_ids) and "[201]" in m for p, m in deep.problems)
    assert inspect([f"root={copy}"]) == 1


def test_not_a_dataset(tmp_path: Path) -> None:
    report = inspect_dataset(tmp_path)
    assert not report.ok and "dataset.yaml" in report.problems[0][0]
    assert exit_status(inspect, []) == 2  # root= is required
