"""``scripts/occlusion_study.py`` runs end to end on the ``tiny`` dataset (only what holds by construction), and
``scripts/occlusion_ablation.py`` plans, resumes and summarises its training runs."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from PIL import Image

from airfisheye_bench.geometry.occlusion import OCCLUSION_METHODS
from airfisheye_bench.studies import occlusion_ablation, occlusion_study
from airfisheye_bench.studies.generated_blocks import block_in


@pytest.fixture(scope="module")
def study() -> ModuleType:
    return occlusion_study


def test_main_tiny(
    study: ModuleType, tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    figure, out = tmp_path / "overlay.png", tmp_path / "study.json"
    argv = ["--root", str(tiny_dataset), "--frames", "2", "--size", "32", "--figure-scale", "1"]
    payload = study.main([*argv, "--figure", str(figure), "--json", str(out)])

    assert json.loads(out.read_text())["results"].keys() == {"32"}
    assert 1 <= payload["frames"] <= 2
    rows = {name: row["pooled"] for name, row in payload["results"]["32"]["rows"].items()}
    assert set(rows) == {name for name, _, _ in study.variants()} | {study.ORACLE}
    assert {m for _, m, _ in study.variants()} == set(OCCLUSION_METHODS)  # read from the library, not listed
    summary = payload["results"]["32"]
    assert summary["hidden_projected"] == rows["none"]["hidden_kept"]
    assert summary["hidden_fraction"] == pytest.approx(rows["none"]["hidden_kept"] / rows["none"]["kept"])
    none = rows["none"]
    assert none["kept"] > 0
    for name, row in rows.items():
        assert row["truth"] == none["truth"], name  # one ground truth for every row
        for key in ("precision", "recall", "f1"):
            assert 0.0 <= row[key] <= 1.0, (name, key)
        assert row["sparse_wrong"] <= row["sparse_gt"] <= row["sparse_px"]
        assert row["sparse_gt"] + row["sparse_no_gt"] == row["sparse_px"]
    # `none` keeps every projected point: all the visible ones, and the hidden ones too.
    assert none["recall"] == 1.0
    assert none["tp"] == none["truth"] and none["hidden_kept"] == none["kept"] - none["truth"]
    for name in OCCLUSION_METHODS:  # occlusion tests only remove projected points
        assert rows[name]["kept"] <= none["kept"] and rows[name]["hidden_kept"] <= none["hidden_kept"]
        assert rows[name]["truth"] == none["truth"]
    assert rows[study.ORACLE]["precision"] == rows[study.ORACLE]["recall"] == 1.0
    # The per-location breakdown partitions the split: its counts add up to the pooled ones.
    per_location = summary["per_location"]
    assert set(per_location) == {sid.split("/")[0] for sid in summary["sample_ids"]}
    for name, row in rows.items():
        for key in ("kept", "tp", "hidden_kept", "sparse_wrong", "sparse_gt"):
            assert sum(loc[name][key] for loc in per_location.values()) == row[key], (name, key)

    # Hidden points as the positive class, per flight: doing nothing detects none of them.
    detection = summary["hidden_detection"]
    flights = detection["per_flight"]["none"]
    assert (
        detection["flights"] == len({sid.rsplit("/", 1)[0] for sid in summary["sample_ids"]}) == len(flights)
    )
    assert all(s["recall"] == 0.0 for s in flights.values() if not math.isnan(s["recall"]))
    assert set(detection["scores"]) == {name for name, _, _ in study.variants()}
    printed = capsys.readouterr().out
    assert "| 32² | ordering |" in printed and "hidden points = positive" in printed
    size = payload["figure"]["size"]
    width, height = Image.open(figure).size
    panels = len(OCCLUSION_METHODS)  # `none` first, then each other method
    assert width == panels * size + (panels - 1) * 4 and height > size  # gap 4, label strips on top
    assert set(payload["figure"]["panels"]) == set(OCCLUSION_METHODS)


def test_methods_and_options_are_checked(study: ModuleType) -> None:
    assert [row for row, _, _ in study.variants(["zbuffer"])] == ["zbuffer", "none"]
    assert study.parse_options(["zbuffer.kernel=7", "zbuffer.relative=true"]) == {
        "zbuffer": {"kernel": 7, "relative": True}
    }
    with pytest.raises(ValueError, match="unknown"):
        study.variants(["nope"])
    with pytest.raises(ValueError, match=r"METHOD\.NAME=VALUE"):
        study.parse_options(["kernel=7"])


def test_options_reach_the_method(study: ModuleType, tiny_dataset: Path) -> None:
    """A z-buffer margin beyond any range keeps every projected point: the option was passed through."""
    frame = study.load_frame(study.make_datasets(tiny_dataset, "test", "cubemap", 32, 120.0), 0)
    ds = study.make_datasets(tiny_dataset, "test", "cubemap", 32, 120.0)[True]
    gt = ds[0]["depth"][0].numpy()
    valid = ds.valid_mask.numpy()
    rows = study.variants(["zbuffer"])
    loose = study.measure_frame(frame, ds.camera, gt, valid, 120.0, rows, {"zbuffer": {"threshold": 1e6}})
    assert loose["zbuffer"]["kept"] == loose["none"]["kept"] > 0


def test_sparse_map_is_the_served_input(study: ModuleType, tiny_dataset: Path) -> None:
    from datamodules.dataset import AirFisheyeDataset, CameraConfig

    served = AirFisheyeDataset.from_root(tiny_dataset, "test", "completion", camera=CameraConfig(size=32))
    frame = study.load_frame(study.make_datasets(tiny_dataset, "test", "cubemap", 32, 120.0), 0)
    ours = study.sparse_map(
        frame.points, frame.T[True], served.camera, frame.spec, "ordering", 120.0, served.valid_mask.numpy()
    )
    np.testing.assert_array_equal(ours, served[0]["sparse_depth"][0].numpy())


# ------------------------------------------------------------------------------------------------ ablation
@pytest.fixture(scope="module")
def ablation() -> ModuleType:
    return occlusion_ablation


def _fake_train(metrics_of: dict[tuple[str, int], float], calls: list[list[str]]):
    """A stand-in for ``train.py``: records the command and writes a results.json with a made-up RMSE."""

    def run(argv: list[str]) -> None:
        calls.append(argv)
        args = dict(a.split("=", 1) for a in argv[2:])
        out = Path(args["hydra.run.dir"])
        out.mkdir(parents=True)
        rmse = metrics_of[(args["data.occlusion"], int(args["seed"]))]
        (out / "results.json").write_text(json.dumps({"metrics": {"rmse": rmse, "mae": rmse / 2}}))

    return run


def _fake_regions(affected_of: dict[tuple[str, int], float], calls: list[Path]):
    """A stand-in for ``run_region_scores``: a made-up affected-pixel RMSE per run."""

    def score(out: Path) -> dict:
        calls.append(out)
        method, seed = out.parent.name, int(out.name.removeprefix("seed"))
        rmse = affected_of[(method, seed)]
        return {
            "arm": method,
            "regions": {"all": {"rmse": 0.0}, "affected": {"rmse": rmse}, "near": {"rmse": None}},
        }

    return score


def test_ablation_trains_each_method_and_seed_once_and_summarises(
    ablation: ModuleType, tmp_path: Path
) -> None:
    values = {
        ("none", 0): 5.0,
        ("none", 1): 6.0,
        ("none", 2): 7.0,
        ("ordering", 0): 4.0,
        ("ordering", 1): 4.5,
    }
    calls: list[list[str]] = []
    argv = ["--out", str(tmp_path), "--methods", "none,ordering", "--seeds", "0", "1", "2"]
    values[("ordering", 2)] = 5.0
    out = tmp_path / "summary.json"
    affected = {key: 2 * value for key, value in values.items()}
    scored: list[Path] = []
    payload = ablation.main(
        [*argv, "--json", str(out), "--", "trainer=debug"],
        runner=_fake_train(values, calls),
        scorer=_fake_regions(affected, scored),
    )

    assert len(calls) == 6 and len(scored) == 6
    for call in calls:
        assert "task=completion" in call and "trainer=debug" in call
        assert call.index("trainer.deterministic=true") < call.index(
            "trainer=debug"
        )  # the caller's come last
    none = payload["results"]["none"]["metrics"]["rmse"]
    assert none["mean"] == pytest.approx(6.0) and none["std"] == pytest.approx(1.0) and none["n"] == 3
    assert payload["results"]["ordering"]["metrics"]["mae"]["mean"] == pytest.approx(13.5 / 6)
    assert json.loads(out.read_text())["results"].keys() == {"none", "ordering"}

    # Paired against none, seed by seed: ordering - none = -1, -1.5, -2 -> mean -1.5, s = 0.5,
    # half-width t(0.975, 2) * 0.5 / sqrt(3) = 4.303 * 0.288675 = 1.242169.
    rmse = payload["paired_vs_none"]["ordering"]["rmse"]
    assert rmse["seeds"] == [0, 1, 2] and rmse["diffs"] == pytest.approx([-1.0, -1.5, -2.0])
    assert rmse["mean"] == pytest.approx(-1.5) and rmse["std"] == pytest.approx(0.5)
    assert rmse["ci95"] == pytest.approx([-1.5 - 1.242169, -1.5 + 1.242169], abs=1e-6)
    assert payload["paired_vs_none"]["ordering"]["affected/rmse"]["mean"] == pytest.approx(-3.0)
    assert "near/rmse" not in payload["paired_vs_none"]["ordering"]  # null values are left out
    assert payload["results"]["none"]["metrics"]["affected/rmse"]["mean"] == pytest.approx(12.0)

    calls.clear()  # a second call resumes: nothing left to train or score, same summary
    scored.clear()
    again = ablation.main(argv, runner=_fake_train(values, calls), scorer=_fake_regions(affected, scored))
    assert calls == [] and scored == [] and again["results"] == payload["results"]


def test_ablation_rejects_unknown_methods(ablation: ModuleType, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="unknown"):
        ablation.plan(tmp_path, ["nope"], [0])


def _fake_train_with_curve(rmse_of: dict[tuple[str, int], float]):
    """``train.py``'s stand-in for the recorded ablation: results.json and a validation curve."""

    def run(argv: list[str]) -> None:
        args = dict(a.split("=", 1) for a in argv[2:])
        out = Path(args["hydra.run.dir"])
        out.mkdir(parents=True)
        rmse = rmse_of[(args["data.occlusion"], int(args["seed"]))]
        (out / "results.json").write_text(
            json.dumps(
                {"primary_metric": "rmse", "metrics": {"rmse": rmse}, "dataset": {"content_sha256": "c0"}}
            )
        )
        (out / "metrics.csv").write_text("epoch,val/rmse,train/loss\n0,9.0,\n0,,3.0\n1,8.5,\n")

    return run


