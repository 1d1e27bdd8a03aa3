"""The quick-start benchmark: its record, the README table generated from it, and the committed results."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from airfisheye_bench.studies import quickstart, quickstart_report, quickstart_variant

ROOT = Path(__file__).resolve().parents[2]
COMMITTED = ROOT / "docs" / "quickstart_results.json"
README = ROOT / "README.md"


def _fake_run(
    run: quickstart.QuickstartRun, metrics: dict[str, float], root: Path, wall_s: float = 60.0
) -> None:
    run.out.mkdir(parents=True)
    results = {"task": run.task, "metrics": metrics, "dataset": {"root": str(root), "name": "synth"}}
    run.results.write_text(json.dumps(results))
    run.record.write_text(json.dumps({"command": "python train.py", "commit": "abc", "wall_s": wall_s}))


@pytest.fixture
def record(tmp_path: Path) -> dict:
    data = tmp_path / "data"
    data.mkdir()
    (data / "x.txt").write_text("x")
    runs = quickstart.plan(tmp_path / "runs", ["seg", "depth"], [0, 1])
    values = {0: 0.20, 1: 0.30}
    for run in runs:
        if run.task == "seg":
            _fake_run(run, {"mIoU": values[run.seed], "pixel_acc": 0.5}, data)
        elif run.seed == 0:  # depth seed 1 has not finished
            _fake_run(run, {"rmse": 15.0, "abs_rel": 0.3, "delta1": 0.5, "sq_rel": 1.0}, data, wall_s=725.0)
    baselines = {
        "seg": {"name": "majority", "metrics": {"mIoU": 0.1, "pixel_acc": 0.4}},
        "depth": {"name": "mean", "metrics": {"rmse": 20.0, "abs_rel": 0.4, "delta1": 0.3}},
    }
    return quickstart.summarize(runs, baselines, "python scripts/quickstart_benchmark.py", "0123456789abcdef")


def test_summary_has_mean_std_per_seed_values_and_the_missing_seeds(record: dict) -> None:
    seg, depth = record["tasks"]["seg"], record["tasks"]["depth"]
    assert seg["summary"]["mIoU"]["mean"] == pytest.approx(0.25)
    assert seg["summary"]["mIoU"]["std"] == pytest.approx(0.0707107, rel=1e-5)  # sample std of 0.2, 0.3
    assert seg["seeds"]["1"]["metrics"]["mIoU"] == 0.3
    assert depth["missing_seeds"] == [1] and list(depth["seeds"]) == ["0"]
    assert depth["summary"]["rmse"]["std"] is None  # one seed: no spread
    assert record["dataset"]["content_sha256"] and record["dataset"]["name"] == "synth"
    assert quickstart.beats_baseline(seg) == {"0": True, "1": True}


def test_a_seed_keeps_its_validation_curve(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    (run,) = quickstart.plan(tmp_path / "runs", ["completion"], [0])
    _fake_run(run, {"rmse": 7.0}, data)
    (run.out / "metrics.csv").write_text("epoch,train/loss,val/rmse\n0,5.0,\n0,,9.5\n1,,8.0\n")
    seed = quickstart.summarize([run], {}, "collect", "0123")["tasks"]["completion"]["seeds"]["0"]
    assert seed["validation_curve"] == [{"epoch": 0, "val/rmse": 9.5}, {"epoch": 1, "val/rmse": 8.0}]


def test_readme_table_shows_the_spread_and_round_trips(record: dict) -> None:
    table = quickstart.readme_table(record)
    assert "mIoU 0.250 ± 0.071" in table and "(2 seeds: 0, 1)" in table
    assert "RMSE 15.00 m" in table and "12 min 05 s" in table
    text = f"intro\n{quickstart.TABLE_BEGIN}\nold\n{quickstart.TABLE_END}\nafter\n"
    updated = quickstart.replace_table(text, table)
    assert quickstart.table_in(updated) == table and updated.endswith("after\n")
    with pytest.raises(ValueError, match="markers"):
        quickstart.replace_table("no table here", table)


def test_a_run_records_the_cpu_kernels_it_was_limited_to(tmp_path: Path, monkeypatch) -> None:
    """A result moves with the CPU's kernels as well as the seed: a run made with them switched says so."""
    (run,) = quickstart.plan(tmp_path / "runs", ["seg"], [0])
    monkeypatch.setenv("ATEN_CPU_CAPABILITY", "avx2")
    monkeypatch.delenv("MKL_CBWR", raising=False)
    seen: dict = {}

    def runner(argv: list[str], cwd: Path, env: dict[str, str]) -> None:
        seen.update(env)
        run.out.mkdir(parents=True)
        run.results.write_text(json.dumps({"task": "seg", "metrics": {"mIoU": 0.2}, "dataset": {}}))

    quickstart.train_missing([run], ROOT, runner=runner, log=lambda _: None, threads=1)
    assert seen["ATEN_CPU_CAPABILITY"] == "avx2" and seen["OMP_NUM_THREADS"] == "1"
    assert json.loads(run.record.read_text())["cpu_kernels"] == {"ATEN_CPU_CAPABILITY": "avx2"}
    record = quickstart.summarize([run], {}, "python scripts/quickstart_benchmark.py", "0123456789abcdef")
    assert record["tasks"]["seg"]["seeds"]["0"]["cpu_kernels"] == {"ATEN_CPU_CAPABILITY": "avx2"}


