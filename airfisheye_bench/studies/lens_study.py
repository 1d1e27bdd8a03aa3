"""The lens study (docs/results.md, "Across lenses"): does a model hold on a lens it was not trained on?

Arms, each trained at the quick-start size (128², the quick start's epochs) for every task of :data:`TASKS` and
seed of :data:`SEEDS`, with the seeds paired across arms:

- ``a``: the quick start, one lens (the synthetic release's 190° equidistant);
- ``b``: a list of lenses (:data:`TRAIN_LENSES`) with per-sample jitter (:data:`JITTER`);
- ``c``: ``b`` with ``model.camera_input=rays`` (the lens's ray map given to the model);
- ``d``: a pinhole model (90° perspective views of the same cube faces), scored on the fisheyes through
  perspective views (``views=cube``).

Every run is then scored on each test lens of :data:`TEST_LENSES` and the robustness row
(``airfisheye-evaluate lenses=[...] robustness=true``), and its record -- training commit and command, evaluation
command, the dataset's content identity, the run's own test metrics and the whole ``cross_lens`` block, flights
included -- is written to ``docs/figures/lens_study/runs/<arm>_<task>_seed<seed>.json`` as soon as it exists. The
test lenses are none of the training lenses except arm ``a``'s and ``b``'s equidistant 190°; the calibration files
are under ``docs/lenses/`` (their sources in its README). Each run is also scored on the same lenses over
:data:`HELD_OUT`, 32 test flights of the quick start's data from areas no run trained on (the quick start's own test
split has 3 flights, too few for an interval over them to bound anything but large gaps): the record's
``held_out`` block, with the robustness row over the same flights as its ``robustness``.

:func:`summarise` reads the records alone: per arm, task and test lens the mean and sample standard deviation over
the seeds, and the cross-lens gap ``1 - other / own`` (``other / own - 1`` for errors) with a t-interval over the
test flights (the seeds' per-flight scores averaged first: frames of one flight are not independent), Bonferroni
over the family of lenses. Over the held-out flights the arms are also compared with each other, lens by lens
(:mod:`airfisheye_bench.studies.lens_contrasts`: b − a, c − b, d − a on paired seeds), and each arm's robustness
row is read perturbation by perturbation: the change of each, flight by flight, with its interval.

The study accumulates across sessions: a run whose record exists is not run again, and a training that a session's
end cut is resumed exactly from its last checkpoint, its record keeping the segments it trained in
(:mod:`airfisheye_bench.studies.segments`).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.evaluation.cross_lens import cross_lens_gap
from airfisheye_bench.runs.results import json_safe
from airfisheye_bench.specs import get_task
from airfisheye_bench.studies.clustered import cluster_difference
from airfisheye_bench.studies.generated_blocks import replace_block
from airfisheye_bench.studies.lens_contrasts import (
    arm_contrasts,
    contrast_lines,
    flight_scores,
    robustness_changes,
    robustness_lines,
)
from airfisheye_bench.studies.provenance import REPO, git_commit, machine, provenance, records_of_format
from airfisheye_bench.studies.quickstart import METRIC_LABELS
from airfisheye_bench.studies.segments import train_in_segments

__all__ = [
    "ARMS",
    "HELD_OUT",
    "JITTER",
    "RECORD_FORMAT",
    "SEEDS",
    "TASKS",
    "TEST_LENSES",
    "TRAIN_LENSES",
    "Arm",
    "StudyRun",
    "plan",
    "summarise",
]

RECORD_FORMAT = "airfisheye-bench/lens-study-run/v1"
TASKS = ("depth", "seg")
SEEDS = (0, 1, 2)
#: The committed calibration files of the test lenses (sources: ``docs/lenses/README.md``).
LENS_FILES = "docs/lenses"
#: Arm b's lenses: four designs and fields of view, none of the test lenses but the equidistant 190°.
TRAIN_LENSES = (
    "{model:equidistant,fov_deg:190}",
    "{model:equisolid,fov_deg:170}",
    "{model:stereographic,fov_deg:150}",
    "{model:equidistant,fov_deg:100}",
)
#: Arm b's jitter: ±5 % focal length, ±2 px principal point, ±5 % of each distortion term.
JITTER = "{focal:0.05,principal_point_px:2,distortion:0.05}"
#: The test lenses: two ideal fisheyes, three real calibrations, a narrow fisheye and a pinhole.
TEST_LENSES = (
    "{model:equidistant,fov_deg:190}",
    "{model:equisolid,fov_deg:180}",
    f"{{name:tumvi_kb,calibration:'{LENS_FILES}/tumvi_kb_camchain.yaml'}}",
    f"{{name:tumvi_ds,calibration:'{LENS_FILES}/tumvi_ds_basalt.json',camera:1}}",
    f"{{name:woodscape_front,calibration:'{LENS_FILES}/woodscape_front.json'}}",
    "{model:equidistant,fov_deg:120}",
    f"{{name:pinhole_90,calibration:'{LENS_FILES}/pinhole_90.yaml'}}",
)

#: The evaluation set of many flights (``synth/presets.py``, ``quickstart_flights``): the quick start's data as 32
#: test flights of 6 frames, at another dataset seed (none of its areas is one the runs trained on).
HELD_OUT = ("data.preset=quickstart_flights", "data.dataset_seed=1")


@dataclass(frozen=True)
class Arm:
    """One way of training: its training overrides and its evaluation's own."""

    name: str
    title: str
    train: tuple[str, ...] = ()
    evaluate: tuple[str, ...] = ()