def _fake_frames(offset_of: dict[tuple[str, int], float]):
    """Per-frame scores: frame k of flight f has RMSE 10 + f + offset (the arm and seed's), 3 frames a flight."""

    def score(out: Path) -> dict:
        method, seed = out.parent.name, int(out.name.removeprefix("seed"))
        rows = []
        for f in range(4):
            for k in range(3):
                value = 10.0 + f + offset_of[(method, seed)] + (0.1 * k if method == "ordering" else 0.0)
                regions = {
                    r: {"rmse": value, "mae": value / 2, "abs_rel": 0.1, "pixels": 5}
                    for r in ("all", "changed")
                }
                rows.append({"sample_id": f"town/traj{f:02d}/{k:06d}", "regions": regions})
        return {"arm": method, "checkpoint": str(out / "checkpoints" / "epoch_001.ckpt"), "frames": rows}

    return score


def test_recorded_ablation_writes_one_record_a_run_and_summarises_by_flight(
    ablation: ModuleType, tmp_path: Path
) -> None:
    offsets = {("none", 0): 0.0, ("none", 1): 0.4, ("ordering", 0): -1.0, ("ordering", 1): -0.2}
    record = tmp_path / "records"
    argv = ["--out", str(tmp_path / "runs"), "--methods", "none,ordering", "--seeds", "0", "1"]
    argv += ["--record", str(record), "--allow-dirty", "--json", str(tmp_path / "summary.json")]
    payload = ablation.main(
        argv, runner=_fake_train_with_curve({k: 5.0 for k in offsets}), frame_scorer=_fake_frames(offsets)
    )

    assert sorted(p.name for p in record.iterdir()) == [
        f"{m}_seed{s}.json" for m in ("none", "ordering") for s in (0, 1)
    ]
    one = json.loads((record / "ordering_seed1.json").read_text())
    assert one["provenance"]["command"].startswith(
        "python train.py task=completion data.occlusion=ordering seed=1"
    )
    assert one["epochs_trained"] == 2 and [c["val/rmse"] for c in one["validation_curve"]] == [9.0, 8.5]
    assert one["dataset"] == {"content_sha256": "c0"} and one["checkpoint"] == "epoch_001.ckpt"

    # ordering - none per frame: seed 0: -1 + 0.1 k, seed 1: -0.6 + 0.1 k -> per flight (k = 0..2, both seeds):
    # -0.7 in every flight: n = 4 flights (not 12 frames, not 2 seeds), zero spread.
    d = payload["paired"]["ordering"]["all/rmse"]
    assert d["n"] == 4 and d["per_flight"] == pytest.approx({f"town/traj{f:02d}": -0.7 for f in range(4)})
    assert d["per_seed"] == pytest.approx([-0.9, -0.5]) and d["seed_spread"]["std"] == pytest.approx(
        0.2828427
    )
    assert payload["family_size"] == len(payload["paired"]["ordering"])
    assert all("p_holm" in e for e in payload["paired"]["ordering"].values())
    assert json.loads((tmp_path / "summary.json").read_text())["records"][0] == "none_seed0.json"
    # Each run's training and cost, one row per record.
    assert [(r["method"], r["seed"], r["best_epoch"], r["val_best"]) for r in payload["runs"]] == [
        (m, s, 2, 8.5) for m in ("none", "ordering") for s in (0, 1)
    ]
    table = ablation.ablation_records.runs_table(payload["runs"])
    assert table.count("\n| `") == 4 and "9.00, 8.50 (2), 8.50" in table

    # The records alone are the study: the run folders can go.
    import shutil

    shutil.rmtree(tmp_path / "runs")
    again = ablation.main(
        [
            "--out",
            str(tmp_path / "runs"),
            "--methods",
            "none,ordering",
            "--record",
            str(record),
            "--collect-only",
        ]
    )
    assert again["paired"]["ordering"]["all/rmse"]["mean"] == pytest.approx(-0.7)

    # --report rewrites the report's generated block, and only that, with a link relative to the report.
    records = ablation.ablation_records
    docs = tmp_path / "docs"
    docs.mkdir()
    report = docs / "results.md"
    report.write_text(f"# Results\nbefore\n{records.REPORT_BEGIN}\nold\n{records.REPORT_END}\nafter\n")
    collect = ["--out", str(tmp_path / "runs"), "--record", str(record), "--collect-only"]
    collect += ["--json", str(tmp_path / "summary.json"), "--report", str(report)]
    written = ablation.main(collect)
    text = report.read_text()
    assert text.startswith("# Results\nbefore\n") and text.endswith(f"{records.REPORT_END}\nafter\n")
    block = block_in(text, records.REPORT_BEGIN, records.REPORT_END)
    assert block == records.report_block(written, "../summary.json")
    assert "| `ordering` | RMSE, whole image | 0,1 | \u22120.700 |" in block  # the typographic minus

    # A report without the markers is refused, named, and left as it was.
    report.write_text("no block here\n")
    with pytest.raises(SystemExit, match=r"--report .*results.md: no generated block"):
        ablation.main(collect)
    assert report.read_text() == "no block here\n"


