"""Hidden-point detection's pairwise F1 comparisons restated from an occlusion-study record's per-flight scores.

    python scripts/hidden_detection.py docs/figures/occlusion_ablation/hidden_detection_1536.json \
        --json docs/figures/occlusion_ablation/hidden_detection_1536_paired.json --report docs/results.md

Recomputes each pair's F1 difference over the flights with one family for the Holm correction, the Bonferroni
interval and the minimum detectable effects (``airfisheye_bench.studies.hidden_detection.restate``), without
measuring the frames again; prints the table, ``--json`` writes it with its provenance (the source record's data
identity and commit), ``--report`` rewrites the block of ``docs/results.md`` that shows it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_json, atomic_write_text
from airfisheye_bench.studies import hidden_detection
from airfisheye_bench.studies.generated_blocks import replace_block
from airfisheye_bench.studies.provenance import provenance

REPO = Path(__file__).resolve().parents[1]


def _relative(path: Path) -> str:
    resolved = path.resolve()
    return resolved.relative_to(REPO).as_posix() if resolved.is_relative_to(REPO) else str(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("record", type=Path, help="an occlusion_study.py record with hidden_detection")
    parser.add_argument("--json", type=Path, help="write the restated comparisons here")
    parser.add_argument("--report", type=Path, help="rewrite this report's generated block from --json")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    source = json.loads(args.record.read_text(encoding="utf-8"))
    made = source.get("provenance", source)
    restated = {
        "provenance": {
            **provenance("scripts/hidden_detection.py", argv),
            "dataset": made.get("dataset"),  # the frames the source record measured
        },
        "source": {"file": _relative(args.record), "commit": made.get("commit")},
        "paired_f1": hidden_detection.restate(source),
    }
    for size, paired in restated["paired_f1"].items():
        print(f"{size} px:\n{hidden_detection.paired_table(paired)}\n")
    if args.json is not None:
        atomic_write_json(args.json, restated)
        print(f"wrote {args.json}")
    if args.report is not None:
        if args.json is None:
            parser.error("--report shows the record --json writes: give both")
        name = args.json.resolve().relative_to((REPO / "docs" / "figures").resolve()).as_posix()
        block = hidden_detection.paired_report(restated, name)
        text = args.report.read_text(encoding="utf-8")
        begin, end = hidden_detection.REPORT_BEGIN, hidden_detection.REPORT_END
        atomic_write_text(args.report, replace_block(text, block, begin, end))
        print(f"wrote {args.report}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