_LENS_LIST = (f"data.camera.lenses=[{','.join(TRAIN_LENSES)}]", f"data.camera.jitter={JITTER}")
ARMS: dict[str, Arm] = {
    arm.name: arm
    for arm in (
        Arm("a", "one lens (equidistant 190°)"),
        Arm("b", "lens list + jitter", _LENS_LIST),
        Arm("c", "lens list + jitter + rays", (*_LENS_LIST, "model.camera_input=rays")),
        Arm(
            "d",
            "pinhole 90° through perspective views",
            (f"data.camera.calibration={LENS_FILES}/pinhole_90.yaml",),
            ("views=cube",),
        ),
    )
}


@dataclass(frozen=True)
class StudyRun:
    """One training run of the study and where its files go."""

    arm: str
    task: str
    seed: int
    out: Path

    @property
    def run_dir(self) -> Path:
        return self.out / self.arm / self.task / f"seed{self.seed}"

    @property
    def trained(self) -> Path:
        """The training's own record (commit, command, wall time), beside the run."""
        return self.run_dir.with_name(f"seed{self.seed}.train.json")

    @property
    def name(self) -> str:
        return f"{self.arm}_{self.task}_seed{self.seed}"

    def train_argv(self) -> list[str]:
        arm = ARMS[self.arm]
        return [
            sys.executable,
            "train.py",
            f"task={self.task}",
            f"seed={self.seed}",
            *arm.train,
            f"hydra.run.dir={self.run_dir}",
        ]

    def evaluate_argv(self, held_out: bool = False) -> list[str]:
        """The scoring command: the run's own test split with the robustness row, or (``held_out``) the lenses
        over :data:`HELD_OUT`'s flights."""
        return self._scoring_argv(
            f"lenses=[{','.join(TEST_LENSES)}]",
            *(HELD_OUT if held_out else ("robustness=true",)),
            out=self.evaluated(held_out),
        )

    def robustness_argv(self) -> list[str]:
        """The robustness row over :data:`HELD_OUT`'s flights (the trained lens and its perturbations alone)."""
        return self._scoring_argv("robustness=true", *HELD_OUT, out=self.run_dir / "robustness_flights")

    def _scoring_argv(self, *overrides: str, out: Path) -> list[str]:
        return [
            sys.executable,
            "scripts/evaluate.py",
            f"ckpt_path={self.run_dir}",
            *overrides,
            "num_panels=0",
            *ARMS[self.arm].evaluate,
            f"out={out}",
        ]

    def evaluated(self, held_out: bool = False) -> Path:
        """Where a scoring writes its ``results.json``."""
        return self.run_dir / ("lenses_flights" if held_out else "lenses")


def plan(out: str | Path, arms: Sequence[str], tasks: Sequence[str], seeds: Sequence[int]) -> list[StudyRun]:
    """The runs of ``arms`` x ``tasks`` x ``seeds``, seed-major (a finished seed pairs every arm)."""
    unknown = sorted(set(arms) - set(ARMS))
    if unknown:
        raise ValueError(f"unknown arm {unknown[0]!r}; expected some of {', '.join(ARMS)}")
    return [StudyRun(a, t, s, Path(out)) for s in seeds for t in tasks for a in arms]


