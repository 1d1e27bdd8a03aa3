"""``airfisheye-evaluate lenses=[...] robustness=true``: one model scored on many lenses of the same frames."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation.command import evaluate
from airfisheye_bench.evaluation.cross_lens import (
    cross_lens_gap,
    largest_changes,
    parse_test_lenses,
    robustness_lenses,
)
from airfisheye_bench.geometry import ideal_camera
from airfisheye_bench.geometry.cameras import KannalaBrandt
from tests.helpers import calibration_fixtures as fx
from tests.helpers.configs import compose_eval


def test_lens_specs_parse_with_names_and_refuse_mistakes_in_one_line() -> None:
    lenses = parse_test_lenses(
        [
            "trained",
            {"model": "equisolid", "fov_deg": 180},
            {"calibration": "/x/tumvi_ds.yaml", "camera": "cam0"},
            {"name": "wide", "model": "equidistant", "fov_deg": 200, "perturb": {"principal_point_px": 1}},
        ]
    )
    assert [lens.name for lens in lenses] == ["trained", "equisolid 180°", "tumvi_ds (cam0)", "wide"]
    assert lenses[0].trained and not lenses[3].trained
    assert lenses[3].perturb.shift == (1.0, 1.0)
    assert lenses[3].spec()["perturb"] == {"focal": 1.0, "principal_point_px": [1.0, 1.0], "distortion": []}
    bad = {
        "not a list": ("equisolid", "lenses: expected a non-empty list"),
        "unknown key": ([{"model": "equisolid", "fov": 180}], "lenses[0]: unknown key 'fov'"),
        "both": (
            [{"calibration": "a.yaml", "model": "equisolid"}],
            "lenses[0]: a calibration gives the lens",
        ),
        "focal": ([{"perturb": {"focal": -1}}], "lenses[0].perturb.focal=-1"),
        "twice": (["trained", "trained"], "lenses[1]: the name 'trained' is taken by lenses[0]"),
    }
    for value, expected in bad.values():
        with pytest.raises(ValueError) as err:
            parse_test_lenses(value)
        assert str(err.value).startswith(expected) and "\n" not in str(err.value)


def test_the_robustness_row_is_one_lens_across_units() -> None:
    ideal = robustness_lenses(ideal_camera(128, 128, fov_deg=190.0))
    assert [lens.perturb.focal for lens in ideal[:2]] == [0.98, 1.02]
    assert [lens.perturb.shift for lens in ideal[2:]] == [
        (-1.28, 0.0),
        (1.28, 0.0),
        (0.0, -1.28),
        (0.0, 1.28),
    ]
    kb = KannalaBrandt(64, 64, 20.0, 20.0, 31.5, 31.5, k1=0.1, k2=0.01)
    with_distortion = robustness_lenses(kb)
    assert len(with_distortion) == 8 and [lens.perturb.distortion for lens in with_distortion[6:]] == [
        (0.95,),
        (1.05,),
    ]
    perturbed = with_distortion[7].perturb.apply(kb)
    assert perturbed.k1 == pytest.approx(0.105) and perturbed.k2 == kb.k2 and perturbed.fx == kb.fx


def test_gap_and_largest_change_follow_each_metrics_direction() -> None:
    assert cross_lens_gap(0.5, 0.4, higher_is_better=True) == pytest.approx(0.2)
    assert cross_lens_gap(10.0, 12.0, higher_is_better=False) == pytest.approx(0.2)
    assert cross_lens_gap(10.0, 9.0, higher_is_better=False) == pytest.approx(-0.1)
    assert math.isnan(cross_lens_gap(0.0, 1.0, higher_is_better=True))
    assert largest_changes(
        {"a": 1.0, "b": 2.0}, [{"a": 1.5, "b": 2.0}, {"a": 0.8, "b": 1.9}]
    ) == pytest.approx({"a": 0.5, "b": 0.1})


def _evaluate(run: Path, out: Path, *overrides: str) -> dict:
    return evaluate(compose_eval([f"ckpt_path={run}", "num_workers=0", "num_panels=0", *overrides], out))


@pytest.mark.integration
def test_a_checkpoint_scored_on_a_list_of_lenses_writes_the_matrix(tiny_runs, tmp_path: Path) -> None:
    run = tiny_runs("depth")
    own = json.loads((run / "results.json").read_text())
    out = tmp_path / "eval"
    record = _evaluate(run, out, "lenses=[trained,{model:equisolid,fov_deg:180}]")
    cross = record["cross_lens"]
    assert json.loads((out / "results.json").read_text())["cross_lens"] == cross
    assert [row["name"] for row in cross["lenses"]] == ["trained", "equisolid 180°"]
    trained, equisolid = cross["lenses"]
    # The trained lens is the plain evaluation, and the run's own test score: the same frames, the same model.
    assert trained["metrics"] == record["metrics"]
    assert trained["metrics"]["rmse"] == pytest.approx(own["metrics"]["rmse"], abs=1e-4)
    assert trained["seen"] and not equisolid["seen"]
    assert trained["gap"]["rmse"] == 0.0
    assert equisolid["gap"]["rmse"] == pytest.approx(
        equisolid["metrics"]["rmse"] / trained["metrics"]["rmse"] - 1
    )
    assert equisolid["gap"]["delta1"] == pytest.approx(
        1 - equisolid["metrics"]["delta1"] / trained["metrics"]["delta1"]
    )
    assert equisolid["camera"]["model"] == "equisolid" and equisolid["num_frames"] == trained["num_frames"]
    # A lens changes what the model sees, so its score; the flights are the test split's trajectories.
    assert equisolid["metrics"]["rmse"] != trained["metrics"]["rmse"]
    assert set(trained["flights"]) == set(equisolid["flights"]) and len(trained["flights"]) >= 1
    assert cross["trained_lenses"] == [record["config"]["camera"]] and "robustness" not in cross


@pytest.mark.slow
def test_a_calibration_file_and_the_robustness_row(tiny_runs, tmp_path: Path) -> None:
    run = tiny_runs("depth")
    ds = fx.write_basalt(tmp_path / "ds.json", fx.TUMVI_DS, "ds")
    record = _evaluate(run, tmp_path / "eval", f"lenses=[{{calibration:'{ds}',camera:0}}]", "robustness=true")
    cross = record["cross_lens"]
    assert [row["name"] for row in cross["lenses"]] == ["trained", "ds (0)"]
    trained, double_sphere = cross["lenses"]
    assert double_sphere["camera"]["model"] == "double_sphere" and not double_sphere["seen"]
    robustness = cross["robustness"]
    assert robustness["metrics"] == trained["metrics"] and len(robustness["perturbations"]) == 6
    changes = [abs(p["metrics"]["rmse"] - trained["metrics"]["rmse"]) for p in robustness["perturbations"]]
    assert robustness["largest_change"]["rmse"] == pytest.approx(max(changes)) and max(changes) > 0


@pytest.mark.integration
def test_lenses_need_a_model_and_a_list(tiny_runs, tmp_path: Path) -> None:
    run = tiny_runs("depth")
    with pytest.raises(ConfigError, match="lenses: expected a non-empty list"):
        evaluate(compose_eval([f"ckpt_path={run}", "lenses=equisolid"], tmp_path))
    with pytest.raises(ConfigError, match="need ckpt_path= or onnx_path="):
        evaluate(compose_eval(["task=depth", f"predictions={tmp_path}", "lenses=[trained]"], tmp_path))
