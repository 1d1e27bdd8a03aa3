"""Test-time cross-over on ``tiny`` with a freshly initialised tiny NLSPN: one model, every sparse input."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import torch

from airfisheye_bench.evaluation.predictors import CheckpointPredictor
from airfisheye_bench.geometry.occlusion import ORACLE, SPARSE_INPUTS
from airfisheye_bench.metrics import CompletionMetrics
from airfisheye_bench.studies.crossover import (
    CROSSOVER_ARMS,
    arm_datasets,
    arm_datasets_from_config,
    crossover,
    crossover_table,
    difference_table,
    frame_scores,
    input_differences,
    paired_frames_table,
    spread_frames,
    window_radius_share,
)
from airfisheye_bench.tasks import CompletionTask
from datamodules.dataset import collate
from tests.helpers.configs import compose_train
from tests.helpers.models import TINY

SIZE = 32


@pytest.fixture(scope="module")
def datasets(tiny_dataset: Path):
    # tiny's val location has hidden points in view (test_oracle_input)
    return arm_datasets(tiny_dataset, "val", source="cubemap", size=SIZE)


@pytest.fixture(scope="module")
def predictor() -> CheckpointPredictor:
    torch.manual_seed(0)
    return CheckpointPredictor(CompletionTask({"name": "nlspn", **TINY["nlspn"]}))


def test_every_input_scores_the_same_model_on_the_same_frames(datasets, predictor) -> None:
    result = crossover(predictor, datasets, radius=1, near_m=30.0, batch_size=1)
    assert list(CROSSOVER_ARMS) == ["none", *(a for a in SPARSE_INPUTS if a != "none")]
    assert set(result["arms"]) == set(CROSSOVER_ARMS) and result["frames"] == len(datasets["none"])

    # The whole-image row of each arm is the task metric of that arm's own evaluation, computed independently.
    for arm, ds in datasets.items():
        plain = CompletionMetrics()
        for index in range(len(ds)):
            batch = collate([ds[index]])
            plain.update(predictor(batch), batch["depth"], batch["valid_mask"])
        assert result["arms"][arm]["all"]["rmse"] == pytest.approx(float(plain.compute()["rmse"]), rel=1e-6)

    diff = result["input_difference"]
    assert diff["none"]["differing"] == 0
    assert diff[ORACLE]["differing"] == result["affected"]["differing_px"] > 0
    affected = result["arms"]["none"]["affected"]
    assert 0 < affected["pixels"] <= result["affected"]["dilated_px"] <= result["affected"]["valid_px"]
    for arm in CROSSOVER_ARMS:  # one set of regions for every arm: defined by none and oracle, not by the arm
        for region in ("all", "affected", "near"):
            assert result["arms"][arm][region]["pixels"] == result["arms"]["none"][region]["pixels"]
        assert 0.0 <= diff[arm]["frac_of_sparse"] <= 1.0
    # `none` and `oracle` inputs differ on the affected pixels only: outside them the predictions may still differ
    # (a convolution's reach), but the difference of the inputs there is 0 by construction.
    assert not math.isnan(result["arms"][ORACLE]["affected"]["rmse"])

    # Per-frame pairs: one pair per frame that has pixels of the region; their mean difference is the difference
    # of the two arms' per-image averages over the same frames.
    paired = result["paired_frames"]
    assert "none" not in paired and set(paired) == set(CROSSOVER_ARMS) - {"none"}
    for arm in paired:
        for region in ("all", "affected"):
            d = paired[arm][f"{region}/rmse"]
            assert d["n"] == result["arms"]["none"][region]["images"]
            expected = result["arms"][arm][region]["rmse"] - result["arms"]["none"][region]["rmse"]
            assert d["mean"] == pytest.approx(expected, abs=1e-9)
            assert d["n"] < 2 or d["ci95"][0] <= d["mean"] <= d["ci95"][1]
    assert "| `oracle` |" in paired_frames_table(result)

    table = crossover_table(result)
    assert table.splitlines()[2].startswith("| `none` |") and "(+0.0000)" not in table.splitlines()[2]
    assert "| `oracle` |" in difference_table(result)


def test_input_differences_need_no_model_and_none_and_oracle(datasets) -> None:
    counts = input_differences(datasets, radius=0, frames=1)
    assert counts["frames"] == 1 and counts["arms"] == {}
    assert counts["affected"]["dilated_px"] == counts["affected"]["differing_px"]  # radius 0: no dilation
    with pytest.raises(ValueError, match="oracle"):
        crossover(None, {"none": datasets["none"], "ordering": datasets["ordering"]})
    share = window_radius_share(datasets["zbuffer"])
    assert sum(share.values()) == pytest.approx(1.0)


def test_datasets_from_a_run_config_change_only_the_input(tiny_dataset: Path) -> None:
    cfg = compose_train(
        [
            "task=completion",
            f"data.root={tiny_dataset}",
            "data.occlusion=zbuffer",
            "data.occlusion_options={kernel:3}",
            "data.camera.size=48",
        ]
    )
    arms = ("none", "zbuffer", ORACLE)
    built = arm_datasets_from_config(cfg.data, "val", arms, size=SIZE)
    # a dataset holds an Occlusion, or the oracle's name
    served = {arm: getattr(ds.occlusion, "method", ds.occlusion) for arm, ds in built.items()}
    assert served == {a: a for a in arms}
    assert all(ds.camera.width == SIZE for ds in built.values())
    assert built["zbuffer"].occlusion.options["kernel"] == 3  # the run's options stay with its own method


def test_spread_frames() -> None:
    assert spread_frames(38, 4) == [0, 12, 25, 37]
    assert spread_frames(3, 1) == [0]
    with pytest.raises(ValueError):
        spread_frames(3, 0)


def test_frame_scores_hold_every_arm_s_changes_and_agree_with_the_cross_over(datasets, predictor) -> None:
    rows = frame_scores(predictor, datasets, "ordering", radius=1, near_m=30.0, batch_size=2)
    assert [r["sample_id"] for r in rows] == list(datasets["none"].sample_ids)
    result = crossover(predictor, datasets, radius=1, near_m=30.0, batch_size=1)
    # The whole image and the none-vs-oracle region are the cross-over's, frame by frame (per-image means).
    for region in ("all", "affected", "near"):
        frames = [r["regions"][region]["rmse"] for r in rows if region in r["regions"]]
        assert sum(frames) / len(frames) == pytest.approx(
            result["arms"]["ordering"][region]["rmse"], rel=1e-6
        )
    # The neutral region holds the affected one (the oracle is an arm) and every other arm's changes.
    for row in rows:
        pixels = {region: v["pixels"] for region, v in row["regions"].items()}
        assert pixels.get("changed", 0) >= pixels.get("affected", 0)
        assert pixels["all"] >= pixels.get("changed", 0)

    # With only none and the oracle served, `changed` is `affected`; each arm added can only grow it.
    def changed(arms) -> list[int]:
        subset = {a: datasets[a] for a in arms}
        return [
            r["regions"].get("changed", {}).get("pixels", 0)
            for r in frame_scores(predictor, subset, "none", 1)
        ]

    pair = changed(("none", ORACLE))
    assert pair == [r["regions"].get("affected", {}).get("pixels", 0) for r in rows]
    for arm in CROSSOVER_ARMS:
        grown = changed(dict.fromkeys(("none", ORACLE, arm)))
        assert all(
            p <= g <= c["regions"].get("changed", {}).get("pixels", 0)
            for p, g, c in zip(pair, grown, rows, strict=True)
        )
    with pytest.raises(ValueError, match="not among"):
        frame_scores(predictor, {a: datasets[a] for a in ("none", ORACLE)}, "ordering")
