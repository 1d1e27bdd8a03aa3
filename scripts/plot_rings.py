"""Plot a metric by incidence-angle ring (error vs theta) as an SVG line chart: of several ``results.json`` files, or
the report's figures from the committed quick-start record.

    python scripts/plot_rings.py runs/eval/depth_ckpt/results.json runs/eval/completion_ckpt/results.json \
        --metric rmse --out runs/rmse_by_ring.svg
    python scripts/plot_rings.py --record docs/quickstart_results.json --out docs/figures

Each file becomes one line over the rings of its breakdown (``ring_<lo>-<hi>/<metric>``), labelled with its
``model.name`` (or ``--labels``). With ``--record``, ``--out`` is a folder and the figures of ``docs/results.md``
(``airfisheye_bench.studies.ring_figures.RECORD_FIGURES``) are drawn there from the record's seeds. Every chart
embeds the values it plots (``ring_figures.plotted``), which the tests compare with the record.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.evaluation import load_results
from airfisheye_bench.studies.ring_figures import (
    RECORD_FIGURES,
    plotted,
    record_figure,
    ring_values,
    svg_chart,
)

REPO = Path(__file__).resolve().parents[1]


def _print(svg: str, out: Path) -> None:
    for label, series in plotted(svg)["series"].items():
        cells = ", ".join(
            f"{lo:g}-{hi:g}: {'-' if v is None else f'{v:.4g}'}" for lo, hi, v in series["values"]
        )
        print(f"{label} ({series['origin']}): {cells}")
    print(f"wrote {out}")


def _from_record(record_path: Path, folder: Path) -> None:
    record = json.loads(record_path.read_text(encoding="utf-8"))
    resolved = record_path.resolve()
    source = resolved.relative_to(REPO).as_posix() if resolved.is_relative_to(REPO) else str(record_path)
    for figure in RECORD_FIGURES:
        svg = record_figure(record, figure, source)
        atomic_write_text(folder / figure.name, svg)
        _print(svg, folder / figure.name)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", nargs="*", type=Path, help="results.json files")
    parser.add_argument("--record", type=Path, help="draw the report's figures from this quick-start record")
    parser.add_argument(
        "--metric", default="rmse", help="metric key of the breakdown (rmse, abs_rel, mIoU, ...)"
    )
    parser.add_argument("--labels", default=None, help="comma-separated legend labels, one per file")
    parser.add_argument("--title", default=None)
    parser.add_argument("--out", type=Path, required=True, help="output .svg (a folder with --record)")
    args = parser.parse_args(argv)
    if args.record is not None:
        if args.results:
            parser.error("give results.json files or --record, not both")
        try:
            _from_record(args.record, args.out)
        except (OSError, KeyError, ValueError) as err:
            parser.error(f"{args.record}: {err}")
        return 0
    if not args.results:
        parser.error("give results.json files (or --record)")
    labels = args.labels.split(",") if args.labels else [None] * len(args.results)
    if len(labels) != len(args.results):
        parser.error(f"--labels has {len(labels)} names for {len(args.results)} files")
    series, origins = {}, {}
    for path, label in zip(args.results, labels, strict=True):
        record = load_results(path)
        name = label or record.get("model", {}).get("name") or path.parent.name
        try:
            series[name] = ring_values(record.get("breakdown", {}), args.metric)
        except ValueError as err:
            parser.error(f"{path}: {err}")
        origins[name] = str(path)
    title = args.title or f"{args.metric} by incidence-angle ring"
    command = "python scripts/plot_rings.py " + " ".join(sys.argv[1:] if argv is None else argv)
    svg = svg_chart(series, args.metric, title, {"command": command}, origins)
    atomic_write_text(args.out, svg)
    _print(svg, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