@pytest.mark.skipif(quickstart.machine_busy_s() is None, reason="needs /proc/stat (Linux)")
def test_a_run_records_its_cpu_time_and_the_other_work_beside_it(tmp_path: Path) -> None:
    """A wall time is what a user waits only if the run had the machine: the record says how shared it was."""
    (run,) = quickstart.plan(tmp_path / "runs", ["seg"], [0])
    spin = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.4: pass"

    def runner(argv: list[str], cwd: Path, env: dict[str, str]) -> None:
        subprocess.run([sys.executable, "-c", spin], check=True)  # the run: a child's CPU time
        exec(spin)  # other work beside it: this process, not a child of the benchmark's runs
        run.out.mkdir(parents=True)
        run.results.write_text(json.dumps({"task": "seg", "metrics": {"mIoU": 0.2}, "dataset": {}}))

    quickstart.train_missing([run], ROOT, runner=runner, log=lambda _: None)
    saved = json.loads(run.record.read_text())
    assert 0.35 <= saved["cpu_s"] < saved["wall_s"] + 0.5
    assert (
        saved["other_cores"] >= 0.3
    )  # 0.4 s of the parent's CPU over a ~0.9 s run (more if the machine is busy)
    assert quickstart.ran_alone(saved) is False


def test_the_wall_time_cell_uses_the_runs_that_had_the_machine_alone() -> None:
    def entry(*seeds: dict) -> dict:
        seeds_ = {str(k): s for k, s in enumerate(seeds)}
        summary = {"wall_s": quickstart.mean_std([s["wall_s"] for s in seeds])}
        alone = [s["wall_s"] for s in seeds if quickstart.ran_alone(s)]
        if alone:
            summary["wall_s_alone"] = quickstart.mean_std(alone)
        return {"seeds": seeds_, "summary": summary}

    mixed = entry({"wall_s": 600.0, "other_cores": 0.02}, {"wall_s": 900.0, "other_cores": 1.0})
    assert quickstart._wall_text(mixed) == "10 min 00 s (alone; 1 run)"
    shared = entry({"wall_s": 900.0, "other_cores": 0.8}, {"wall_s": 960.0, "other_cores": 1.0})
    assert quickstart._wall_text(shared) == "15 min 30 s (beside other work using 0.9 cores on average)"
    assert (
        quickstart._wall_text(entry({"wall_s": 725.0})) == "12 min 05 s"
    )  # a record from before the account
    one_thread = {"omp_num_threads": "1"}
    assert (
        quickstart._wall_text(entry({"wall_s": 600.0, "other_cores": 0.02, **one_thread}))
        == "10 min 00 s (alone; 1 run, 1 thread)"
    )
    assert quickstart._wall_text(
        entry(
            {"wall_s": 900.0, "other_cores": 0.8, **one_thread},
            {"wall_s": 960.0, "other_cores": 1.0, **one_thread},
        )
    ) == ("15 min 30 s (beside other work using 0.9 cores on average, 1 thread each)")