def train(run: StudyRun, threads: int = 1) -> None:
    """Train ``run`` from the checkout (one thread each: two runs share a 2-core machine) and record how; a run
    that a session's end cut is resumed exactly, and its record keeps the segments
    (:mod:`airfisheye_bench.studies.segments`)."""
    env = {**os.environ, "OMP_NUM_THREADS": str(threads), "MKL_NUM_THREADS": str(threads)}
    argv = run.train_argv()
    log_path = run.run_dir.with_suffix(".log")

    def runner(args: list[str]) -> int:
        with open(log_path, "a" if "ckpt_path=last" in args else "w") as log:
            return subprocess.run(args, cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT).returncode

    trained, code = train_in_segments(argv, run.run_dir, git_commit(REPO), runner)
    record = {
        "commit": trained["commit"],
        "rc": code,
        "wall_s": trained["wall_s"],
        "command": ["python", *argv[1:]],
        "omp_num_threads": threads,
        **({"segments": trained["segments"]} if len(trained["segments"]) > 1 else {}),
    }
    atomic_write_text(run.trained, json.dumps(record, indent=1) + "\n")
    if code != 0:
        raise RuntimeError(f"{run.name}: training exited {code} (log: {log_path})")


def score(run: StudyRun, records: Path, threads: int = 1) -> Path:
    """Score a trained run on every test lens and the robustness row; write its record into ``records``."""
    evaluated, evaluation = _evaluate(run.evaluate_argv(), threads)
    own = json.loads((run.run_dir / "results.json").read_text(encoding="utf-8"))
    trained = json.loads(run.trained.read_text(encoding="utf-8"))
    record = {
        "format": RECORD_FORMAT,
        "provenance": _provenance(evaluation["commit"], run, machine()),
        "arm": run.arm,
        "task": run.task,
        "seed": run.seed,
        "training": trained,
        "evaluation": evaluation,
        "machine": machine(),
        "dataset": evaluated["dataset"],
        "test_metrics": own["metrics"],
        "cross_lens": evaluated["cross_lens"],
    }
    path = records / f"{run.name}.json"
    atomic_write_text(path, json.dumps(record, indent=1) + "\n")
    score_held_out(run, path, threads)
    score_held_out_robustness(run, path, threads)
    return path


def score_held_out(run: StudyRun, path: Path, threads: int = 1) -> None:
    """Score the trained ``run`` on every test lens over :data:`HELD_OUT` and add that to its record at ``path``
    (``held_out``: the overrides, the evaluation's commit and command, the data's identity, ``cross_lens``)."""
    evaluated, evaluation = _evaluate(run.evaluate_argv(held_out=True), threads)
    record = json.loads(path.read_text(encoding="utf-8"))
    record["held_out"] = {
        "overrides": list(HELD_OUT),
        "evaluation": {**evaluation, "machine": machine()},
        "dataset": evaluated["dataset"],
        "cross_lens": evaluated["cross_lens"],
    }
    atomic_write_text(path, json.dumps(record, indent=1) + "\n")


def score_held_out_robustness(run: StudyRun, path: Path, threads: int = 1) -> None:
    """Score the trained ``run``'s robustness row over :data:`HELD_OUT` and add it to the ``held_out`` block of its
    record at ``path`` (``robustness``: the evaluation's commit and command, and the row with its flights). The
    quick start's 3 flights cannot tell one perturbation's direction from another; 32 can."""
    evaluated, evaluation = _evaluate(run.robustness_argv(), threads)
    record = json.loads(path.read_text(encoding="utf-8"))
    if evaluated["dataset"] != record["held_out"]["dataset"]:
        raise RuntimeError(
            f"{run.name}: the robustness row was scored on other data than the held-out lenses"
        )
    record["held_out"]["robustness"] = {
        "evaluation": {**evaluation, "machine": machine()},
        **evaluated["cross_lens"]["robustness"],
    }
    atomic_write_text(path, json.dumps(record, indent=1) + "\n")