def test_a_recorded_run_refuses_uncommitted_code(
    ablation: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(ablation, "git_commit", lambda repo: "0123abc+dirty")
    argv = ["--out", str(tmp_path), "--methods", "none", "--seeds", "0", "--record", str(tmp_path / "r")]
    with pytest.raises(SystemExit, match="uncommitted changes"):
        ablation.main(argv, runner=lambda argv: None)
    assert not (tmp_path / "none").exists()


def test_hidden_detection_pools_counts_per_flight_and_compares_methods_pairwise() -> None:
    from airfisheye_bench.studies.hidden_detection import hidden_detection

    # Two frames per flight: counts pool within the flight before the scores (not a mean of frame ratios).
    frame = {"a": {"tp": 3, "fp": 1, "fn": 0}, "b": {"tp": 1, "fp": 0, "fn": 3}}
    by_flight = {
        f"town/traj{f:02d}": {m: [c, {"tp": 1, "fp": 1, "fn": 1}] for m, c in frame.items()} for f in range(3)
    }
    result = hidden_detection(by_flight, ["a", "b"])
    a = result["per_flight"]["a"]["town/traj00"]  # pooled tp 4, fp 2, fn 1
    assert a["precision"] == pytest.approx(4 / 6) and a["recall"] == pytest.approx(4 / 5)
    assert result["scores"]["a"]["f1"]["n"] == 3 and result["flights"] == 3
    d = result["paired_f1"]["a - b"]  # the same gap in every flight: no spread, p = 0
    assert d["n"] == 3 and d["mean"] == pytest.approx(16 / 22 - 4 / 9)  # b: precision 2/3, recall 2/6
    assert d["p_holm"] == 0.0


def test_a_killed_run_is_resumed_exactly_and_its_segments_recorded(
    ablation: ModuleType, tmp_path: Path
) -> None:
    calls: list[list[str]] = []

    def train(argv: list[str]) -> None:
        calls.append(argv)
        args = dict(a.split("=", 1) for a in argv[2:])
        out = Path(args["hydra.run.dir"])
        if "ckpt_path" not in args:  # the first segment is killed after its first checkpoint
            (out / "checkpoints").mkdir(parents=True)
            (out / "checkpoints" / "last.ckpt").write_text("weights")
            raise KeyboardInterrupt
        (out / "results.json").write_text(json.dumps({"metrics": {"rmse": 5.0}}))

    argv = ["--out", str(tmp_path), "--methods", "none", "--seeds", "0", "--no-regions"]
    with pytest.raises(KeyboardInterrupt):
        ablation.main(argv, runner=train)
    ablation.main(argv, runner=train)
    assert calls[1][2:] == ["ckpt_path=last", f"hydra.run.dir={tmp_path / 'none' / 'seed0'}"]
    record = json.loads((tmp_path / "none" / "seed0" / "provenance.json").read_text())
    assert len(record["segments"]) == 2 and record["segments"][0]["wall_s"] is None
    assert record["wall_s"] is None  # the killed segment's time is unknown, not 0
    assert record["command"].startswith("python train.py task=completion data.occlusion=none seed=0")
