"""Completion ablation of the occlusion correction: train and test NLSPN per (method, seed), report mean ± std.

For every sparse input (default: every one of ``airfisheye_bench.geometry.occlusion.SPARSE_INPUTS``, read when the
script runs: the occlusion methods and ``oracle``, the generator's exact visibility) and every seed, one run of

    python train.py task=completion data.occlusion=<method> seed=<seed> hydra.run.dir=<out>/<method>/seed<seed> \\
        <overrides...>

(``trainer.deterministic=true`` comes first, so seed ``s`` of every arm starts from the same weights and sees the
same data order). ``train.py`` builds the sparse input of training *and* test with that method, tests the best
checkpoint on the test split and writes ``results.json``; this script then scores that checkpoint with its own
input on the regions where the methods differ (``regions.json``: the pixels whose input differs between ``none``
and the oracle, dilated by ``--radius``, and the near range below ``--near`` m; see
:mod:`airfisheye_bench.metrics.regions`), collects both and reports per method the mean ± sample standard
deviation over the seeds, and per method the paired difference against ``none`` seed by seed with its 95 %
t-interval (:mod:`airfisheye_bench.studies.paired`). Runs whose ``results.json`` / ``regions.json`` exist are
skipped, so an interrupted ablation resumes; a failed run stops the script.

    python scripts/occlusion_ablation.py --out runs/ablation_occlusion --seeds 0 1 2 3 4 -- \\
        data.preset=occlusion data.source=fisheye data.camera.size=256 trainer.max_epochs=5
    python scripts/occlusion_ablation.py --out runs/ablation_occlusion --collect-only --json ablation.json

Everything after ``--`` is passed to ``train.py`` as is (Hydra overrides).

With ``--record DIR`` each finished run also leaves its record in ``DIR`` (``<method>_seed<s>.json``,
:mod:`airfisheye_bench.studies.ablation_records`: commit, command, data identity, validation curve, per-frame
scores on every region, the method-neutral ``changed`` one included), ``--commit-records`` commits it to git at
once, and ``--collect-only --record DIR`` summarises the records alone, with the test flight as the unit and a
Holm correction over the family; with ``--json FILE --report REPORT.md`` the summary is written and the report's
generated block (its runs, the arms' means, the paired comparisons) rewritten from it. A run is refused when the
checkout has uncommitted changes (a result is never trained from code that no commit holds); ``--allow-dirty`` is
for trying the tool.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from airfisheye_bench.atomic import atomic_write_json, atomic_write_text
from airfisheye_bench.geometry import occlusion
from airfisheye_bench.metrics.regions import DEFAULT_NEAR_M, DEFAULT_RADIUS_PX
from airfisheye_bench.studies import ablation_records
from airfisheye_bench.studies.ablation_records import mean_std
from airfisheye_bench.studies.crossover import run_frame_scores, run_region_scores
from airfisheye_bench.studies.generated_blocks import replace_block
from airfisheye_bench.studies.paired import paired_differences, paired_table
from airfisheye_bench.studies.provenance import git_commit, provenance
from airfisheye_bench.studies.segments import resume_argv, segments_path, train_in_segments

# The checkout this package sits in: the ablation drives its train.py (studies run from a checkout).
REPO = Path(__file__).resolve().parents[2]
#: Metrics of the table, in this order (others in results.json are kept in the JSON).
TABLE_METRICS = ("rmse", "mae", "abs_rel", "delta1", "affected/rmse", "near/rmse")
#: Metrics of the paired table (``region/metric`` from ``regions.json``).
PAIRED_METRICS = (
    "rmse",
    "abs_rel",
    "affected/rmse",
    "affected/mae",
    "affected/abs_rel",
    "near/rmse",
    "near/abs_rel",
)
REGION_METRICS = ("rmse", "mae", "abs_rel", "delta1")


@dataclass(frozen=True)
class Run:
    """One training run of the ablation."""

    method: str
    seed: int
    out: Path

    @property
    def results(self) -> Path:
        return self.out / "results.json"

    @property
    def regions(self) -> Path:
        return self.out / "regions.json"

    def argv(self, overrides: Sequence[str]) -> list[str]:
        """The ``train.py`` command line (Hydra overrides; ours first, so the caller's cannot move the run)."""
        return [
            sys.executable,
            str(REPO / "train.py"),
            "task=completion",
            f"data.occlusion={self.method}",
            f"seed={self.seed}",
            "trainer.deterministic=true",
            *overrides,
            f"hydra.run.dir={self.out}",
        ]


def plan(out: Path, methods: Sequence[str], seeds: Sequence[int]) -> list[Run]:
    """Every (method, seed) run, each in ``<out>/<method>/seed<seed>``, seed-major: an ablation stopped early
    has the same seeds for every method, so what it has is comparable."""
    unknown = [m for m in methods if m not in occlusion.SPARSE_INPUTS]
    if unknown:
        raise ValueError(f"--methods: unknown {unknown}; available: {', '.join(occlusion.SPARSE_INPUTS)}")
    return [Run(m, int(s), out / m / f"seed{int(s)}") for s in seeds for m in methods]


def execute(
    runs: Sequence[Run],
    overrides: Sequence[str],
    runner: Callable[[list[str]], None],
    after: Callable[[Run], None] | None = None,
    allow_dirty: bool = True,
) -> None:
    """Train every run that has no ``results.json`` yet; ``after(run)`` once each has finished (or was found
    finished). A run with a ``last.ckpt`` and no results was killed (a session's end): it is resumed exactly
    (``ckpt_path=last``). Each segment's commit (taken when it starts) and wall time are kept beside the run
    (``seed<s>.segments.json``), and the run's commit, command and wall time go to ``<run>/provenance.json``."""
    for k, run in enumerate(runs, 1):
        if run.results.is_file():
            print(f"[{k}/{len(runs)}] {run.method} seed {run.seed}: done already", file=sys.stderr)
        else:
            commit = git_commit(REPO)
            if commit.endswith("+dirty") and not allow_dirty:
                raise SystemExit(
                    f"{REPO}: uncommitted changes; a study run must train from a commit (commit them, or "
                    "--allow-dirty to try the tool)"
                )
            argv = run.argv(overrides)
            command = " ".join(["python", *(Path(a).name if a == argv[1] else a for a in argv[1:])])
            resumed = segments_path(run.out).is_file() or resume_argv(argv, run.out) != argv
            print(
                f"[{k}/{len(runs)}] {run.method} seed {run.seed}" + (" (resumed)" if resumed else ""),
                file=sys.stderr,
            )
            # A run killed and resumed (ckpt_path=last: exact on one CPU process) trained in several segments.
            trained, _ = train_in_segments(argv, run.out, commit, runner)
            record = {**trained, "command": command}
            atomic_write_text(run.out / "provenance.json", json.dumps(record, indent=2) + "\n")
        if after is not None:
            after(run)


def write_record(
    run: Run,
    folder: Path,
    commit_it: bool = False,
    frame_scorer: Callable[[Path], dict[str, Any]] = run_frame_scores,
) -> Path | None:
    """Score a finished run per frame (``frames.json`` in the run) and write its record into ``folder``
    (:func:`~airfisheye_bench.studies.ablation_records.build_record`); with ``commit_it``, commit it."""
    target = folder / f"{run.method}_seed{run.seed}.json"
    if target.is_file() or not run.results.is_file():
        return None
    frames_path = run.out / "frames.json"
    if not frames_path.is_file():
        print(f"frames: {run.method} seed {run.seed}", file=sys.stderr)
        atomic_write_text(frames_path, json.dumps(frame_scorer(run.out), indent=1) + "\n")
    frames = json.loads(frames_path.read_text(encoding="utf-8"))
    results = json.loads(run.results.read_text(encoding="utf-8"))
    prov_path = run.out / "provenance.json"
    prov = json.loads(prov_path.read_text(encoding="utf-8")) if prov_path.is_file() else {}
    prov.setdefault("commit", "unknown")
    prov["scored_by"] = git_commit(REPO)
    primary = f"val/{results.get('primary_metric', 'rmse')}"
    curve = ablation_records.validation_curve(run.out / "metrics.csv", primary)
    record = ablation_records.build_record(
        run.method, run.seed, prov, results, frames, curve, prov.pop("wall_s", None)
    )
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(target, json.dumps(record, indent=1, allow_nan=False) + "\n")
    if commit_it:
        _git_commit_file(target, f"Occlusion ablation: the record of {run.method} seed {run.seed}")
    return target


def _git_commit_file(path: Path, message: str) -> None:
    """Commit ``path`` alone (other staged or unstaged changes stay as they are); retried while git is busy."""
    for attempt in range(10):
        added = subprocess.run(
            ["git", "add", "--", str(path)], cwd=path.parent, capture_output=True, text=True
        )
        done = added.returncode == 0 and (
            subprocess.run(
                ["git", "commit", "-q", "-m", message, "--only", "--", str(path)],
                cwd=path.parent,
                capture_output=True,
                text=True,
            ).returncode
            == 0
        )
        if done:
            return
        time.sleep(2 + attempt)
    print(f"could not commit {path}: commit it by hand", file=sys.stderr)


def run_subprocess(argv: list[str]) -> None:
    subprocess.run(argv, check=True, cwd=REPO)


def score_regions(runs: Sequence[Run], scorer: Callable[[Path], dict[str, Any]]) -> None:
    """Write ``regions.json`` for every trained run that has none yet."""
    for run in runs:
        if run.results.is_file() and not run.regions.is_file():
            print(f"regions: {run.method} seed {run.seed}", file=sys.stderr)
            atomic_write_text(run.regions, json.dumps(scorer(run.out), indent=2) + "\n")


def collect(runs: Sequence[Run]) -> dict[str, dict[str, Any]]:
    """``method -> {"seeds": [...], "metrics": {name: {"values", "mean", "std", "n"}}}`` from the finished runs."""
    out: dict[str, dict[str, Any]] = {
        m: {"seeds": [], "values": {}} for m in dict.fromkeys(r.method for r in runs)
    }
    for run in runs:
        if not run.results.is_file():
            continue
        record = json.loads(run.results.read_text(encoding="utf-8"))
        entry = out[run.method]
        entry["seeds"].append(run.seed)
        for name, value in run_metrics(run, record).items():
            entry["values"].setdefault(name, []).append(value)
    return {
        method: {
            "seeds": entry["seeds"],
            "metrics": {name: {"values": v, **mean_std(v)} for name, v in entry["values"].items()},
        }
        for method, entry in out.items()
        if entry["seeds"]
    }


def run_metrics(run: Run, record: dict[str, Any] | None = None) -> dict[str, float]:
    """A finished run's numeric test metrics, and ``region/metric`` from its ``regions.json`` where it has one."""
    if record is None:
        record = json.loads(run.results.read_text(encoding="utf-8"))
    out = {
        name: float(value)
        for name, value in record["metrics"].items()
        if isinstance(value, int | float) and not isinstance(value, bool)
    }
    if run.regions.is_file():
        regions = json.loads(run.regions.read_text(encoding="utf-8"))["regions"]
        for region, values in regions.items():
            if region == "all":
                continue  # the whole image: results.json's own metrics
            for name in REGION_METRICS:
                if values.get(name) is not None:
                    out[f"{region}/{name}"] = float(values[name])
    return out


def paired(runs: Sequence[Run], reference: str = "none") -> dict[str, Any]:
    """Paired differences against ``reference`` per seed (:func:`~airfisheye_bench.studies.paired.paired_differences`)."""
    values: dict[str, dict[int, dict[str, float]]] = {}
    for run in runs:
        if run.results.is_file():
            values.setdefault(run.method, {})[run.seed] = run_metrics(run)
    if reference not in values:
        return {}
    return paired_differences(values, reference)


def markdown_table(summary: dict[str, dict[str, Any]], metrics: Sequence[str] = TABLE_METRICS) -> str:
    """One row per method: ``mean ± std`` of each metric over its seeds."""
    present = [m for m in metrics if any(m in s["metrics"] for s in summary.values())]
    lines = [
        "| sparse input | seeds | " + " | ".join(present) + " |",
        "|---|---|" + "---:|" * len(present),
    ]
    for method, entry in summary.items():
        cells = []
        for name in present:
            stat = entry["metrics"].get(name)
            if stat is None:
                cells.append("-")
            elif math.isnan(stat["std"]):  # one seed: no spread to show
                cells.append(f"{stat['mean']:.4f}")
            else:
                cells.append(f"{stat['mean']:.4f} ± {stat['std']:.4f}")
        seeds = ",".join(str(s) for s in entry["seeds"])
        lines.append(f"| `{method}` | {seeds} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def parse_args(argv: Sequence[str] | None) -> tuple[argparse.Namespace, list[str]]:
    argv = list(sys.argv[1:] if argv is None else argv)
    overrides: list[str] = []
    if "--" in argv:
        cut = argv.index("--")
        argv, overrides = argv[:cut], argv[cut + 1 :]
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="folder of the runs (<out>/<method>/seed<s>)")
    parser.add_argument(
        "--methods",
        type=lambda v: [m for m in v.split(",") if m],
        help="comma-separated sparse inputs (default: every one of SPARSE_INPUTS, the oracle included)",
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--collect-only", action="store_true", help="train nothing, summarise what is there")
    parser.add_argument("--json", type=Path, help="write the summary here")
    parser.add_argument(
        "--no-regions", action="store_true", help="skip the per-region scoring (regions.json)"
    )
    parser.add_argument(
        "--radius", type=int, default=DEFAULT_RADIUS_PX, help="dilation of the affected pixels"
    )
    parser.add_argument("--near", type=float, default=DEFAULT_NEAR_M, help="near-range bound in metres")
    parser.add_argument("--record", type=Path, help="folder of the per-run records (and their summary)")
    parser.add_argument(
        "--commit-records", action="store_true", help="git-commit each record as it is written"
    )
    parser.add_argument(
        "--report",
        type=Path,
        help="with --record and --json: rewrite the summary's generated block in this Markdown file",
    )
    parser.add_argument(
        "--allow-dirty", action="store_true", help="train even with uncommitted changes (not for results)"
    )
    return parser.parse_args(argv), overrides


def main(
    argv: Sequence[str] | None = None,
    runner: Callable[[list[str]], None] = run_subprocess,
    scorer: Callable[[Path], dict[str, Any]] | None = None,
    frame_scorer: Callable[[Path], dict[str, Any]] = run_frame_scores,
) -> dict[str, Any]:
    args, overrides = parse_args(argv)
    methods = args.methods or list(occlusion.SPARSE_INPUTS)
    runs = plan(args.out, methods, args.seeds)
    if args.record is not None:
        if not args.collect_only:
            after = lambda run: write_record(run, args.record, args.commit_records, frame_scorer)  # noqa: E731
            execute(runs, overrides, runner, after=after, allow_dirty=args.allow_dirty)
        return summarise_records(args, argv)
    if not args.collect_only:
        execute(runs, overrides, runner)
        if not args.no_regions:
            score_regions(
                runs, scorer or (lambda out: run_region_scores(out, radius=args.radius, near_m=args.near))
            )
    summary = collect(runs)
    if not summary:
        raise SystemExit(f"no results.json under {args.out}: nothing to summarise")
    print(markdown_table(summary))
    differences = paired(runs)
    if differences:
        print("\nPaired differences against `none` (same seed), mean [95 % t-interval]:\n")
        print(paired_table(differences, PAIRED_METRICS))
    payload = {
        "out": str(args.out),
        "methods": methods,
        "seeds": args.seeds,
        "overrides": overrides,
        "command": "python scripts/occlusion_ablation.py " + " ".join(sys.argv[1:] if argv is None else argv),
        "results": summary,
        "paired_vs_none": differences,
    }
    if args.json is not None:
        atomic_write_json(args.json, payload)  # NaN (one seed) -> null
    return payload


def summarise_records(args: argparse.Namespace, argv: Sequence[str] | None) -> dict[str, Any]:
    """The records' summary (:func:`~airfisheye_bench.studies.ablation_records.summarise`), printed and, with
    ``--json``, written with its provenance."""
    records = ablation_records.load_records(args.record)
    if not records:
        raise SystemExit(f"no run records under {args.record}: nothing to summarise")
    summary = ablation_records.summarise(records)
    print(ablation_records.runs_table(summary["runs"]) + "\n")
    print(ablation_records.summary_tables(summary))
    payload = {
        "provenance": provenance("scripts/occlusion_ablation.py", argv),
        "records": sorted(f"{r['method']}_seed{r['seed']}.json" for r in records),
        "record_commits": sorted({r["provenance"]["commit"] for r in records}),
        "datasets": sorted({(r.get("dataset") or {}).get("content_sha256", "unknown") for r in records}),
        **summary,
    }
    if args.json is not None:
        atomic_write_json(args.json, payload)
    if args.report is not None:
        write_report(args.report, payload, args.json)
    return payload


def write_report(report: Path, summary: dict[str, Any], source: Path | None) -> None:
    """Replace the generated block of ``report`` (:func:`~airfisheye_bench.studies.ablation_records.report_block`)
    with the summary's, its link relative to the report; the report must already hold the markers."""
    if source is None:
        raise SystemExit("--report needs --json: the block links the summary file it shows")
    try:
        text = report.read_text(encoding="utf-8")
    except OSError as error:
        raise SystemExit(f"--report {report}: {error.strerror}") from None
    link = Path(os.path.relpath(source.resolve(), report.resolve().parent)).as_posix()
    try:
        text = replace_block(
            text,
            ablation_records.report_block(summary, link),
            ablation_records.REPORT_BEGIN,
            ablation_records.REPORT_END,
        )
    except ValueError:
        raise SystemExit(
            f"--report {report}: no generated block to rewrite; expected the lines\n"
            f"{ablation_records.REPORT_BEGIN}\n{ablation_records.REPORT_END}"
        ) from None
    atomic_write_text(report, text)
