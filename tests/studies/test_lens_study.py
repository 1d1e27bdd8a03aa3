"""The lens study's plan and summary: paired seeds, the commands each run records, gaps grouped by flight."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from airfisheye_bench.evaluation.cross_lens import parse_test_lenses
from airfisheye_bench.studies.generated_blocks import block_in, replace_block
from airfisheye_bench.studies.lens_study import (
    ARMS,
    RECORD_FORMAT,
    REPORT_BEGIN,
    REPORT_END,
    TEST_LENSES,
    TRAIN_LENSES,
    plan,
    report_block,
    summarise,
    train,
    upgrade_record,
)
from airfisheye_bench.studies.provenance import REPO
from airfisheye_bench.studies.segments import train_in_segments


def test_plan_pairs_seeds_and_each_arm_trains_and_scores_as_documented(tmp_path: Path) -> None:
    runs = plan(tmp_path, ["a", "c"], ["depth"], [0, 1])
    assert [(r.arm, r.seed) for r in runs] == [("a", 0), ("c", 0), ("a", 1), ("c", 1)]
    c = runs[1]
    assert c.name == "c_depth_seed0" and c.run_dir == tmp_path / "c" / "depth" / "seed0"
    argv = c.train_argv()
    assert argv[1:4] == ["train.py", "task=depth", "seed=0"] and "model.camera_input=rays" in argv
    assert any(a.startswith("data.camera.lenses=[{model:equidistant,fov_deg:190}") for a in argv)
    evaluate = c.evaluate_argv()
    assert "robustness=true" in evaluate and evaluate[-1] == f"out={c.run_dir / 'lenses'}"
    assert "views=cube" in plan(tmp_path, ["d"], ["seg"], [0])[0].evaluate_argv()
    with pytest.raises(ValueError, match="unknown arm 'e'"):
        plan(tmp_path, ["e"], ["seg"], [0])


def test_a_training_cut_by_a_sessions_end_is_resumed_and_its_segments_recorded(
    tmp_path: Path, monkeypatch
) -> None:
    run = plan(tmp_path, ["d"], ["depth"], [1])[0]
    calls: list[list[str]] = []

    def fake_run(argv: list[str], **kwargs) -> subprocess.CompletedProcess:
        calls.append(argv)
        if "ckpt_path=last" not in argv:  # the first segment is killed after its first checkpoint
            (run.run_dir / "checkpoints").mkdir(parents=True)
            (run.run_dir / "checkpoints" / "last.ckpt").write_text("weights")
            raise KeyboardInterrupt
        return subprocess.CompletedProcess(argv, 0)

    monkeypatch.setattr("airfisheye_bench.studies.lens_study.subprocess.run", fake_run)
    monkeypatch.setattr("airfisheye_bench.studies.lens_study.git_commit", lambda repo: "c0ffee")
    with pytest.raises(KeyboardInterrupt):
        train(run)
    assert not run.trained.exists()  # a cut training leaves no record, only its segment
    train(run)
    assert calls[1][2:] == ["ckpt_path=last", f"hydra.run.dir={run.run_dir}"]
    record = json.loads(run.trained.read_text())
    assert record["rc"] == 0 and record["commit"] == "c0ffee"
    # The record names the run's command, not the resume's.
    assert record["command"][:4] == ["python", "train.py", "task=depth", "seed=1"]
    assert [s["wall_s"] is None for s in record["segments"]] == [True, False]
    assert record["wall_s"] is None  # the cut segment's time is unknown, not 0


def test_a_run_cut_before_its_segments_were_kept_starts_with_an_unknown_one(tmp_path: Path) -> None:
    run_dir = tmp_path / "seed0"
    (run_dir / "checkpoints").mkdir(parents=True)
    (run_dir / "checkpoints" / "last.ckpt").write_text("weights")
    trained, returned = train_in_segments(["python", "train.py", "seed=0"], run_dir, "c0ffee", lambda argv: 0)
    assert returned == 0 and trained["commit"] is None and trained["wall_s"] is None
    assert [s["commit"] for s in trained["segments"]] == [None, "c0ffee"]


def test_the_test_lenses_parse_and_their_files_are_committed() -> None:
    lenses = parse_test_lenses([_spec(s) for s in TEST_LENSES])
    assert [lens.name for lens in lenses][:2] == ["equidistant 190°", "equisolid 180°"]
    for lens in lenses:
        if "calibration" in lens.camera:
            assert (REPO / lens.camera["calibration"]).is_file(), lens.camera
    assert len(TRAIN_LENSES) == 4 and set(ARMS) == {"a", "b", "c", "d"}


def _spec(text: str) -> dict:
    """A Hydra ``{k:v,...}`` literal of this module's (no nesting, quoted paths) as a dict."""
    out = {}
    for item in text.strip("{}").split(","):
        key, value = item.split(":", 1)
        value = value.strip("'")
        out[key] = float(value) if value.replace(".", "").isdigit() and key != "camera" else value
    if "camera" in out:
        out["camera"] = int(out["camera"])
    return out


