"""Charts of the HTML leaderboard, drawn by matplotlib at build time and inlined as SVG.

Every chart is ``WIDTH_IN`` inches wide (its SVG's ``viewBox`` in points): the page shows it at least that wide
(CSS ``5.6in``) where the window allows, so text of ``FONT_PT`` points is at least ``FONT_PT * 4 / 3`` pixels, 13 px
for legends and axes alike.

Text, axes and grid are drawn in a placeholder colour that becomes ``currentColor`` in the SVG, so every chart
takes the page's text colour and stays readable in light and dark mode (the background is transparent). Data
use the Okabe-Ito palette (distinguishable with the common colour-vision deficiencies), and each series also
has its own marker, so colour is never the only cue.

Example:
    >>> svg = binned_chart({"run1": [(0, 30, 4.1), (30, 60, 5.0), (60, 95, None)]},
    ...                    metric="RMSE (m)", axis="incidence angle (°)", key="demo", label="RMSE by ring")
    >>> svg.startswith("<svg") and "currentColor" in svg and 'aria-label="RMSE by ring"' in svg
    True
"""

from __future__ import annotations

import io
import math
import re
import textwrap
from collections.abc import Mapping, Sequence
from html import escape

__all__ = [
    "FONT_PT",
    "MARKERS",
    "OKABE_ITO",
    "WIDTH_IN",
    "bar_chart",
    "binned_chart",
    "legend_columns",
    "legend_labels",
]

#: Okabe & Ito (2008), without black (the text colour) and yellow (too light on white).
OKABE_ITO = ("#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00")
MARKERS = ("o", "s", "^", "D", "v", "P")
_INK = "#010203"  # placeholder for text, axes and grid: replaced by currentColor
#: A chart's width in inches; the page's CSS shows it at least this wide (``.chart``: ``5.6in``), where it fits.
WIDTH_IN = 5.6
#: Every text of a chart (ticks, labels, legend), in points: 10 pt is 13.3 px at the chart's own size.
FONT_PT = 10
_STYLE = {
    "svg.fonttype": "none",  # text stays text: small, selectable, in the page's font
    "font.family": "sans-serif",
    # Laid out with DejaVu Sans (shipped with matplotlib); similar fallbacks where a browser lacks it.
    "font.sans-serif": ["DejaVu Sans", "Arial", "Helvetica"],
    "font.size": FONT_PT,
    "text.color": _INK,
    "axes.edgecolor": _INK,
    "axes.labelcolor": _INK,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "xtick.color": _INK,
    "ytick.color": _INK,
    "grid.color": _INK,
    "grid.alpha": 0.2,
    "legend.frameon": False,
}
_SIZE = re.compile(r'\s(width|height)="[^"]*"')


def binned_chart(
    series: Mapping[str, Sequence[tuple[float, float, float | None]]],
    *,
    metric: str,
    axis: str,
    key: str,
    label: str,
    scale: float = 1.0,
) -> str:
    """A line chart of a metric over bins (incidence-angle rings, depth ranges), one line per series.

    Args:
        series: ``{legend label: [(lo, hi, value), ...]}``; ``None`` values leave a gap. The bins of all series
            share one categorical axis, in order of ``(lo, hi)``.
        metric: The y-axis label.
        axis: The x-axis label (the bins are labelled ``lo–hi``).
        key: Unique among the charts of one page (SVG element ids are derived from it).
        label: The chart's accessible name.
        scale: Multiplies every value (100 for percentages).

    Returns:
        An ``<svg>`` element without fixed size.
    """
    bins = sorted({(lo, hi) for rows in series.values() for lo, hi, _ in rows})
    position = {b: i for i, b in enumerate(bins)}
    legend = legend_labels(list(series)) if len(series) > 1 else [_plain(name) for name in series]
    columns = legend_columns(legend)
    rows_of_legend = sum(
        max(label.count("\n") + 1 for label in legend[i : i + columns])
        for i in range(0, len(legend), columns)
    )
    from matplotlib.figure import Figure  # matplotlib takes seconds to import: only a page with charts pays

    with _style(key):
        fig = Figure(
            figsize=(WIDTH_IN, 3.0 + (0.22 * rows_of_legend + 0.1 if len(series) > 1 else 0)),
            layout="constrained",
        )
        ax = fig.add_subplot()
        for n, (rows, name) in enumerate(zip(series.values(), legend, strict=True)):
            points = sorted((position[(lo, hi)], math.nan if v is None else v * scale) for lo, hi, v in rows)
            ax.plot(
                [x for x, _ in points],
                [y for _, y in points],
                color=OKABE_ITO[n % len(OKABE_ITO)],
                marker=MARKERS[n % len(MARKERS)],
                linewidth=1.8,
                markersize=5,
                label=name,
            )
        ax.set_xticks(range(len(bins)), [f"{lo:g}–{hi:g}" for lo, hi in bins])
        ax.set_xlabel(axis)
        ax.set_ylabel(metric)
        ax.grid(axis="y")
        if len(series) > 1:  # below the axes: long labels must not squeeze the plot
            fig.legend(loc="outside lower center", ncols=columns, fontsize=FONT_PT)
        return _svg(fig, label)


