"""Charts of a metric by incidence-angle ring, as SVG drawn by hand (no plotting dependency; it renders in Markdown),
each carrying the values it plots.

``docs/figures/absrel_by_ring.svg`` and ``miou_by_ring.svg`` are drawn from the committed quick-start record
(:data:`RECORD_FIGURES`, one seed per task from its ``breakdown``; ``python scripts/plot_rings.py --record
docs/quickstart_results.json --out docs/figures``). Every chart embeds in its ``<metadata>`` the values it plots and
where they came from (:func:`plotted`), so a test compares a committed figure with its record without decoding the
drawing, and a figure drawn before the record changed is caught.

Example:
    >>> svg = svg_chart({"a": [(0.0, 30.0, 0.1), (30.0, 95.0, 0.2)]}, "abs_rel", "t", {"source": "x.json"})
    >>> plotted(svg)["series"]["a"]["values"]
    [[0.0, 30.0, 0.1], [30.0, 95.0, 0.2]]
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from html import escape, unescape
from typing import Any

__all__ = [
    "RECORD_COMMAND",
    "RECORD_FIGURES",
    "RingFigure",
    "plotted",
    "record_figure",
    "ring_values",
    "svg_chart",
]

COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")
_RING = re.compile(r"^ring_([0-9.]+)-([0-9.]+)/(.+)$")
_METADATA = re.compile(r'<metadata id="plotted">(.*?)</metadata>', re.DOTALL)

Ring = tuple[float, float, "float | None"]


@dataclass(frozen=True)
class RingFigure:
    """A figure of the report: ``metric`` by ring, one line per ``(label, task, seed)`` of the quick-start record."""

    name: str
    metric: str
    title: str
    series: tuple[tuple[str, str, str], ...]


#: The report's figures (docs/results.md, section 5): depth and completion seed 1, segmentation seed 2.
RECORD_FIGURES = (
    RingFigure(
        "absrel_by_ring.svg",
        "abs_rel",
        "Depth AbsRel by incidence angle, synthetic quickstart test split",
        (("AdaBins (image only)", "depth", "1"), ("NLSPN + LiDAR (ordering)", "completion", "1")),
    ),
    RingFigure(
        "miou_by_ring.svg",
        "mIoU",
        "mIoU by incidence angle, synthetic quickstart test split",
        (("DeepLabV3+ / ResNet18", "seg", "2"),),
    ),
)
#: The command that draws :data:`RECORD_FIGURES` (each figure's metadata names it).
RECORD_COMMAND = "python scripts/plot_rings.py --record docs/quickstart_results.json --out docs/figures"


def ring_values(breakdown: Mapping[str, float | None], metric: str) -> list[Ring]:
    """``(lo, hi, value)`` of ``metric`` per incidence-angle ring of a ``breakdown`` (``ring_<lo>-<hi>/<metric>``),
    in ring order; a ``ValueError`` when it has none.

    Example:
        >>> ring_values({"ring_30-60/rmse": 2.0, "ring_0-30/rmse": 1.0, "range_0-10/rmse": 9.0}, "rmse")
        [(0.0, 30.0, 1.0), (30.0, 60.0, 2.0)]
    """
    rings = []
    for key, value in breakdown.items():
        match = _RING.match(key)
        if match and match.group(3) == metric:
            rings.append((float(match.group(1)), float(match.group(2)), value))
    if not rings:
        raise ValueError(f"no ring_*/{metric} values in the breakdown")
    return sorted(rings)


def record_figure(record: Mapping[str, Any], figure: RingFigure, source: str) -> str:
    """``figure`` drawn from the quick-start ``record`` (read from the file ``source``); a ``KeyError`` naming the
    task and seed the record lacks."""
    series, origins = {}, {}
    for label, task, seed in figure.series:
        try:
            breakdown = record["tasks"][task]["seeds"][seed]["breakdown"]
        except KeyError:
            raise KeyError(f"{source} has no breakdown of {task} seed {seed} ({figure.name})") from None
        series[label] = ring_values(breakdown, figure.metric)
        origins[label] = f"{task} seed {seed}"
    meta = {"source": source, "record_commit": record.get("commit"), "command": RECORD_COMMAND}
    return svg_chart(series, figure.metric, figure.title, meta, origins)


def svg_chart(
    series: Mapping[str, Sequence[Ring]],
    metric: str,
    title: str,
    source: Mapping[str, Any],
    origins: Mapping[str, str] | None = None,
) -> str:
    """A line chart: x = ring centre (degrees), y = metric; one polyline and legend entry per series. Its
    ``<metadata>`` holds ``source`` and, per series, its ``origin`` and the ``values`` plotted (:func:`plotted`)."""
    width, height, left, right, top, bottom = 640, 360, 64, 170, 36, 48
    values = [v for rings in series.values() for _, _, v in rings if v is not None]
    x_max = max(hi for rings in series.values() for _, hi, _ in rings)
    y_max = max(values) * 1.1 if values else 1.0
    plot_w, plot_h = width - left - right, height - top - bottom

    def x(deg: float) -> float:
        return left + plot_w * deg / x_max

    def y(value: float) -> float:
        return top + plot_h * (1 - value / y_max)

    meta = {
        **source,
        "metric": metric,
        "series": {
            label: {"origin": (origins or {}).get(label, label), "values": [list(r) for r in rings]}
            for label, rings in series.items()
        },
    }
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" '
        f'font-size="12"><rect width="100%" height="100%" fill="white"/>',
        f'<metadata id="plotted">{escape(json.dumps(meta, sort_keys=True), quote=False)}</metadata>',
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


def plotted(svg: str) -> dict[str, Any]:
    """The metadata :func:`svg_chart` embedded: ``{"source", "metric", "series": {label: {"origin", "values"}}}``;
    a ``ValueError`` for an SVG without it (drawn before charts carried their values)."""
    match = _METADATA.search(svg)
    if match is None:
        raise ValueError("the SVG has no plotted-values metadata")
    return json.loads(unescape(match.group(1)))
