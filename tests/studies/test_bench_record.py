"""scripts/bench_record.py: a benchmark's output kept whole with its provenance, and the tables read back from it."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from airfisheye_bench.studies import bench_record


def test_a_recorded_run_keeps_the_output_its_provenance_and_the_load(tmp_path: Path, capsys) -> None:
    script = tmp_path / "bench_x.py"
    script.write_text("print('timing')\nprint('| case | ms |')\nprint('|---|---:|')\nprint('| a | 1.5 |')\n")
    record = bench_record.run_recorded(
        str(script), ["--fast"], ["--json", "x.json", "--", str(script), "--fast"]
    )
    assert record["benchmark"] == f"python {script} --fast"
    assert (
        record["provenance"]["command"] == f"python scripts/bench_record.py --json x.json -- {script} --fast"
    )
    assert len(record["load_average_before"]) == len(record["load_average_after"]) == 3
    assert record["wall_s"] > 0 and record["cpu_s"] >= 0
    assert bench_record.tables(record["output"]) == [["| case | ms |", "|---|---:|", "| a | 1.5 |"]]
    assert "| a | 1.5 |" in capsys.readouterr().out  # passed through as it ran


def test_a_failed_benchmark_writes_no_record(tmp_path: Path) -> None:
    script = tmp_path / "broken.py"
    script.write_text("import sys\nsys.exit(3)\n")
    with pytest.raises(RuntimeError, match="exited with 3: no record written"):
        bench_record.run_recorded(str(script), [], [sys.executable])


def test_a_benchmark_reading_a_dataset_records_its_content_identity(tmp_path: Path) -> None:
    root = tmp_path / "data"
    (root / "a").mkdir(parents=True)
    (root / "a" / "x.bin").write_bytes(b"frame")
    (root / "manifest.json").write_text("{}")
    script = tmp_path / "bench_x.py"
    script.write_text("print('ok')\n")
    record = bench_record.run_recorded(str(script), [], [str(script)], data=[root])
    (identity,) = record["datasets"]
    assert identity["name"] == "data" and len(identity["content_sha256"]) == 64
    changed = tmp_path / "data2"
    (changed / "a").mkdir(parents=True)
    (changed / "a" / "x.bin").write_bytes(b"other")
    (changed / "manifest.json").write_text("{}")
    other = bench_record.run_recorded(str(script), [], [str(script)], data=[changed])
    assert other["datasets"][0]["content_sha256"] != identity["content_sha256"]


def test_a_record_keeps_the_environment_that_changes_what_is_measured(tmp_path: Path, monkeypatch) -> None:
    script = tmp_path / "bench_x.py"
    script.write_text("import os\nprint(os.environ['MALLOC_TRIM_THRESHOLD_'])\n")
    for name in bench_record.ENVIRONMENT:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "4294967296")
    record = bench_record.run_recorded(str(script), [], [str(script)])
    assert record["environment"] == {"MALLOC_TRIM_THRESHOLD_": "4294967296"}
    assert record["output"].strip() == "4294967296"  # the benchmark ran with it
