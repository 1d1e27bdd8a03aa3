"""The lens study's arm comparisons (:mod:`airfisheye_bench.studies.lens_contrasts`): paired seeds, flights as the
unit, one family per task."""

from __future__ import annotations

import math

import pytest

from airfisheye_bench.studies.lens_contrasts import (
    arm_contrasts,
    contrast_lines,
    robustness_changes,
    robustness_lines,
)

FLIGHTS = ("f0", "f1", "f2", "f3")


def _run(arm: str, seed: int, scores: dict[str, list[float]], task: str = "depth") -> dict:
    """A record with one score per flight on each lens."""
    lenses = [
        {"name": name, "flights": {f: {"delta1": v} for f, v in zip(FLIGHTS, values, strict=True)}}
        for name, values in scores.items()
    ]
    return {"arm": arm, "task": task, "seed": seed, "cross_lens": {"lenses": lenses}}


def test_a_contrast_pairs_the_seeds_both_arms_have_and_averages_them_per_flight() -> None:
    records = [
        _run("a", 0, {"x": [0.5, 0.6, 0.4, 0.5]}),
        _run("a", 1, {"x": [0.7, 0.6, 0.6, 0.5]}),
        _run("b", 0, {"x": [0.7, 0.7, 0.6, 0.6]}),
        _run("b", 1, {"x": [0.7, 0.8, 0.6, 0.6]}),
        _run("b", 2, {"x": [0.0, 0.0, 0.0, 0.0]}),  # a has no seed 2: left out
    ]
    out = arm_contrasts(records, {"depth": "delta1"})["depth"]
    contrast = out["contrasts"]["b − a"]
    assert contrast["seeds"] == [0, 1] and out["family"] == 1
    # per flight: b's seed mean − a's seed mean = 0.1, 0.15, 0.1, 0.1
    cell = contrast["lenses"]["x"]
    assert cell["n"] == 4 and cell["mean"] == pytest.approx(0.1125)
    assert cell["clusters"] == list(FLIGHTS)


def test_the_family_is_every_comparison_and_lens_of_a_task_and_trained_is_not_a_lens() -> None:
    lenses = {"trained": [0.5] * 4, "x": [0.5, 0.6, 0.4, 0.5], "y": [0.3, 0.4, 0.2, 0.3]}
    records = [_run(arm, 0, lenses) for arm in "abc"] + [_run("a", 0, {"x": [0.2] * 4}, task="seg")]
    out = arm_contrasts(records, {"depth": "delta1", "seg": "mIoU"})
    assert list(out) == ["depth"]  # seg has arm a alone: nothing to compare
    assert list(out["depth"]["contrasts"]) == ["b − a", "c − b"]  # no arm d
    assert out["depth"]["family"] == 4
    assert set(out["depth"]["contrasts"]["b − a"]["lenses"]) == {"x", "y"}
    assert out["depth"]["contrasts"]["b − a"]["lenses"]["x"]["mean"] == 0.0


def test_the_table_states_an_interval_holding_zero_with_its_detectable_difference() -> None:
    records = [
        _run("a", 0, {"x": [0.5, 0.6, 0.4, 0.5], "y": [0.5, 0.5, 0.5, 0.5]}),
        _run("b", 0, {"x": [0.6, 0.7, 0.5, 0.62], "y": [0.52, 0.47, 0.53, 0.49]}),
    ]
    contrasts = arm_contrasts(records, {"depth": "delta1"})
    lines = contrast_lines(contrasts, {"delta1": "δ1"}, "summary.json")
    assert lines[1].startswith("**depth, arms compared: difference of δ1**") and "2 comparisons" in lines[1]
    (row,) = [line for line in lines if line.startswith("| b − a |")]
    x, y = row.split(" | ")[2:4]
    assert x.startswith("+0.105 [") and "mde" not in x  # detected
    y_cell = contrasts["depth"]["contrasts"]["b − a"]["lenses"]["y"]
    low, high = y_cell["ci_family"]
    assert low < 0 < high and math.isfinite(y_cell["mde_family"])
    assert y.rstrip(" |").endswith(f"· mde {y_cell['mde_family']:.3f}")


def _robust(arm: str, seed: int, reference: list[float], shifted: dict[str, list[float]]) -> dict:
    """A record whose robustness row has the ``reference`` score per flight and one row per perturbation."""
    flights = lambda values: {f: {"delta1": v} for f, v in zip(FLIGHTS, values, strict=True)}  # noqa: E731
    return {
        "arm": arm,
        "task": "depth",
        "seed": seed,
        "cross_lens": {
            "lenses": [],
            "robustness": {
                "flights": flights(reference),
                "perturbations": [
                    {"name": f"trained ({n})", "flights": flights(v)} for n, v in shifted.items()
                ],
            },
        },
    }


def test_a_robustness_change_is_per_flight_over_the_seeds_with_every_arm_and_perturbation_in_its_family() -> (
    None
):
    ref = [0.5, 0.6, 0.4, 0.5]
    unscored = {"arm": "c", "task": "depth", "seed": 0, "cross_lens": {"lenses": []}}  # not in the table
    records = [
        _robust("a", 0, ref, {"up": [0.4, 0.5, 0.3, 0.4], "down": ref}),
        # Seed 1 does not move, so the mean over the seeds is half of seed 0's change.
        _robust("a", 1, ref, {"up": [0.5, 0.6, 0.4, 0.5], "down": ref}),
        _robust("b", 0, ref, {"up": ref}),
        unscored,
    ]
    out = robustness_changes(records, {"depth": "delta1"})["depth"]
    assert out["family"] == 3 and list(out["arms"]) == ["a", "b"] and out["arms"]["a"]["seeds"] == [0, 1]
    up = out["arms"]["a"]["perturbations"]["trained (up)"]
    assert up["n"] == 4 and up["mean"] == pytest.approx(-0.05) and up["std"] == pytest.approx(0.0)
    table = robustness_lines({"depth": out}, {"delta1": "δ1"}, {"a": "one lens"}, "summary.json")
    assert "| arm | seeds | up | down |" in table and "Bonferroni-corrected over the 3 cells" in table[1]
    row = next(line for line in table if line.startswith("| a: one lens | 0, 1 |"))
    assert row.split(" | ")[2] == "-0.050 [-0.050, -0.050]" and "mde" in row.split(" | ")[3]
    largest = robustness_lines({"depth": out}, {}, {}, "s", largest={"depth": {"a": "0.050 ± 0.071"}})
    assert "| arm | seeds | up | down | largest change |" in largest
    assert largest[-2].endswith("| 0.050 ± 0.071 |") and largest[-1].endswith("| – |")  # b: none given
