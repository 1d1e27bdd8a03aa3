"""A record of a speed benchmark that prints its tables: the script run once, its output kept with what a number of
``docs/benchmarks.md`` is cited by (commit, command, machine, the load averages before and after, its wall and CPU
time), so that a table there names the file it comes from (``tests/test_figures_provenance.py`` checks that a
cited record holds the table's rows).

    python scripts/bench_record.py --json docs/figures/bench/metrics.json -- scripts/bench_metrics.py

The scripts print markdown tables already; keeping their output whole, rather than a schema per benchmark, is what
lets one recorder serve each of them.

Example:
    >>> tables("text\\n| a | b |\\n|---|---|\\n| 1 | 2 |\\nmore")
    [['| a | b |', '|---|---|', '| 1 | 2 |']]
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from airfisheye_bench.runs.results import dataset_identity
from airfisheye_bench.studies.provenance import REPO, load_average, provenance

__all__ = ["ENVIRONMENT", "run_recorded", "tables"]

#: Environment variables that change what a benchmark measures (threads, the allocator, where data are cached): a
#: record keeps those that were set, since its command line does not show them.
ENVIRONMENT = (
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "MALLOC_MMAP_THRESHOLD_",
    "MALLOC_TRIM_THRESHOLD_",
    "AIRFISHEYE_DATA",
    "ATEN_CPU_CAPABILITY",
    "ONEDNN_MAX_CPU_ISA",
)


def run_recorded(
    script: str,
    args: Sequence[str],
    recorder_argv: Sequence[str],
    repo: Path = REPO,
    data: Sequence[str | Path] = (),
) -> dict[str, Any]:
    """Run ``python <script> <args>`` in ``repo`` (its output passed through) and return its record; a
    ``RuntimeError`` naming the script when it fails, so no record of a failed run is written.

    ``data``: the dataset folders the benchmark reads; the record keeps each one's content identity
    (``datasets``), so a number names the data it was measured on."""
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(repo), os.environ.get("PYTHONPATH")])),
    }
    before, cpu_before = load_average(), resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, script, *args], cwd=repo, env=env, capture_output=True, text=True, check=False
    )
    wall = time.perf_counter() - start
    cpu_after = resource.getrusage(resource.RUSAGE_CHILDREN)
    sys.stdout.write(done.stdout)
    if done.returncode != 0:
        sys.stderr.write(done.stderr[-4000:])
        raise RuntimeError(f"python {script} exited with {done.returncode}: no record written")
    return {
        "provenance": provenance("scripts/bench_record.py", list(recorder_argv)),
        "benchmark": " ".join(["python", script, *args]),
        "environment": {name: os.environ[name] for name in ENVIRONMENT if name in os.environ},
        "load_average_before": before,
        "load_average_after": load_average(),
        "wall_s": round(wall, 2),
        "cpu_s": round(
            (cpu_after.ru_utime - cpu_before.ru_utime) + (cpu_after.ru_stime - cpu_before.ru_stime), 2
        ),
        **({"datasets": [dataset_identity(root, Path(root).name) for root in data]} if data else {}),
        "output": done.stdout,
    }


def tables(output: str) -> list[list[str]]:
    """The markdown tables of a benchmark's output, each as its lines (header, separator, rows)."""
    found: list[list[str]] = []
    current: list[str] = []
    for line in [*output.splitlines(), ""]:
        if line.strip().startswith("|"):
            current.append(line.strip())
        elif current:
            found.append(current)
            current = []
    return [t for t in found if len(t) > 2]