def _record(arm: str, seed: int, own: dict[str, float], other: dict[str, float]) -> dict:
    def row(name: str, flights: dict[str, float], seen: bool) -> dict:
        mean = sum(flights.values()) / len(flights)
        return {
            "name": name,
            "seen": seen,
            "metrics": {"delta1": mean, "abs_rel": 0.3},
            "gap": {"delta1": 0.0 if seen else 0.2 + 0.1 * seed, "abs_rel": 0.0},
            "flights": {f: {"delta1": v, "abs_rel": 0.3} for f, v in flights.items()},
        }

    return {
        "format": RECORD_FORMAT,
        "arm": arm,
        "task": "depth",
        "seed": seed,
        "cross_lens": {
            "lenses": [row("trained", own, True), row("pinhole_90", other, False)],
            "robustness": {"largest_change": {"delta1": 0.01 * (seed + 1), "abs_rel": 0.0}},
        },
    }


def test_summary_means_seeds_and_groups_the_gap_by_flight() -> None:
    records = [
        _record("a", 0, {"f1": 0.5, "f2": 0.6, "f3": 0.4}, {"f1": 0.4, "f2": 0.3, "f3": 0.4}),
        _record("a", 1, {"f1": 0.5, "f2": 0.4, "f3": 0.4}, {"f1": 0.2, "f2": 0.3, "f3": 0.2}),
    ]
    arm = summarise(records)["depth"]["a"]
    assert arm["seeds"] == [0, 1] and arm["own"] == "trained"
    pinhole = arm["lenses"]["pinhole_90"]
    assert not pinhole["seen"] and pinhole["delta1"]["n"] == 2
    assert pinhole["delta1"]["mean"] == pytest.approx((1.1 / 3 + 0.7 / 3) / 2)  # each seed: its frames' mean
    gap = pinhole["gap"]["delta1"]
    # Per flight: the seeds' mean on each lens, then 1 - other / own (δ1: higher is better).
    expected = {"f1": 1 - 0.3 / 0.5, "f2": 1 - 0.3 / 0.5, "f3": 1 - 0.3 / 0.4}
    assert gap["clusters"] == ["f1", "f2", "f3"] and gap["mean"] == pytest.approx(sum(expected.values()) / 3)
    assert gap["family_size"] == 1 and gap["ci"][0] < gap["mean"] < gap["ci"][1]
    assert arm["robustness"]["delta1"]["mean"] == pytest.approx(0.015)
    assert "gap" not in arm["lenses"]["trained"] and arm["lenses"]["trained"]["abs_rel"]["std"] == 0.0


def test_the_report_tables_come_from_the_summary() -> None:
    records = [
        _record("a", 0, {"f1": 0.5, "f2": 0.6, "f3": 0.4}, {"f1": 0.4, "f2": 0.3, "f3": 0.4}),
        _record("a", 1, {"f1": 0.5, "f2": 0.4, "f3": 0.4}, {"f1": 0.2, "f2": 0.3, "f3": 0.2}),
    ]
    summary = summarise(records)
    text = report_block(summary)
    lines = text.splitlines()
    assert "| arm | seeds | trained | pinhole_90 |" in lines
    delta1 = summary["depth"]["a"]["lenses"]
    row = f"| a: one lens (equidistant 190°) | 2 | {delta1['trained']['delta1']['mean']:.3f} ± "
    assert any(line.startswith(row) and line.endswith(" ★ | 0.300 ± 0.094 |") for line in lines), lines
    gap = delta1["pinhole_90"]["gap"]["delta1"]
    pooled = delta1["pinhole_90"]["pooled_gap"]["delta1"]
    assert pooled["n"] == 2 and pooled["mean"] == pytest.approx(
        0.25
    )  # each run's whole-split gap, over the seeds
    low, high = gap["ci_family"]
    cell = f"{pooled['mean']:.3f} ± {pooled['std']:.3f} ({gap['mean']:+.3f} [{low:+.3f}, {high:+.3f}], 3)"
    assert f"| a: one lens (equidistant 190°) | 2 | {cell} |" in lines
    assert "| a: one lens (equidistant 190°) | 2 | 0.015 ± 0.007 |" in lines
    document = f"x\n{REPORT_BEGIN}\nold\n{REPORT_END}\ny"
    assert block_in(replace_block(document, text, REPORT_BEGIN, REPORT_END), REPORT_BEGIN, REPORT_END) == text


def test_a_record_without_provenance_gains_it_from_its_own_fields(tmp_path: Path) -> None:
    record = {**_record("b", 2, {"f1": 0.5}, {"f1": 0.4}), "machine": "x86_64, 2 CPU cores"}
    record["evaluation"] = {"commit": "a" * 40, "command": ["python", "scripts/evaluate.py"]}
    path = tmp_path / "b_depth_seed2.json"
    path.write_text(json.dumps(record))
    assert upgrade_record(path) and not upgrade_record(path)  # once
    upgraded = json.loads(path.read_text())
    assert upgraded["provenance"] == {
        "commit": "a" * 40,
        "command": "python scripts/lens_study.py --arms b --tasks depth --seeds 2",
        "machine": "x86_64, 2 CPU cores",
    }
    assert {k: v for k, v in upgraded.items() if k != "provenance"} == record


