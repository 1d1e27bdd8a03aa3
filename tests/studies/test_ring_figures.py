"""The report's ring figures: drawn from the committed quick-start record, and carrying the values they plot."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from airfisheye_bench.studies import ring_figures

ROOT = Path(__file__).resolve().parents[2]
RECORD = ROOT / "docs" / "quickstart_results.json"


@pytest.mark.parametrize("figure", ring_figures.RECORD_FIGURES, ids=lambda f: f.name)
def test_a_report_figure_plots_what_the_record_holds(figure: ring_figures.RingFigure) -> None:
    record = json.loads(RECORD.read_text(encoding="utf-8"))
    svg = (ROOT / "docs" / "figures" / figure.name).read_text(encoding="utf-8")
    shown = ring_figures.plotted(svg)
    assert shown["source"] == "docs/quickstart_results.json" and shown["metric"] == figure.metric
    for label, task, seed in figure.series:
        breakdown = record["tasks"][task]["seeds"][seed]["breakdown"]
        expected = [list(r) for r in ring_figures.ring_values(breakdown, figure.metric)]
        assert shown["series"][label]["values"] == expected, (
            f"{figure.name}: {label} is not {task} seed {seed} of {RECORD.name}; "
            f"redraw: {ring_figures.RECORD_COMMAND}"
        )
    # ... and the drawing is the one those values give (no hand-edited point).
    assert svg == ring_figures.record_figure(record, figure, "docs/quickstart_results.json"), (
        f"redraw: {ring_figures.RECORD_COMMAND}"
    )


def test_a_chart_embeds_its_values_and_a_point_moves_with_them() -> None:
    series = {"a": [(0.0, 30.0, 0.1), (30.0, 95.0, 0.2)], "b & <c>": [(0.0, 30.0, None), (30.0, 95.0, 0.4)]}
    svg = ring_figures.svg_chart(series, "abs_rel", "t", {"source": "x.json"}, {"a": "depth seed 1"})
    meta = ring_figures.plotted(svg)
    assert meta["series"]["a"] == {"origin": "depth seed 1", "values": [[0.0, 30.0, 0.1], [30.0, 95.0, 0.2]]}
    assert meta["series"]["b & <c>"]["values"][0] == [0.0, 30.0, None]  # escaped in the SVG, read back whole
    moved = ring_figures.svg_chart({**series, "a": [(0.0, 30.0, 0.3), (30.0, 95.0, 0.2)]}, "abs_rel", "t", {})
    polyline = next(line for line in svg.splitlines() if line.startswith("<polyline"))
    assert polyline not in moved
    with pytest.raises(ValueError, match="no plotted-values metadata"):
        ring_figures.plotted("<svg></svg>")


def test_a_figure_of_a_seed_the_record_lacks_names_it() -> None:
    record = {"commit": "0" * 40, "tasks": {"seg": {"seeds": {}}}}
    figure = ring_figures.RingFigure("x.svg", "mIoU", "t", (("l", "seg", "2"),))
    with pytest.raises(KeyError, match="seg seed 2"):
        ring_figures.record_figure(record, figure, "r.json")