def _evaluate(argv: list[str], threads: int) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run one scoring command (``threads`` threads); return its ``results.json`` and how it was made: the commit,
    the command (its output folder named relative to the run), the wall time and the threads."""
    env = {**os.environ, "OMP_NUM_THREADS": str(threads), "MKL_NUM_THREADS": str(threads)}
    start = time.time()
    subprocess.run(argv, cwd=REPO, env=env, check=True, stdout=subprocess.DEVNULL)
    folder = Path(argv[-1].removeprefix("out="))
    evaluated = json.loads((folder / "results.json").read_text(encoding="utf-8"))
    out = f"out=<run>/{folder.name}"
    evaluation = {
        "commit": git_commit(REPO),
        "command": ["python", *argv[1:-1], out],
        "wall_s": time.time() - start,
        "omp_num_threads": threads,
    }
    return evaluated, evaluation


def _provenance(commit: str, run: StudyRun, machine_name: str) -> dict[str, str]:
    """The record's provenance block: the commit that scored it, the study command that made it, the machine."""
    command = f"python scripts/lens_study.py --arms {run.arm} --tasks {run.task} --seeds {run.seed}"
    return {"commit": commit, "command": command, "machine": machine_name}


def upgrade_record(path: Path) -> bool:
    """Give a record written before its ``provenance`` block one, from its own fields (the evaluation's commit and
    machine); ``True`` when the file was rewritten. Nothing else changes."""
    record = json.loads(path.read_text(encoding="utf-8"))
    if record.get("format") != RECORD_FORMAT or "provenance" in record:
        return False
    run = StudyRun(record["arm"], record["task"], int(record["seed"]), Path("."))
    block = _provenance(record["evaluation"]["commit"], run, record["machine"])
    atomic_write_text(
        path, json.dumps({"format": RECORD_FORMAT, "provenance": block, **record}, indent=1) + "\n"
    )
    return True


# ------------------------------------------------------------------------------------------------- summary


def load_records(folder: str | Path) -> list[dict[str, Any]]:
    """The study's run records in ``folder`` (others ignored), by arm, task and seed."""
    return sorted(records_of_format(folder, RECORD_FORMAT), key=lambda r: (r["arm"], r["task"], r["seed"]))