def test_plan_refuses_an_unknown_task(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="unknown quick-start task"):
        quickstart.plan(tmp_path, ["segmentation"], [0])


# ------------------------------------------------------------------------------------ the committed results
def _committed() -> dict:
    if not COMMITTED.is_file():
        pytest.fail(f"{COMMITTED} is missing: run scripts/quickstart_benchmark.py")
    return json.loads(COMMITTED.read_text(encoding="utf-8"))


def test_readme_table_is_the_one_generated_from_the_committed_results() -> None:
    record = _committed()
    shown = quickstart.table_in(README.read_text(encoding="utf-8"))
    assert shown == quickstart.readme_table(record), (
        "regenerate: python scripts/quickstart_benchmark.py --readme"
    )


def test_every_number_of_the_readme_table_is_in_the_committed_results() -> None:
    record = _committed()
    shown = quickstart.table_in(README.read_text(encoding="utf-8"))
    expected: set[str] = set()
    for entry in record["tasks"].values():
        for key, stat in entry.get("summary", {}).items():
            digits = quickstart._DIGITS.get(key, 3)
            for value in (stat["mean"], stat["std"]):
                if value is not None:
                    expected.add(f"{value:.{digits}f}")
        for key, value in entry.get("baseline", {}).get("metrics", {}).items():
            expected.add(f"{value:.{quickstart._DIGITS.get(key, 3)}f}")
        for seed in entry["seeds"].values():  # completion: the LiDAR input's coverage per ring, in per cent
            expected |= {f"{100 * v:.1f}" for v in seed.get("sparse_coverage", {}).values()}
    rows = [line for line in shown.splitlines() if line.startswith("| `")]
    assert rows, "the README table has no rows"
    for row in rows:
        cells = row.split("|")[4:6]  # the result and baseline columns
        for number in re.findall(r"\d+\.\d+", " ".join(cells)):
            assert number in expected, (
                f"{number} in the README's row {row[:40]}... is not in {COMMITTED.name}"
            )


def test_each_quick_start_beats_its_trivial_baseline_on_every_seed() -> None:
    record = _committed()
    unfinished = []
    for task, entry in record["tasks"].items():
        if entry["missing_seeds"]:
            unfinished.append(f"{task} seeds {entry['missing_seeds']}")
        if not entry["seeds"]:
            continue
        wins = quickstart.beats_baseline(entry)
        assert all(wins.values()), (
            f"{task}: seeds {[s for s, w in wins.items() if not w]} do not beat the baseline"
        )
    if unfinished:  # reported, not hidden: the record says which runs it still lacks
        pytest.skip(f"{COMMITTED.name} lacks {'; '.join(unfinished)}")


