"""Summarise the Chamfer probe's runs: each setting over its seeds, and paired against training without the term.

    python scripts/depth_probe_summary.py                       # docs/figures/depth_probe/*_seed*.json
    python scripts/depth_probe_summary.py --json docs/figures/depth_probe/summary.json

Prints a markdown table per setting (mean ± sample std over seeds of the last step's scores) and the paired
differences against ``w0`` with 95 % t-intervals over seeds; ``--json`` also writes them, with provenance. The logic
is :mod:`airfisheye_bench.studies.depth_probe`.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_json
from airfisheye_bench.studies import depth_probe
from airfisheye_bench.studies.paired import paired_table
from airfisheye_bench.studies.provenance import provenance

REPO = Path(__file__).resolve().parents[1]
_SHOWN = ("rmse", "abs_rel", "delta1", "eval_train_gap", "centre_median", "pred_over_gt")


def _mean_sd(values: list[float]) -> str:
    if len(values) < 2:
        return f"{values[0]:.3f}"
    return f"{statistics.mean(values):.3f} ± {statistics.stdev(values):.3f}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--folder", type=Path, default=REPO / "docs" / "figures" / "depth_probe")
    parser.add_argument("--json", type=Path, help="also write the summary here")
    args = parser.parse_args(argv)
    runs = depth_probe.load_runs(args.folder)
    if not runs:
        raise SystemExit(f"{args.folder}: no <setting>_seed<s>.json records")
    summary = depth_probe.summarize(runs)
    lines = [
        "| setting | seeds | " + " | ".join(_SHOWN) + " | beats the baseline |",
        "|---|---|" + "---:|" * len(_SHOWN) + "---|",
    ]
    for setting, entry in summary["settings"].items():
        seeds = entry["seeds"]
        cells = [_mean_sd([s[m] for s in seeds.values()]) for m in _SHOWN]
        beats = sum(entry["beats_baseline"].values())
        lines.append(
            f"| {setting} | {', '.join(seeds)} | " + " | ".join(cells) + f" | {beats} of {len(seeds)} |"
        )
    base = summary["baseline"]
    lines += [
        "",
        f"Baseline (the training batches' mean depth per pixel): RMSE {base['rmse']:.2f} m, "
        f"AbsRel {base['abs_rel']:.3f}, δ1 {base['delta1']:.3f}.",
        "",
    ]
    paired = summary["paired_vs_w0"]
    if paired:
        lines.append(paired_table(paired, ["rmse", "abs_rel", "delta1"], reference="w0", arm="setting"))
    print("\n".join(lines))
    if args.json:
        summary = {
            **provenance("scripts/depth_probe_summary.py", argv if argv is not None else sys.argv[1:]),
            **summary,
        }
        atomic_write_json(args.json, summary, indent=1)  # NaN (one pair) -> null
    return 0


if __name__ == "__main__":
    sys.exit(main())
