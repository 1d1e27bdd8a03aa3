"""How far each quick-start result moves with the CPU's kernels, beside its seeds' spread.

    python scripts/quickstart_kernels.py
    python scripts/quickstart_kernels.py --json docs/figures/quickstart_kernels/summary.json
    python scripts/quickstart_kernels.py --cross-evaluate RUN [RUN ...] --cross-json FILE

Reads ``docs/quickstart_results.json`` (the machine's own kernels) and the limited-kernel runs of
``docs/figures/quickstart_kernels/``; prints, per task, each kernel path's mean ± sample std over its seeds (test
metrics and the last validation score) and the per-seed paired differences (limited − record) with 95 % t-intervals.
``--json`` also writes them, with provenance. ``--cross-evaluate`` scores the test split with each given quick-start
run's best checkpoint under every kernel setting those runs were trained with (each in a fresh process, one thread)
and prints how far any score moves with the setting: whether the kernels act on the evaluation or on the training.
The logic is :mod:`airfisheye_bench.studies.quickstart_kernels`.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_json
from airfisheye_bench.studies import quickstart_kernels
from airfisheye_bench.studies.paired import paired_table
from airfisheye_bench.studies.provenance import provenance

REPO = Path(__file__).resolve().parents[1]
METRICS = {
    "seg": ["mIoU", "pixel_acc"],
    # and the depth bands, where the paths part (docs/results.md, section 2)
    "depth": [
        "rmse",
        "abs_rel",
        "delta1",
        *(f"range_{band}/rmse" for band in ("0-10", "10-20", "20-40", "40-80", "80-120")),
    ],
    "completion": ["rmse", "mae", "abs_rel", "delta1"],
}


def _cell(entry: dict) -> str:
    if entry["std"] is None:
        return f"{entry['mean']:.3f}"
    return f"{entry['mean']:.3f} ± {entry['std']:.3f}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--record", type=Path, default=REPO / "docs" / "quickstart_results.json")
    parser.add_argument("--folder", type=Path, default=REPO / "docs" / "figures" / "quickstart_kernels")
    parser.add_argument("--json", type=Path, help="also write the summary here")
    parser.add_argument(
        "--cross-evaluate", type=Path, nargs="+", metavar="RUN", help="quick-start run folders"
    )
    parser.add_argument("--cross-json", type=Path, help="write the --cross-evaluate scores here")
    args = parser.parse_args(argv)
    if args.cross_evaluate:
        return _cross_evaluate(args.cross_evaluate, args.cross_json, argv)
    record, others = quickstart_kernels.load_records(args.record, args.folder)
    runs = quickstart_kernels.kernel_runs(record, others)
    summary = quickstart_kernels.kernel_spread(runs, METRICS)
    for task, entry in summary.items():
        shown = [m for m in METRICS[task] if m in entry["paths"]["record"]] + [
            k for k in entry["paths"]["record"] if k.startswith("val/")
        ]
        print(f"\n### {task}\n")
        print("| kernels | seeds | " + " | ".join(shown) + " |")
        print("|---|---|" + "---:|" * len(shown))
        for path, spread in entry["paths"].items():
            cells = [_cell(spread[k]) if k in spread else "-" for k in shown]
            print(f"| {path} | {', '.join(map(str, spread['seeds']))} | " + " | ".join(cells) + " |")
        if entry["paired"]:
            print()
            print(paired_table(entry["paired"], shown, reference="record", arm="kernels"))
    if args.json:
        payload = {
            **provenance("scripts/quickstart_kernels.py", argv if argv is not None else sys.argv[1:]),
            "datasets": quickstart_kernels.datasets([record, *others]),  # what every run was measured on
            **summary,
        }
        atomic_write_json(args.json, payload)  # NaN (one seed) -> null
    return 0


def _cross_evaluate(runs: list[Path], out: Path | None, argv: list[str] | None) -> int:
    missing = [str(r) for r in runs if not (r / "benchmark.json").is_file()]
    if missing:
        print(
            f"error: not quick-start run folders (no benchmark.json): {', '.join(missing)}", file=sys.stderr
        )
        return 2
    result = quickstart_kernels.cross_evaluate(
        runs, lambda run, kernels: quickstart_kernels.evaluate_under(run, kernels, REPO)
    )
    for run in result["runs"]:
        cells = ", ".join(
            f"{name}: rmse {s.get('rmse', float('nan')):.4f}" for name, s in run["scores"].items()
        )
        print(
            f"{run['run']} (trained {run['trained_with']}): {cells}; largest change {run['largest_change']:.2e}"
        )
    if out:
        # the runs' data, identified from its files as every figure's is
        data = json.loads((runs[0] / "results.json").read_text())["dataset"]
        script, args = "scripts/quickstart_kernels.py", argv if argv is not None else sys.argv[1:]
        payload = {**provenance(script, args, dataset=data["root"], dataset_name=data["name"]), **result}
        atomic_write_json(out, payload)
    return 0


if __name__ == "__main__":
    sys.exit(main())