def test_a_run_is_also_scored_over_the_held_out_flights_and_reported_first() -> None:
    from airfisheye_bench.studies.lens_study import HELD_OUT, held_out_records

    run = plan(Path("runs"), ["b"], ["seg"], [1])[0]
    argv = run.evaluate_argv(held_out=True)
    assert set(HELD_OUT) <= set(argv) and "robustness=true" not in argv
    assert argv[-1] == f"out={run.run_dir / 'lenses_flights'}"
    robustness = run.robustness_argv()  # the trained lens and its perturbations alone, over the same flights
    assert set(HELD_OUT) <= set(robustness) and "robustness=true" in robustness
    assert not any(a.startswith("lenses=") for a in robustness)
    assert robustness[-1] == f"out={run.run_dir / 'robustness_flights'}"
    many = {f"f{i}": 0.5 + 0.01 * i for i in range(8)}
    records = [
        _record("a", s, {"f1": 0.5, "f2": 0.6, "f3": 0.4}, {"f1": 0.4, "f2": 0.3, "f3": 0.4}) for s in (0, 1)
    ]
    records[0]["held_out"] = {
        "dataset": {"name": "held"},
        "cross_lens": _record("a", 0, many, many)["cross_lens"],
    }
    held = held_out_records(records)
    assert [r["seed"] for r in held] == [0] and held[0]["dataset"] == {"name": "held"}
    assert summarise(held)["depth"]["a"]["lenses"]["pinhole_90"]["gap"]["delta1"]["n"] == 8  # flights
    text = report_block(summarise(records), held=summarise(held))
    first, second = text.index("32 held-out test flights"), text.index("own test split (3 flights)")
    assert first < second and "robustness row" not in text[:second] and "robustness row" in text[second:]
    row = {"flights": {}, "perturbations": [], "largest_change": {"delta1": 0.02}}
    records[0]["held_out"]["robustness"] = {"evaluation": {"commit": "c0ffee"}, **row}
    held_row = held_out_records(records)[0]["cross_lens"]["robustness"]  # what the held-out summary reads
    assert held_row == row
    assert summarise(held_out_records(records))["depth"]["a"]["robustness"]["delta1"]["mean"] == 0.02
    records[1]["held_out"] = {"dataset": {"name": "other"}, "cross_lens": records[1]["cross_lens"]}
    with pytest.raises(ValueError, match="different datasets"):
        held_out_records(records)


def test_the_committed_report_is_the_one_the_committed_records_give() -> None:
    """docs/results.md's block and summary.json are what ``scripts/lens_study.py --summary ... --report ...`` makes
    of the committed records: regenerate them when a record lands."""
    from airfisheye_bench.studies.lens_study import held_out_analysis, held_out_records, load_records

    records = load_records(REPO / "docs" / "figures" / "lens_study" / "runs")
    summary = json.loads(
        (REPO / "docs" / "figures" / "lens_study" / "summary.json").read_text(encoding="utf-8")
    )
    assert summary["records"] == [f"{r['arm']}_{r['task']}_seed{r['seed']}.json" for r in records]
    held = held_out_records(records)
    assert summary["held_out"]["records"] == [f"{r['arm']}_{r['task']}_seed{r['seed']}.json" for r in held]
    text = (REPO / "docs" / "results.md").read_text(encoding="utf-8")
    held_summary, contrasts, robustness = held_out_analysis(held)
    expected = report_block(summarise(records), held=held_summary, contrasts=contrasts, robustness=robustness)
    assert block_in(text, REPORT_BEGIN, REPORT_END) == expected, (
        "regenerate: python scripts/lens_study.py --summary docs/figures/lens_study/summary.json --report docs/results.md"
    )


def test_the_held_out_robustness_row_joins_the_records_held_out_block(tmp_path: Path, monkeypatch) -> None:
    from airfisheye_bench.studies import lens_study

    run = plan(tmp_path, ["a"], ["depth"], [0])[0]
    path = tmp_path / "a_depth_seed0.json"
    path.write_text(json.dumps({"held_out": {"dataset": {"name": "held"}, "cross_lens": {"lenses": []}}}))
    row = {"camera": {}, "metrics": {}, "flights": {}, "perturbations": [], "largest_change": {}}
    scored = {"dataset": {"name": "held"}, "cross_lens": {"lenses": [], "robustness": row}}
    monkeypatch.setattr(lens_study, "_evaluate", lambda argv, threads: (scored, {"command": argv}))
    lens_study.score_held_out_robustness(run, path)
    held_out = json.loads(path.read_text())["held_out"]
    assert (
        held_out["robustness"]["perturbations"] == []
        and "robustness=true" in held_out["robustness"]["evaluation"]["command"]
    )
    scored["dataset"] = {"name": "other"}  # scored on other data than the held-out lenses: refused
    with pytest.raises(RuntimeError, match="other data"):
        lens_study.score_held_out_robustness(run, path)