def test_seeds_of_the_earlier_record_are_kept_when_their_runs_are_elsewhere(
    record: dict, tmp_path: Path
) -> None:
    # The earlier record has depth seed 1; here only seed 0 has finished (in another output folder).
    previous = json.loads(json.dumps(record))
    previous["tasks"]["depth"]["seeds"]["1"] = {
        "metrics": {"rmse": 17.0, "abs_rel": 0.32, "delta1": 0.45},
        "wall_s": 700.0,
        "commit": "def",
        "command": "python train.py task=depth seed=1",
    }
    runs = [r for r in quickstart.plan(tmp_path / "runs", ["seg", "depth"], [0, 1])]
    merged = quickstart.summarize(runs, {}, "collect", "0123", previous)
    depth = merged["tasks"]["depth"]
    assert list(depth["seeds"]) == ["0", "1"] and depth["missing_seeds"] == []
    assert depth["seeds"]["1"]["commit"] == "def"  # it says which code trained it
    assert depth["summary"]["rmse"]["mean"] == pytest.approx(16.0)
    assert depth["baseline"] == record["tasks"]["depth"]["baseline"]  # nothing here to refit it on

    previous["tasks"]["completion"] = {
        "seeds": {"0": {"metrics": {"rmse": 5.0}, "wall_s": 1.0}},
        "missing_seeds": [],
    }
    only_seg = quickstart.summarize(runs[:1], {}, "collect seg", "0123", previous)  # seg seed 0 alone
    assert list(only_seg["tasks"]) == ["seg", "depth", "completion"]  # the others are kept as they were
    assert only_seg["tasks"]["depth"]["seeds"]["1"]["commit"] == "def"

    previous["dataset"]["content_sha256"] = "f" * 64  # measured on other data: never mixed
    with pytest.raises(ValueError, match="the data changed"):
        quickstart.summarize(runs, {}, "collect", "0123", previous)


def test_the_reports_generated_tables_are_the_ones_the_committed_files_give() -> None:
    # docs/results.md sections 2, 3 and 6 print only what docs/quickstart_results.json and the export reports say.
    report = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    assert quickstart_report.regenerate(report, _committed(), ROOT / "docs") == report, (
        "regenerate: python scripts/quickstart_benchmark.py --readme"
    )
    for begin, end in (
        (quickstart_report.RESULTS_BEGIN, quickstart_report.RESULTS_END),
        (quickstart_report.CLAIM_BEGIN, quickstart_report.CLAIM_END),
        (quickstart_report.DEPLOY_BEGIN, quickstart_report.DEPLOY_END),
    ):
        assert quickstart.table_in(report, begin, end).strip(), f"{begin[:40]}... is empty"


def test_report_tables_show_the_paper_the_seeds_and_the_baseline(record: dict) -> None:
    tables = quickstart_report.results_tables(record)
    assert "| DeepLabV3+ / ResNet50 (paper IV-A) | released AirFisheye, test | 0.512 | – |" in tables
    assert (
        "mean ± std over 2 seeds (0, 1) | synthetic quickstart, test | 0.250 ± 0.071 | 0.500 ± 0.000 |"
        in tables
    )
    assert "| seed 1 (commit `abc`) | synthetic quickstart, test | 0.300 | 0.500 |" in tables
    assert "| trivial baseline: mean | synthetic quickstart, test | 0.400 | – | 20.00 |" in tables
    assert "depth" in quickstart_report.claim_table(record)  # no completion runs: says so, no ratio
    assert "no finished depth and completion runs" in quickstart_report.claim_table(record)


def test_deployment_table_reads_the_export_report() -> None:
    record = {
        "model": "deeplabv3plus",
        "onnx_bytes": 49_500_000,
        "parity": {"verdict": "max |diff| 1.9e-05 ≤ atol 0.0001: OK", "frames": 4},
        "latency": {
            "ratio_ort_over_torch": 0.42,
            "onnxruntime_ms": 67.6,
            "pytorch_ms": 161.8,
            "batch": 4,
            "threads": 2,
        },
        "int8": {
            "ok": True,
            "mode": "static",
            "frames": 64,
            "fp32_bytes": 49_500_000,
            "int8_bytes": 12_500_000,
            "metrics_fp32": {"mIoU": 0.2377, "pixel_acc": 0.7173},
            "metrics_int8": {"mIoU": 0.2382, "pixel_acc": 0.7171},
            "speedup": 1.22,
            "batch": 4,
            "threads": 2,
        },
    }
    table = quickstart_report.deployment_tables({"seg": record})
    assert r"| deeplabv3plus (seg) | 49.5 MB | max \|diff\| 1.9e-05 ≤ atol 0.0001: OK (4 frames) |" in table
    assert "0.42 (67.6 / 161.8 ms, batch 4, 2 threads)" in table
    assert "49.5 → 12.5 MB | mIoU 0.238 → 0.238, pixel acc 0.717 → 0.717 | ×1.22" in table
    assert "No export report" in quickstart_report.deployment_tables({})