def held_out_records(records: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The records scored over :data:`HELD_OUT`, each with that scoring as its ``cross_lens`` and ``dataset`` (what
    :func:`summarise` reads); ``ValueError`` when they were scored on different data."""
    held = [
        {**r, "cross_lens": _held_out_cross_lens(r["held_out"]), "dataset": r["held_out"]["dataset"]}
        for r in records
        if "held_out" in r
    ]
    if len({json.dumps(r["dataset"], sort_keys=True) for r in held}) > 1:
        raise ValueError("the records' held-out scorings come from different datasets")
    return held


#: The metrics each task's cells show (the issue's mIoU / δ1 / AbsRel).
CELL_METRICS = {"seg": ("mIoU",), "depth": ("delta1", "abs_rel"), "completion": ("delta1", "abs_rel")}
#: The metric the arms are compared on, per task: the first of its cells.
COMPARED = {task: metrics[0] for task, metrics in CELL_METRICS.items()}


def held_out_analysis(held: Sequence[Mapping[str, Any]]) -> tuple[dict, dict, dict]:
    """What the study reports of its :func:`held_out_records`: their :func:`summarise`, the arms compared lens by
    lens (:func:`~airfisheye_bench.studies.lens_contrasts.arm_contrasts`) and each arm's robustness row perturbation
    by perturbation (:func:`~airfisheye_bench.studies.lens_contrasts.robustness_changes`)."""
    return summarise(held), arm_contrasts(held, COMPARED), robustness_changes(held, COMPARED)


def _held_out_cross_lens(held_out: Mapping[str, Any]) -> dict[str, Any]:
    """The held-out scoring's ``cross_lens``, with its robustness row where the run has one."""
    rows = dict(held_out["cross_lens"])
    if "robustness" in held_out:
        rows["robustness"] = {k: v for k, v in held_out["robustness"].items() if k != "evaluation"}
    return rows


def summarise(records: Sequence[Mapping[str, Any]], level: float = 0.95) -> dict[str, Any]:
    """``{task: {arm: {"seeds", "lenses": {lens: {metric: {"values", "mean", "std"}, "gap": {metric: interval}},
    "robustness": {metric: {"values", "mean", "std"}}}}}``.

    A lens's gap is measured against the run's own lens(es) (``trained``) flight by flight on the seeds' mean of each
    flight's score, with a t-interval over the flights and a Bonferroni family of the arm's test lenses.
    """
    out: dict[str, Any] = {}
    for record in records:
        task = out.setdefault(record["task"], {})
        arm = task.setdefault(record["arm"], {"seeds": [], "runs": []})
        arm["seeds"].append(record["seed"])
        arm["runs"].append(record)
    for task_name, arms in out.items():
        spec = get_task(task_name)
        for name, arm in arms.items():
            arms[name] = _arm_summary(spec, arm["seeds"], arm["runs"], level)
    return out


def _arm_summary(spec: Any, seeds: list[int], runs: list[Mapping[str, Any]], level: float) -> dict[str, Any]:
    metrics = CELL_METRICS[spec.name]
    names = list(dict.fromkeys(row["name"] for r in runs for row in r["cross_lens"]["lenses"]))
    own_name = (
        "trained"
        if any(row["name"] == "trained" for r in runs for row in r["cross_lens"]["lenses"])
        else names[0]
    )
    family = max(1, len(names) - 1)
    lenses: dict[str, Any] = {}
    for name in names:
        rows = [_row(r, name) for r in runs]
        rows = [row for row in rows if row is not None]
        cell: dict[str, Any] = {"seen": any(row.get("seen") for row in rows)}
        for metric in metrics:
            cell[metric] = _mean_std([row["metrics"].get(metric) for row in rows])
        if name != own_name:
            cell["pooled_gap"] = {
                metric: _mean_std([(row.get("gap") or {}).get(metric) for row in rows]) for metric in metrics
            }
            cell["gap"] = {
                metric: _flight_gap(spec, runs, own_name, name, metric, family, level) for metric in metrics
            }
        lenses[name] = cell
    robustness = {
        metric: _mean_std(
            [
                r["cross_lens"]["robustness"]["largest_change"].get(metric)
                for r in runs
                if "robustness" in r["cross_lens"]
            ]
        )
        for metric in metrics
    }
    return {"seeds": sorted(seeds), "lenses": lenses, "robustness": robustness, "own": own_name}


def _row(record: Mapping[str, Any], name: str) -> Mapping[str, Any] | None:
    return next((row for row in record["cross_lens"]["lenses"] if row["name"] == name), None)


def _mean_std(values: Sequence[float | None]) -> dict[str, Any]:
    finite = [float(v) for v in values if v is not None and math.isfinite(v)]
    n = len(finite)
    mean = sum(finite) / n if n else math.nan
    std = math.sqrt(sum((v - mean) ** 2 for v in finite) / (n - 1)) if n > 1 else math.nan
    return {"values": finite, "n": n, "mean": mean, "std": std}


def _flight_gap(
    spec: Any, runs: Sequence[Mapping[str, Any]], own: str, other: str, metric: str, family: int, level: float
) -> dict[str, Any]:
    """The gap of ``metric`` from lens ``own`` to ``other``, one value per test flight (its seeds' mean score on
    each lens first), with its interval over the flights."""
    higher = spec.column(metric).higher_is_better if spec.column(metric) else False

    mine, theirs = flight_scores(runs, own, metric), flight_scores(runs, other, metric)
    gaps = {f: cross_lens_gap(mine[f], theirs[f], higher) for f in sorted(mine.keys() & theirs.keys())}
    gaps = {f: g for f, g in gaps.items() if math.isfinite(g)}
    if not gaps:
        return {"n": 0}
    return cluster_difference(gaps, family_size=family, level=level)


# ------------------------------------------------------------------------------------------------- report

#: The markers of the generated block in ``docs/results.md`` (rewritten by ``scripts/lens_study.py --report``).
REPORT_BEGIN = "<!-- lens-study:begin (python scripts/lens_study.py --summary docs/figures/lens_study/summary.json --report docs/results.md) -->"
REPORT_END = "<!-- lens-study:end -->"


def report_block(
    summary: Mapping[str, Any],
    source: str = "figures/lens_study/summary.json",
    held: Mapping[str, Any] | None = None,
    contrasts: Mapping[str, Any] | None = None,
    robustness: Mapping[str, Any] | None = None,
) -> str:
    """The study's tables as markdown: first, where there are any, the scores over :data:`HELD_OUT`'s flights
    (``held``: per task and metric the arms by test lens, then the cross-lens gap with its family interval over the
    flights; ``contrasts``: :func:`~airfisheye_bench.studies.lens_contrasts.arm_contrasts` of the same records;
    ``robustness``: :func:`~airfisheye_bench.studies.lens_contrasts.robustness_changes` of them),
    then the same on the quick start's own test split with the robustness row."""
    lines = [f"Generated from [`{source}`]({source}) (each run's record: `figures/lens_study/runs/`)."]
    if held:
        lines += [
            "",
            f"##### Over 32 held-out test flights (`{' '.join(HELD_OUT)}`; `held_out` in `{source}`)",
        ]
        lines += _task_tables(held, f"{source}, held_out", robustness=False)
        lines += contrast_lines(contrasts or {}, METRIC_LABELS, f"{source}, held_out.contrasts")
        titles = {name: arm.title for name, arm in ARMS.items()}
        largest = {
            task: {name: _pm(arm["robustness"][COMPARED[task]]) for name, arm in arms.items()}
            for task, arms in held.items()
        }
        lines += robustness_lines(
            robustness or {}, METRIC_LABELS, titles, f"{source}, held_out.robustness", largest
        )
        lines += ["", "##### On the quick start's own test split (3 flights), with the robustness row"]
    lines += _task_tables(summary, source, robustness=True)
    return "\n".join(lines)


def _task_tables(summary: Mapping[str, Any], source: str, robustness: bool) -> list[str]:
    lines: list[str] = []
    for task, arms in summary.items():
        for metric in CELL_METRICS[task]:
            lines += [
                "",
                f"**{task}, {METRIC_LABELS[metric]}** (mean ± std over the seeds; ★ a lens the arm trained on; `{source}`)",
                "",
            ]
            lines += _table(arms, metric, _cell_value)
        metric = CELL_METRICS[task][0]
        lines += [
            "",
            f"**{task}, cross-lens gap of {METRIC_LABELS[metric]}** (1 − lens / own for δ1 and mIoU: the fraction lost "
            "off the training lens(es). First the gap of the whole test split's score, mean over the seeds; in "
            "parentheses the mean of the per-flight gaps of the seeds' mean scores, its 95 % interval over the "
            f"flights Bonferroni-corrected over the arm's test lenses, and the flights; `{source}`)",
            "",
        ]
        lines += _table(arms, metric, _cell_gap, skip_own=True)
        if not robustness:
            continue
        lines += [
            "",
            f"**{task}, robustness row**: largest change of {METRIC_LABELS[metric]} under focal ±2 %, principal "
            f"point ±1 % of the width (x, y), first distortion term ±5 % (mean ± std over the seeds; `{source}`)",
            "",
        ]
        lines += ["| arm | seeds | largest change |", "|---|---:|---:|"]
        for name, arm in arms.items():
            lines.append(
                f"| {name}: {ARMS[name].title} | {len(arm['seeds'])} | {_pm(arm['robustness'][metric])} |"
            )
    return lines


def _table(arms: Mapping[str, Any], metric: str, cell, skip_own: bool = False) -> list[str]:
    names = list(
        dict.fromkeys(n for arm in arms.values() for n in arm["lenses"] if not (skip_own and n == arm["own"]))
    )
    lines = ["| arm | seeds | " + " | ".join(names) + " |", "|---|---:|" + "---:|" * len(names)]
    for name, arm in arms.items():
        cells = [cell(arm["lenses"].get(lens), metric) for lens in names]
        lines.append(f"| {name}: {ARMS[name].title} | {len(arm['seeds'])} | " + " | ".join(cells) + " |")
    return lines


def _pm(stat: Mapping[str, Any]) -> str:
    if not stat or not stat.get("n"):
        return "–"
    std = stat["std"]
    return f"{stat['mean']:.3f}" + (f" ± {std:.3f}" if std is not None and math.isfinite(std) else "")


def _cell_value(lens: Mapping[str, Any] | None, metric: str) -> str:
    if lens is None:
        return "–"
    return _pm(lens[metric]) + (" ★" if lens.get("seen") else "")


def _cell_gap(lens: Mapping[str, Any] | None, metric: str) -> str:
    pooled = (lens or {}).get("pooled_gap", {}).get(metric)
    gap = (lens or {}).get("gap", {}).get(metric)
    if not pooled or not pooled.get("n"):
        return "–"
    text = _pm(pooled).replace(" ± ", " ± ", 1)
    if gap and gap.get("n"):
        low, high = (x if x is not None else math.nan for x in gap.get("ci_family", [math.nan, math.nan]))
        interval = f" [{low:+.3f}, {high:+.3f}]" if math.isfinite(low) and math.isfinite(high) else ""
        text += f" ({gap['mean']:+.3f}{interval}, {gap['n']})"
    return text


# ------------------------------------------------------------------------------------------------- command


def _clean_checkout() -> None:
    """Refuse to train or score from code that no commit holds (a result names the commit that made it)."""
    dirty = subprocess.run(
        ["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO, capture_output=True, text=True
    ).stdout.strip()
    if dirty:
        raise SystemExit(f"lens study: the checkout has uncommitted changes; commit them first:\n{dirty}")


def _commit_record(path: Path) -> None:
    """Commit one run's record as soon as it exists: a study accumulates across sessions."""
    subprocess.run(["git", "add", str(path)], cwd=REPO, check=True)
    message = f"Lens study: record of {path.stem} (python scripts/lens_study.py)"
    subprocess.run(["git", "commit", "-q", "-m", message, "--", str(path)], cwd=REPO, check=True)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="logs/lens_study", help="where the runs are trained")
    parser.add_argument(
        "--record", default="docs/figures/lens_study/runs", help="where each run's record goes"
    )
    parser.add_argument("--arms", default="a,b,c,d")
    parser.add_argument("--tasks", default=",".join(TASKS))
    parser.add_argument("--seeds", default=",".join(map(str, SEEDS)))
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--commit", action="store_true", help="git-commit each record as it is written")
    parser.add_argument("--summary", help="write the summary of the records here (no training)")
    parser.add_argument(
        "--report", help="with --summary: rewrite the study's generated block of this markdown file"
    )
    args = parser.parse_args(argv)
    records = Path(args.record)
    if args.summary:
        for path in sorted(records.glob("*.json")):
            upgrade_record(path)
        runs = load_records(records)
        summary = summarise(runs)
        datasets = {json.dumps(r["dataset"], sort_keys=True) for r in runs}
        if len(datasets) > 1:
            raise SystemExit(
                f"lens study: the records in {records} come from different datasets: {sorted(datasets)}"
            )
        held = held_out_records(runs)
        held_summary, contrasts, robustness = held_out_analysis(held)
        record = {
            "format": "airfisheye-bench/lens-study-summary/v1",
            "provenance": provenance("scripts/lens_study.py", argv if argv is not None else sys.argv[1:]),
            "dataset": runs[0]["dataset"] if runs else None,
            "records": [f"{r['arm']}_{r['task']}_seed{r['seed']}.json" for r in runs],
            "tasks": json_safe(summary),
            "held_out": {
                "overrides": list(HELD_OUT),
                "dataset": held[0]["dataset"] if held else None,
                "records": [f"{r['arm']}_{r['task']}_seed{r['seed']}.json" for r in held],
                "tasks": json_safe(held_summary),
                "contrasts": json_safe(contrasts),
                "robustness": json_safe(robustness),
            },
        }
        atomic_write_text(Path(args.summary), json.dumps(record, indent=1, allow_nan=False) + "\n")
        if args.report:
            report = Path(args.report)
            block = report_block(summary, held=held_summary, contrasts=contrasts, robustness=robustness)
            text = replace_block(report.read_text(encoding="utf-8"), block, REPORT_BEGIN, REPORT_END)
            atomic_write_text(report, text)
        return
    _clean_checkout()
    records.mkdir(parents=True, exist_ok=True)
    runs = plan(
        args.out, args.arms.split(","), args.tasks.split(","), [int(s) for s in args.seeds.split(",")]
    )
    for run in runs:
        path = records / f"{run.name}.json"
        if path.is_file():  # a record from before a scoring was added to the study: that scoring, if it can
            held_out = json.loads(path.read_text(encoding="utf-8")).get("held_out")
            if run.run_dir.is_dir() and (held_out is None or "robustness" not in held_out):
                print(f"score {run.name} over the held-out flights", file=sys.stderr, flush=True)
                if held_out is None:
                    score_held_out(run, path, args.threads)
                score_held_out_robustness(run, path, args.threads)
                if args.commit:
                    _commit_record(path)
            continue
        if not (run.trained.is_file() and json.loads(run.trained.read_text())["rc"] == 0):
            print(f"train {run.name}", file=sys.stderr, flush=True)
            train(run, args.threads)
        print(f"score {run.name}", file=sys.stderr, flush=True)
        path = score(run, records, args.threads)
        if args.commit:
            _commit_record(path)
