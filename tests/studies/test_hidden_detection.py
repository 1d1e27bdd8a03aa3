"""Hidden-point detection's pairwise comparisons: one family for every correction, and the committed restatement
of ``hidden_detection_1536.json`` is what its per-flight scores give."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from airfisheye_bench.studies import hidden_detection
from airfisheye_bench.studies.generated_blocks import block_in

ROOT = Path(__file__).resolve().parents[2]
FIGURES = ROOT / "docs" / "figures"
SOURCE = FIGURES / "occlusion_ablation" / "hidden_detection_1536.json"
RESTATED = FIGURES / "occlusion_ablation" / "hidden_detection_1536_paired.json"


def _scores(f1: list[float | None]) -> dict[str, dict[str, float | None]]:
    return {f"town/traj{i:02d}": {"f1": v} for i, v in enumerate(f1)}


def test_one_family_for_holm_bonferroni_and_the_detectable_effect() -> None:
    per_flight = {
        "a": _scores([0.5, 0.6, 0.7, 0.65]),
        "b": _scores([0.4, 0.55, 0.6, 0.5]),
        "c": _scores([0.45, 0.5, 0.72, 0.6]),
        "none": _scores([None] * 4),  # removes nothing: no F1, in no pair
    }
    paired = hidden_detection.paired_f1(per_flight)
    assert list(paired) == ["a - b", "a - c", "b - c"]
    assert {d["family_size"] for d in paired.values()} == {3}
    alone, family = paired["a - b"]["mde"], paired["a - b"]["mde_family"]
    assert 0 < alone < family  # the family's level asks for a larger effect
    lo, hi = paired["a - b"]["ci"]
    flo, fhi = paired["a - b"]["ci_family"]
    assert flo < lo and fhi > hi  # Bonferroni over the same 3
    smallest = min(paired.values(), key=lambda d: d["p"])
    assert smallest["p_holm"] == pytest.approx(
        min(1.0, 3 * smallest["p"])
    )  # Holm's first step: the family's 3


def test_the_committed_restatement_is_what_the_records_per_flight_scores_give() -> None:
    source = json.loads(SOURCE.read_text(encoding="utf-8"))
    restated = json.loads(RESTATED.read_text(encoding="utf-8"))
    assert restated["source"] == {
        "file": "docs/figures/occlusion_ablation/hidden_detection_1536.json",
        "commit": source["provenance"]["commit"],
    }
    assert restated["provenance"]["dataset"] == source["provenance"]["dataset"]
    expected = hidden_detection.restate(source)
    assert list(restated["paired_f1"]) == list(expected)
    for size, pairs in expected.items():
        assert list(restated["paired_f1"][size]) == list(pairs)
        for pair, d in pairs.items():
            shown = restated["paired_f1"][size][pair]
            assert shown["family_size"] == len(pairs)
            for key in ("mean", "p", "p_holm", "mde", "mde_family"):
                assert math.isclose(shown[key], d[key], rel_tol=1e-9), (size, pair, key)
            # The restatement changes only what the family's size decides: the record's own means and Holm p.
            old = source["results"][size]["hidden_detection"]["paired_f1"][pair]
            assert math.isclose(shown["mean"], old["mean"], rel_tol=1e-12)
            assert math.isclose(shown["p_holm"], old["p_holm"], rel_tol=1e-9)


def test_the_report_shows_the_committed_restatement() -> None:
    report = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    restated = json.loads(RESTATED.read_text(encoding="utf-8"))
    expected = hidden_detection.paired_report(restated, RESTATED.relative_to(FIGURES).as_posix())
    shown = block_in(report, hidden_detection.REPORT_BEGIN, hidden_detection.REPORT_END)
    assert shown == expected, f"regenerate: {restated['provenance']['command']}"