def bar_chart(
    values: Mapping[str, float | None], *, metric: str, key: str, label: str, scale: float = 1.0
) -> str:
    """Horizontal bars, one per name (e.g. the IoU of each class); ``None`` is written as "n/a".

    Args:
        values: ``{name: value}`` in display order (top to bottom).
        metric: The x-axis label.
        key: Unique among the charts of one page.
        label: The chart's accessible name.
        scale: Multiplies every value (100 for percentages).

    Returns:
        An ``<svg>`` element without fixed size.

    Example:
        >>> svg = bar_chart({"sky": 0.9, "water": None}, metric="IoU (%)", key="iou", label="IoU", scale=100)
        >>> "n/a" in svg and "90.0" in svg
        True
    """
    from matplotlib.figure import Figure  # matplotlib takes seconds to import: only a page with charts pays

    names = list(values)
    numbers = [math.nan if values[n] is None else values[n] * scale for n in names]
    with _style(key):
        fig = Figure(figsize=(WIDTH_IN, 0.9 + 0.27 * len(names)), layout="constrained")
        ax = fig.add_subplot()
        bars = ax.barh(range(len(names)), [0.0 if math.isnan(v) else v for v in numbers], color=OKABE_ITO[0])
        ax.bar_label(bars, labels=["n/a" if math.isnan(v) else f"{v:.1f}" for v in numbers], padding=3)
        ax.set_yticks(range(len(names)), [_plain(n) for n in names])
        ax.invert_yaxis()  # first name on top
        ax.set_xlabel(metric)
        finite = [v for v in numbers if not math.isnan(v)]
        ax.set_xlim(0, max([*finite, 1e-9]) * 1.15)
        ax.grid(axis="x")
        return _svg(fig, label)


#: Characters of a legend label per line at the legend's font size: one column of the chart's width holds this
#: many (DejaVu Sans at 10 pt averages ~0.0875 in a character; the chart is 5.6 in wide).
LEGEND_WIDTH = 60


def legend_labels(names: Sequence[str], width: int = LEGEND_WIDTH) -> list[str]:
    """Every name in full, wrapped to lines of at most ``width`` characters (never cut), literal for matplotlib.

    Example:
        >>> legend_labels(["run_a: deeplabv3plus / resnet18, checkpoint epoch_003", "b"], width=30)
        ['run_a: deeplabv3plus /\\nresnet18, checkpoint epoch_003', 'b']
    """
    return ["\n".join(textwrap.wrap(_plain(n), width, break_on_hyphens=False)) or _plain(n) for n in names]


def legend_columns(labels: Sequence[str], width: int = LEGEND_WIDTH) -> int:
    """Two legend columns when every line of every label fits half the width, else one."""
    longest = max((len(line) for label in labels for line in label.splitlines()), default=0)
    return 2 if longest <= width // 2 - 4 else 1


def _plain(text: str) -> str:
    """Text shown literally: matplotlib would read ``$...$`` in a run or class name as mathtext."""
    return text.replace("$", r"\$")


def _style(key: str):
    """matplotlib's settings for one chart; SVG ids are salted with its key, so they are unique on the page."""
    import matplotlib as mpl  # matplotlib takes seconds to import: only a page with charts pays

    return mpl.rc_context({**_STYLE, "svg.hashsalt": key})


def _svg(fig, label: str) -> str:
    """The figure as an inline ``<svg>``: no XML prolog or metadata, scalable, themed, with an accessible name."""
    buffer = io.StringIO()
    fig.savefig(buffer, format="svg", transparent=True, metadata={"Date": None, "Creator": None})
    text = buffer.getvalue()
    text = text[text.index("<svg") :]
    text = re.sub(r"<metadata>.*?</metadata>\s*", "", text, flags=re.DOTALL)
    # Ids matplotlib names by figure ("figure_1", "axes_1", ...) repeat across charts; only the referenced ones
    # (clip paths, markers: salted hashes, unique per chart) are needed.
    referenced = {a or b for a, b in re.findall(r'url\(#([^)]+)\)|href="#([^"]+)"', text)}
    text = re.sub(r'\sid="([^"]+)"', lambda m: m[0] if m[1] in referenced else "", text)
    head, rest = text.split(">", 1)
    head = _SIZE.sub("", head)  # the viewBox stays: the page sizes the chart with CSS
    head += f' role="img" aria-label="{escape(label)}"'
    return f"{head}>{rest}".replace(_INK, "currentColor").strip()