def test_rings_table_averages_the_seeds_that_recorded_a_breakdown(record: dict) -> None:
    record = json.loads(json.dumps(record))
    seeds = record["tasks"]["seg"]["seeds"]
    seeds["0"]["breakdown"] = {"ring_0-30/mIoU": 0.1, "ring_30-95/mIoU": 0.3}
    seeds["1"]["breakdown"] = {"ring_0-30/mIoU": 0.2, "ring_30-95/mIoU": 0.5}
    record["tasks"]["depth"]["seeds"]["0"]["breakdown"] = {"ring_0-30/rmse": 12.0, "range_0-10/rmse": 2.5}
    table = quickstart_report.rings_tables(record)
    assert "| incidence angle θ | 0-30° | 30-95° | seeds |" in table
    assert "| segmentation mIoU | 0.150 | 0.400 | 0, 1 |" in table
    assert "| monocular depth RMSE (m) | 12.00 | – | 0 |" in table
    assert "| monocular depth RMSE (m) | 2.50 | 0 |" in table  # by range
    assert "sparse LiDAR" not in table  # no completion seed: no coverage row
    del seeds["0"]["breakdown"], seeds["1"]["breakdown"], record["tasks"]["depth"]["seeds"]["0"]["breakdown"]
    assert "no per-ring breakdown" in quickstart_report.rings_tables(record)


def test_rings_coverage_row_is_what_the_completion_runs_were_served(record: dict) -> None:
    record = json.loads(json.dumps(record))
    record["tasks"]["seg"]["seeds"]["0"]["breakdown"] = {"ring_0-30/mIoU": 0.1, "ring_30-95/mIoU": 0.3}
    served = {"ring_0-30": 0.11, "ring_30-95": 0.05}
    record["tasks"]["completion"] = {
        "seeds": {
            "0": {"metrics": {}, "lidar_density": "paper", "sparse_coverage": served},
            "1": {"metrics": {}, "lidar_density": "paper", "sparse_coverage": {**served, "ring_0-30": 0.13}},
        }
    }
    row = (
        "| sparse LiDAR pixels per ground-truth pixel (completion input as trained, `data.lidar.density=paper`) "
        "| 0.120 | 0.050 | 0, 1 |"
    )
    assert row in quickstart_report.rings_tables(record)


def test_ring_spread_reads_the_largest_seed_spread_the_rise_to_the_rim_and_the_gap_by_range() -> None:
    def seeds(*breakdowns: dict) -> dict:
        return {"seeds": {str(i): {"metrics": {}, "breakdown": b} for i, b in enumerate(breakdowns)}}

    record = {
        "tasks": {
            "seg": seeds(
                {"ring_0-30/mIoU": 0.1, "ring_30-95/mIoU": 0.2},
                {"ring_0-30/mIoU": 0.1, "ring_30-95/mIoU": 0.3},
            ),
            "depth": seeds(
                {
                    "ring_0-30/abs_rel": 0.2,
                    "ring_30-95/abs_rel": 0.3,
                    "ring_0-30/rmse": 10.0,
                    "range_0-10/rmse": 4.0,
                },
                {
                    "ring_0-30/abs_rel": 0.2,
                    "ring_30-95/abs_rel": 0.5,
                    "ring_0-30/rmse": 14.0,
                    "range_0-10/rmse": 4.0,
                },
            ),
            "completion": seeds(
                {"ring_0-30/abs_rel": 0.1, "ring_30-95/abs_rel": 0.2, "range_0-10/rmse": 5.0},
                {"ring_0-30/abs_rel": 0.1, "ring_30-95/abs_rel": 0.2, "range_0-10/rmse": 5.0},
            ),
        }
    }
    text = quickstart_report.ring_spread(record)
    assert "AbsRel by ring at most 0.141 (monocular depth, 30-95°)" in text  # std of 0.3, 0.5
    assert "mIoU by ring at most 0.071 (segmentation, 30-95°)" in text
    assert "RMSE (by ring and by range) at most 2.83 m (monocular depth, 0-30°)" in text
    assert "completion 0.100 → 0.200, monocular depth 0.200 → 0.400" in text
    assert "0-10 m -1.00" in text  # completion worse than depth close by
    assert quickstart_report.ring_spread({"tasks": {}}) == ""


