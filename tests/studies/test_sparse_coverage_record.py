"""The sparse-coverage records of both readings of the paper's density, and the table of docs/design.md ("Sparse
input density") that shows them: every cell is its record's value, and the paper's side is labelled modelled."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIGURES = ROOT / "docs" / "figures"
RECORDS = {128: FIGURES / "sparse_coverage_readings.json", 64: FIGURES / "sparse_coverage_readings_64.json"}
QUICKSTART_CONTENT = json.loads((ROOT / "docs" / "quickstart_results.json").read_text())["dataset"]


def _record(size: int) -> dict:
    return json.loads(RECORDS[size].read_text(encoding="utf-8"))


def _design_rows() -> dict[str, list[str]]:
    text = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    section = text.split("### Sparse input density", 1)[1].split("\n### ", 1)[0]
    rows = [line.strip() for line in section.splitlines() if line.strip().startswith("| ")]
    header, body = rows[0], rows[1:]  # the |---| line is not a row
    assert header.startswith("| ring (deg) | model 1536^2 | model 512^2 |"), header
    return {cells[0]: cells[1:] for cells in ([c.strip() for c in r.strip("|").split("|")] for r in body)}


@pytest.mark.parametrize("size", sorted(RECORDS))
def test_a_coverage_record_names_both_readings_and_says_the_paper_side_is_modelled(size: int) -> None:
    record = _record(size)
    assert record["size"] == size and record["densities"] == ["native", "paper_1536", "paper_512"]
    assert set(record["modelled"]) == {"model_1536", "model_512"}
    assert all("not a measurement" in text for text in record["modelled"].values())
    # The data the quick starts were trained and scored on.
    assert record["provenance"]["dataset"]["content_sha256"] == QUICKSTART_CONTENT["content_sha256"]
    for ring in record["rings"]:  # each reading serves about as many pixels as its model gives
        for reading in ("1536", "512"):
            assert ring["served"][f"paper_{reading}"] == pytest.approx(ring[f"model_{reading}"], rel=0.2)


def test_the_design_table_is_the_records() -> None:
    rows = _design_rows()
    big, small = _record(128), _record(64)
    assert len(rows) == len(big["rings"]) == len(small["rings"])
    for ring, other in zip(big["rings"], small["rings"], strict=True):
        lo, hi = ring["theta_deg"]
        expected = [
            ring["model_1536"],
            ring["model_512"],
            *(ring["served"][d] for d in ("native", "paper_1536", "paper_512")),
            *(other["served"][d] for d in ("native", "paper_1536", "paper_512")),
        ]
        assert rows[f"{lo:g}-{hi:g}"] == [f"{v:.3f}" for v in expected], f"ring {lo:g}-{hi:g}"
