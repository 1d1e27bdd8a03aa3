"""``scripts/bench_loader.py`` (:mod:`airfisheye_bench.studies.loader_speed`) runs end to end on the tiny dataset (structure only, no timing thresholds)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from airfisheye_bench.io.content import content_identity
from airfisheye_bench.studies import loader_speed


@pytest.mark.integration
def test_main_tiny(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bench = loader_speed
    argv = ["--root", str(tiny_dataset), "--size", "32", "--samples", "3", "--repeats", "2"]
    results = bench.main([*argv, "--tasks", "seg", "completion"])
    assert [(r["task"], r["source"]) for r in results] == [
        ("seg", "cubemap"),
        ("seg", "fisheye"),
        ("completion", "cubemap"),
        ("completion", "fisheye"),
    ]
    for r in results:
        assert 0 < r["cpu_min"] <= r["cpu_median"] and math.isfinite(r["cpu_median"])
        assert r["decode"] >= 0 and math.isfinite(r["rss_growth"])
        assert r["samples"] == 3
    rows = [
        line
        for line in capsys.readouterr().out.splitlines()
        if line.startswith("| tiny") and ("| seg |" in line or "| completion |" in line)
    ]
    assert len(rows) == 4


@pytest.mark.integration
def test_per_core_json(tiny_dataset: Path, tmp_path: Path) -> None:
    """Both remap sites, two sizes, the rows and their provenance in the JSON file."""
    out = tmp_path / "loader.json"
    argv = ["--root", str(tiny_dataset), "--size", "32", "48", "--samples", "2", "--repeats", "1"]
    results = loader_speed.main(
        [
            *argv,
            "--tasks",
            "depth",
            "--sources",
            "cubemap",
            "--remap-on",
            "worker",
            "device",
            "--out",
            str(out),
        ]
    )
    assert [(r["size"], r["remap_on"]) for r in results] == [
        (32, "worker"),
        (32, "device"),
        (48, "worker"),
        (48, "device"),
    ]
    record = json.loads(out.read_text())
    assert record["results"] == json.loads(json.dumps(results))
    assert record["command"].startswith("python scripts/bench_loader.py --root")
    assert record["commit"] and "CPU cores" in record["machine"] and len(record["load_average_after"]) == 3
    assert all(r["samples_per_s_per_core"] > 0 and r["face_size"] == 48 for r in record["results"])
    # One root served at two sizes: one identity, that of the files the rows read.
    (identity,) = record["datasets"]
    assert identity["root"] == str(tiny_dataset)
    assert identity["content_sha256"] == content_identity(tiny_dataset)["content_sha256"]


@pytest.mark.integration
def test_fixed_and_drawn_lenses_side_by_side(tiny_dataset: Path) -> None:
    """``--lenses fixed drawn``: the same configuration timed with one lens and with a lens drawn per sample."""
    results = loader_speed.main(
        [
            *[
                "--root",
                str(tiny_dataset),
                "--size",
                "32",
                "--samples",
                "2",
                "--repeats",
                "2",
                "--tasks",
                "depth",
            ],
            *["--sources", "cubemap", "fisheye", "--lenses", "fixed", "drawn", "pooled"],
        ]
    )
    # A pre-rendered fisheye has one lens: it is timed fixed only.
    assert [(r["source"], r["lenses"]) for r in results] == [
        ("cubemap", "fixed"),
        ("cubemap", "drawn"),
        ("cubemap", "pooled"),
        ("fisheye", "fixed"),
    ]
    assert all(r["cpu_median"] > 0 for r in results)
    pooled = results[2]
    assert pooled["pool"] == loader_speed.POOL and pooled["cold_cpu_median"] > 0


@pytest.mark.integration
def test_rows_say_how_many_samples_a_short_split_served(tiny_dataset: Path) -> None:
    """``--samples`` beyond the split's frames: each frame once, and the row says how many (not ``--samples``)."""
    argv = ["--root", str(tiny_dataset), "--size", "32", "--samples", "1000", "--repeats", "1"]
    (row,) = loader_speed.main([*argv, "--tasks", "seg", "--sources", "fisheye"])
    assert 0 < row["samples"] < 1000