def test_the_ratio_to_monocular_compares_with_the_papers_only_at_its_density_and_quality() -> None:
    depth = {"model": "AdaBins", "seeds": {"0": {"metrics": {"delta1": 0.46}}}}
    completion = {"seeds": {"0": {"metrics": {}, "lidar_density": "paper"}}}
    (reason,) = quickstart_report.ratio_not_comparable(depth, completion, paper_delta1=0.865)
    assert "monocular" in reason and "0.460 against 0.865" in reason
    depth["seeds"]["0"]["metrics"]["delta1"] = 0.85
    assert quickstart_report.ratio_not_comparable(depth, completion, paper_delta1=0.865) == []
    completion["seeds"]["1"] = {"metrics": {}}  # trained before the key existed: every return
    (reason,) = quickstart_report.ratio_not_comparable(depth, completion, paper_delta1=0.865)
    assert "density native, paper" in reason


# ------------------------------------------------------------------------------------------------- a variant


def _variant(tmp_path: Path, values: dict[int, float], overrides: list[str]) -> dict:
    data = tmp_path / "data"
    data.mkdir(exist_ok=True)
    (data / "x.txt").write_text("x")
    runs = quickstart.plan(tmp_path / "_".join(["runs", *overrides]), ["seg"], sorted(values))
    for run in runs:
        _fake_run(run, {"mIoU": values[run.seed], "pixel_acc": 0.5}, data)
    return quickstart.summarize(runs, {}, "python scripts/quickstart_benchmark.py", "0" * 40, None, overrides)


def test_a_variant_names_its_overrides_and_is_shown_beside_the_default_with_the_paired_difference(
    tmp_path: Path,
) -> None:
    default = _variant(tmp_path, {0: 0.20, 1: 0.30, 2: 0.25}, [])
    variant = _variant(tmp_path, {0: 0.25, 1: 0.33, 2: 0.32}, ["data.x=1"])
    assert variant["tasks"]["seg"]["command"] == "python train.py task=seg data.x=1"
    paired = quickstart_variant.paired_rows(default, variant, "seg")
    assert paired["mIoU"]["n"] == 3 and paired["mIoU"]["mean"] == pytest.approx(0.05)
    low, high = paired["mIoU"]["ci"]
    assert low < 0.05 < high
    table = quickstart_variant.variant_table(default, variant, "docs/a.json", "docs/b.json")
    rows = table.splitlines()
    assert rows[2].startswith("| `python train.py task=seg` ([record](docs/a.json)) | 0, 1, 2 |")
    assert rows[3].startswith("| `python train.py task=seg data.x=1` ([record](docs/b.json)) | 0, 1, 2 |")
    assert "+0.050 [" in rows[4] and "3 paired seeds" in rows[4]


def test_the_readme_variant_block_is_the_one_generated_from_the_committed_records() -> None:
    text = README.read_text(encoding="utf-8")
    if quickstart_variant.VARIANT_BEGIN not in text:
        pytest.skip("the README shows no variant of the quick start")
    shown = quickstart.table_in(text, quickstart_variant.VARIANT_BEGIN, quickstart_variant.VARIANT_END)
    sources = re.findall(r"\(\[record\]\(([^)]+)\)\)", shown)
    default, variant = (json.loads((ROOT / s).read_text(encoding="utf-8")) for s in dict.fromkeys(sources))
    assert shown == quickstart_variant.variant_table(default, variant, *dict.fromkeys(sources)), (
        "regenerate: python scripts/quickstart_benchmark.py --readme --variant <record>"
    )
