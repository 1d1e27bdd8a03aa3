"""Plot a metric by incidence-angle ring (error vs theta) for several ``results.json`` files, as an SVG line chart.

    python scripts/plot_rings.py runs/eval/depth_ckpt/results.json runs/eval/completion_ckpt/results.json \
        --metric rmse --out docs/figures/rmse_by_ring.svg

Each file becomes one line over the rings of its breakdown (``ring_<lo>-<hi>/<metric>``), labelled with its
``model.name`` (or ``--labels``). SVG is written by hand: no plotting dependency, and it renders in Markdown.
"""

from __future__ import annotations

import argparse
import re
from html import escape
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.evaluation import load_results

COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")
_RING = re.compile(r"^ring_([0-9.]+)-([0-9.]+)/(.+)$")


def ring_values(record: dict, metric: str) -> list[tuple[float, float, float | None]]:
    """``(lo, hi, value)`` of ``metric`` per incidence-angle ring, in ring order."""
    rings = []
    for key, value in record.get("breakdown", {}).items():
        match = _RING.match(key)
        if match and match.group(3) == metric:
            rings.append((float(match.group(1)), float(match.group(2)), value))
    if not rings:
        raise ValueError(f"no ring_*/{metric} values in the breakdown")
    return sorted(rings)


def svg_chart(series: dict[str, list[tuple[float, float, float | None]]], metric: str, title: str) -> str:
    """A line chart: x = ring centre (degrees), y = metric; one polyline and legend entry per series."""
    width, height, left, right, top, bottom = 640, 360, 64, 170, 36, 48
    values = [v for rings in series.values() for _, _, v in rings if v is not None]
    x_max = max(hi for rings in series.values() for _, hi, _ in rings)
    y_max = max(values) * 1.1 if values else 1.0
    plot_w, plot_h = width - left - right, height - top - bottom

    def x(deg: float) -> float:
        return left + plot_w * deg / x_max

    def y(value: float) -> float:
        return top + plot_h * (1 - value / y_max)

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" '
        f'font-size="12"><rect width="100%" height="100%" fill="white"/>',
        f'<text x="{left}" y="20" font-size="14">{escape(title)}</text>',
        f'<line x1="{left}" y1="{top + plot_h}" x2="{left + plot_w}" y2="{top + plot_h}" stroke="black"/>',
        f'<line x1="{left}" y1="{top}" x2="{left}" y2="{top + plot_h}" stroke="black"/>',
        f'<text x="{left + plot_w / 2}" y="{height - 10}" text-anchor="middle">incidence angle theta (deg), '
        "ring centre</text>",
        f'<text x="16" y="{top + plot_h / 2}" transform="rotate(-90 16 {top + plot_h / 2})" '
        f'text-anchor="middle">{escape(metric)}</text>',
    ]
    for i in range(6):
        value = y_max * i / 5
        out.append(f'<text x="{left - 6}" y="{y(value) + 4:.1f}" text-anchor="end">{value:.3g}</text>')
        out.append(
            f'<line x1="{left}" y1="{y(value):.1f}" x2="{left + plot_w}" y2="{y(value):.1f}" stroke="#ddd"/>'
        )
    edges = sorted({e for rings in series.values() for lo, hi, _ in rings for e in (lo, hi)})
    for edge in edges:
        out.append(f'<text x="{x(edge):.1f}" y="{top + plot_h + 16}" text-anchor="middle">{edge:g}</text>')
    for n, (label, rings) in enumerate(series.items()):
        colour = COLOURS[n % len(COLOURS)]
        points = [(x((lo + hi) / 2), y(v)) for lo, hi, v in rings if v is not None]
        path = " ".join(f"{px:.1f},{py:.1f}" for px, py in points)
        out.append(f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="2"/>')
        out += [f'<circle cx="{px:.1f}" cy="{py:.1f}" r="3" fill="{colour}"/>' for px, py in points]
        ly = top + 14 + 18 * n
        out.append(
            f'<line x1="{width - right + 12}" y1="{ly - 4}" x2="{width - right + 32}" y2="{ly - 4}" '
            f'stroke="{colour}" stroke-width="2"/>'
        )
        out.append(f'<text x="{width - right + 38}" y="{ly}">{escape(label)}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", nargs="+", type=Path, help="results.json files")
    parser.add_argument(
        "--metric", default="rmse", help="metric key of the breakdown (rmse, abs_rel, mIoU, ...)"
    )
    parser.add_argument("--labels", default=None, help="comma-separated legend labels, one per file")
    parser.add_argument("--title", default=None)
    parser.add_argument("--out", type=Path, required=True, help="output .svg")
    args = parser.parse_args(argv)
    labels = args.labels.split(",") if args.labels else [None] * len(args.results)
    if len(labels) != len(args.results):
        parser.error(f"--labels has {len(labels)} names for {len(args.results)} files")
    series = {}
    for path, label in zip(args.results, labels, strict=True):
        record = load_results(path)
        try:
            series[label or record.get("model", {}).get("name") or path.parent.name] = ring_values(
                record, args.metric
            )
        except ValueError as err:
            parser.error(f"{path}: {err}")
    title = args.title or f"{args.metric} by incidence-angle ring"
    atomic_write_text(args.out, svg_chart(series, args.metric, title))
    for label, rings in series.items():
        cells = ", ".join(f"{lo:g}-{hi:g}: {'-' if v is None else f'{v:.4g}'}" for lo, hi, v in rings)
        print(f"{label}: {cells}")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
