"""Run a speed benchmark script and keep its output as a record with its provenance (commit, command, machine, load
averages before and after, wall and CPU time), for the tables of ``docs/benchmarks.md`` to cite.

    python scripts/bench_record.py --json docs/figures/bench/metrics.json -- scripts/bench_metrics.py [args]
    python scripts/bench_record.py --json docs/figures/bench/decode.json --data /tmp/afb_bench512 \
        -- scripts/bench_decode.py --root /tmp/afb_bench512

The logic is ``airfisheye_bench.studies.bench_record``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.studies.bench_record import run_recorded


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, required=True, help="the record to write")
    parser.add_argument(
        "--data",
        nargs="+",
        default=[],
        help="dataset folders the benchmark reads: the record keeps their content identity",
    )
    parser.add_argument(
        "benchmark", nargs=argparse.REMAINDER, help="-- scripts/<benchmark>.py [its arguments]"
    )
    args = parser.parse_args(argv)
    benchmark = args.benchmark[1:] if args.benchmark[:1] == ["--"] else args.benchmark
    if not benchmark or not benchmark[0].endswith(".py"):
        parser.error("give the benchmark after --: -- scripts/<benchmark>.py [its arguments]")
    try:
        record = run_recorded(benchmark[0], benchmark[1:], argv, data=args.data)
    except RuntimeError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    atomic_write_text(args.json, json.dumps(record, indent=2) + "\n")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
