"""``airfisheye-generate bench json=FILE``: the frame writer's timings as a record, with what the docs cite them by
(commit, command, machine, the load averages around the run) and each preset's wall and CPU seconds per frame."""

from __future__ import annotations

import json
from pathlib import Path

from airfisheye_bench.cli import commands


def test_the_bench_writes_a_record_with_its_provenance_and_cpu_time(tmp_path: Path, capsys) -> None:
    out = tmp_path / "bench.json"
    assert commands.generate(["bench", "presets=[tiny]", "frames=1", f"json={out}"]) == 0
    assert "| tiny | 48^2 |" in capsys.readouterr().out
    record = json.loads(out.read_text())
    made = record["provenance"]
    assert made["command"] == f"python scripts/generate_synthetic.py bench presets=[tiny] frames=1 json={out}"
    assert made["commit"] and "CPU cores" in made["machine"]
    assert len(record["load_average_before"]) == len(record["load_average_after"]) == 3
    tiny = record["presets"]["tiny"]
    assert tiny["frames"] == 1 and tiny["frame_s"] > 0 and tiny["frame_cpu_s"] > 0
