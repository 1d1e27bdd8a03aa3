"""Evaluation from prediction files: wall time of ``evaluate_predictions`` over N frames (default 1000 at 512^2).

What is timed is the whole evaluation loop of a prediction folder, as ``scripts/evaluate.py predictions=DIR`` runs
it: a ``FilePredictor`` (the folder validated against the frame ids first, timed separately) and
``evaluate_predictions(..., batch_size=8, num_workers=2, num_panels=0)``, i.e. DataLoader workers decoding each
frame's ground truth (``AirFisheyeDataset``, pre-rendered ``fisheye`` source) and its prediction file, and the main
process scoring every batch with the task metric plus its incidence-angle rings (and, for depth, ground-truth
ranges).

The data: a synthetic dataset whose pre-rendered fisheye is ``--size``^2 (the ``tiny`` preset with
``fisheye_size=<size>`` and small cube faces, generated once under ``--data``; or any dataset given by ``--root``).
It has only a few distinct frames, so the evaluation set repeats the frames of all its splits (evaluation form, no
augmentation) up to ``--frames``; each repetition has its own ``sample_id`` (``rep0007/<env>_<traj>/<frame>``), so
every evaluated frame decodes its ground-truth files and its own prediction file (the files are in the page cache:
a warm-cache measurement). The prediction folders (seg: 8-bit label PNGs, the ground truth with ~10% of the
pixels relabelled; depth: 16-bit PNGs, or ``.npy``, of the ground truth times log-normal noise) are written once
with ``SubmissionWriter`` and cached under ``--data`` (not timed).

Besides the loop (best of ``--repeat``), the table splits the cost per frame, measured separately in the main
process on ``--parts-frames`` frames: ground-truth load (``dataset[i]``) and prediction decode (``read_prediction``)
on one torch thread like a loader worker, and the metric updates (``TaskScorer.update`` on collated batches) with the
main process's threads.

    python scripts/bench_evaluate.py                                # 1000 frames at 512^2, seg and depth
    python scripts/bench_evaluate.py --frames 200 --tasks depth --depth-format npy
    python scripts/bench_evaluate.py --write-docs                   # also update docs/benchmarks.md
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import shlex
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from airfisheye_bench.evaluation.evaluator import evaluate_predictions
from airfisheye_bench.evaluation.predictors import FilePredictor
from airfisheye_bench.evaluation.submission import SubmissionWriter, read_prediction
from airfisheye_bench.io import EmptySplitError
from airfisheye_bench.metrics import DEFAULT_DEPTH_EDGES_M
from airfisheye_bench.metrics.scorer import TaskScorer
from airfisheye_bench.specs import get_task
from airfisheye_bench.synth.cli import build_config
from airfisheye_bench.synth.writer import generate_dataset
from datamodules.dataset import AirFisheyeDataset, CameraConfig, collate

# The checkout this package sits in (benchmarks run from one): its docs/benchmarks.md gets the tables.
ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs" / "benchmarks.md"
SECTION = "## Evaluation from prediction files"
BEFORE = "## Metrics"
TASKS = ("seg", "depth")
SPLITS = ("train", "val", "test")
#: Cube faces of the generated dataset: the benchmark serves the pre-rendered fisheye, so they stay small.
FACE_SIZE = 32
#: Share of the pixels a seg prediction relabels; spread of the log-normal noise of a depth prediction.
SEG_ERROR_RATE = 0.1
DEPTH_NOISE_SIGMA = 0.1


# ---------------------------------------------------------------------------------------------------- data
def ensure_bench_dataset(data_dir: Path, size: int, seed: int = 0, workers: int = 2) -> Path:
    """The ``tiny`` preset with a ``size``^2 ray-cast fisheye, generated once into ``data_dir``."""
    config = build_config("tiny", {"fisheye_size": size, "face_size": FACE_SIZE})
    root = Path(data_dir) / f"tiny-fisheye{size}-seed{seed}"
    return generate_dataset(config, root, seed=seed, workers=workers, progress=False)


class RepeatedFrames(Dataset):
    """The frames of ``bases`` (one dataset per split) repeated to ``frames`` samples, each with a unique id.

    Sample ``i`` is frame ``i % n`` of the concatenated splits, served under the id
    ``rep<i // n>/<env>_<trajectory>/<frame>``, so a submission holds one file per sample.
    """

    def __init__(self, bases: Sequence[AirFisheyeDataset], frames: int) -> None:
        if frames < 1:
            raise ValueError(f"frames must be >= 1, got {frames}")
        self.bases = list(bases)
        self.index = [(b, j) for b, base in enumerate(self.bases) for j in range(len(base))]
        n = len(self.index)
        self.sample_ids = [f"rep{i // n:04d}/{self._flat(self.base_id(i))}" for i in range(frames)]
        self.camera = self.bases[0].camera

    @staticmethod
    def _flat(sample_id: str) -> str:
        *traj, frame = sample_id.split("/")
        return f"{'_'.join(traj)}/{frame}"

    @property
    def num_distinct(self) -> int:
        return len(self.index)

    def base_id(self, i: int) -> str:
        b, j = self.index[i % len(self.index)]
        return self.bases[b].sample_ids[j]

    def __len__(self) -> int:
        return len(self.sample_ids)

    def __getitem__(self, i: int) -> dict | None:
        b, j = self.index[i % len(self.index)]
        sample = self.bases[b][j]
        if sample is not None:
            sample["sample_id"] = self.sample_ids[i]
        return sample


def evaluation_set(root: Path, task: str, size: int, frames: int) -> RepeatedFrames:
    """Every split of ``root`` in its evaluation form (fisheye source, no augmentation), repeated to ``frames``."""
    bases = []
    for split in SPLITS:
        try:
            bases.append(
                AirFisheyeDataset.from_root(
                    root, split, task, source="fisheye", camera=CameraConfig(size=size)
                )
            )
        except EmptySplitError:  # a split the generated data left empty
            continue
    if not bases:
        raise ValueError(f"{root} has no frames")
    return RepeatedFrames(bases, frames)


def fake_prediction(task: str, sample: dict, rng: np.random.Generator, num_classes: int) -> np.ndarray:
    """A plausible prediction of one frame from its ground truth."""
    if get_task(task).uses_classes:
        label = sample["label"].numpy()
        wrong = rng.random(label.shape) < SEG_ERROR_RATE
        return np.where(wrong, rng.integers(0, num_classes, label.shape), label).astype(np.uint8)
    depth = sample["depth"].numpy()[0]
    return (depth * rng.lognormal(0.0, DEPTH_NOISE_SIGMA, depth.shape)).astype(np.float32)


def ensure_predictions(
    folder: Path, dataset: RepeatedFrames, task: str, depth_format: str, seed: int = 0
) -> Path:
    """Write (once) a prediction folder with one file per sample of ``dataset``; reused when it exists."""
    if folder.is_dir():
        return folder
    num_classes = dataset.bases[0].spec.num_train_classes
    cache: dict[int, dict] = {}
    with SubmissionWriter(folder, task, depth_format=depth_format) as writer:
        for i, sample_id in enumerate(dataset.sample_ids):
            k = i % dataset.num_distinct
            if k not in cache:
                cache[k] = dataset[k]
            rng = np.random.default_rng([seed, i])
            writer.add(sample_id, fake_prediction(task, cache[k], rng, num_classes))
    return folder


def make_scorer(task: str, dataset: RepeatedFrames) -> TaskScorer:
    """The scorer ``scripts/evaluate.py`` builds for a prediction folder."""
    spec = get_task(task)
    class_names = dataset.bases[0].spec.train_class_names if spec.uses_classes else None
    factory = partial(spec.make_metric, class_names=class_names, max_depth=dataset.bases[0].max_depth)
    return TaskScorer(factory, depth_edges_m=DEFAULT_DEPTH_EDGES_M if spec.depth_breakdown else None)


# ---------------------------------------------------------------------------------------------------- timing
@dataclass
class TaskResult:
    """Timings of one task (seconds; per-frame parts in ms)."""

    task: str
    prediction_format: str
    frames: int
    distinct_frames: int
    size: int
    validate_s: list[float] = field(default_factory=list)
    loop_s: list[float] = field(default_factory=list)
    loop_cpu_s: list[float] = field(default_factory=list)
    parts_ms: dict[str, float] = field(default_factory=dict)
    metrics: dict[str, float] = field(default_factory=dict)
    breakdown: dict[str, float] = field(default_factory=dict)

    @property
    def best_loop_s(self) -> float:
        return min(self.loop_s)

    @property
    def best_validate_s(self) -> float:
        return min(self.validate_s)

    @property
    def frames_per_s(self) -> float:
        return self.frames / self.best_loop_s

    @property
    def best_cpu_s(self) -> float:
        return min(self.loop_cpu_s)

    @property
    def metrics_ms(self) -> float:
        return sum(v for k, v in self.parts_ms.items() if k in ("metric", "rings", "ranges"))

    @property
    def total_s(self) -> float:
        """Validation plus loop: what ``scripts/evaluate.py predictions=DIR`` spends on the frames."""
        return self.best_validate_s + self.best_loop_s


def cpu_seconds() -> float:
    """User + system CPU time of this process and of its reaped children (the DataLoader workers)."""
    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        usage = resource.getrusage(who)
        total += usage.ru_utime + usage.ru_stime
    return total


def _best_cpu_ms_per_frame(fn, n: int, repeat: int) -> float:
    """Least process CPU time of ``repeat`` calls of ``fn`` (one thread), in ms per frame."""
    best = float("inf")
    for _ in range(repeat):
        start = time.process_time()
        fn()
        best = min(best, time.process_time() - start)
    return best / n * 1e3


def time_parts(
    dataset: RepeatedFrames,
    predictor: FilePredictor,
    scorer: TaskScorer,
    theta: torch.Tensor,
    frames: int,
    batch_size: int,
    repeat: int,
) -> dict[str, float]:
    """CPU ms/frame of ground-truth load, prediction decode and the metric updates (task metric, rings, ranges),
    each on one torch thread as in a DataLoader worker (where the evaluation of prediction files runs them)."""
    n = min(frames, len(dataset))
    ids = dataset.sample_ids[:n]
    task = predictor.task
    wrapped = predictor.wrap(dataset)
    batches = [
        collate([wrapped[i] for i in range(start, min(start + batch_size, n))])
        for start in range(0, n, batch_size)
    ]
    target = get_task(task).target

    def score(metric, **kwargs) -> None:
        metric.reset()
        for b in batches:
            metric.update(b["prediction"], b[target], mask=b["valid_mask"], **kwargs)

    parts = {
        "gt": lambda: [dataset[i] for i in range(n)],
        "prediction": lambda: [read_prediction(predictor.files[s], task) for s in ids],
        "metric": lambda: score(scorer.metric),
        "rings": lambda: score(scorer.rings, theta=theta),
    }
    if scorer.ranges is not None:
        parts["ranges"] = lambda: score(scorer.ranges)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        out = {}
        for name, fn in parts.items():
            fn()  # warm-up
            out[name] = _best_cpu_ms_per_frame(fn, n, repeat)
    finally:
        torch.set_num_threads(threads)
    return out


def bench_task(
    task: str,
    root: Path,
    data_dir: Path,
    args: argparse.Namespace,
) -> TaskResult:
    dataset = evaluation_set(root, task, args.size, args.frames)
    fmt = get_task(task).prediction.suffix(args.depth_format).lstrip(".")
    folder = data_dir / f"preds-{root.name}-{task}-{fmt}-{args.size}px-{args.frames}f"
    ensure_predictions(folder, dataset, task, fmt)
    theta = torch.rad2deg(dataset.camera.theta_grid()).float()
    shape = (dataset.camera.height, dataset.camera.width)
    result = TaskResult(task, fmt, len(dataset), dataset.num_distinct, args.size)
    for _ in range(args.repeat):
        start = time.perf_counter()
        predictor = FilePredictor(folder, task, dataset.sample_ids, shape)
        result.validate_s.append(time.perf_counter() - start)
        scorer = make_scorer(task, dataset)
        cpu = cpu_seconds()
        out = evaluate_predictions(
            predictor,
            dataset,
            scorer,
            theta,
            batch_size=args.batch_size,
            num_workers=args.workers,
            num_panels=0,
        )
        if out.num_frames != len(dataset):
            raise RuntimeError(f"{out.num_frames} frames evaluated, expected {len(dataset)}")
        result.loop_s.append(out.seconds)
        result.loop_cpu_s.append(cpu_seconds() - cpu)
        result.metrics, result.breakdown = out.metrics, out.breakdown
    result.parts_ms = time_parts(
        dataset, predictor, make_scorer(task, dataset), theta, args.parts_frames, args.batch_size, args.repeat
    )
    return result


# ---------------------------------------------------------------------------------------------------- report
def machine() -> str:
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    gpu = "CUDA GPU present (unused)" if torch.cuda.is_available() else "no GPU"
    return (
        f"{os.cpu_count()} CPU cores, {gpu}, Python {platform.python_version()}, torch {torch.__version__}; "
        f"load average at the end {load}"
    )


def format_table(results: Sequence[TaskResult], args: argparse.Namespace) -> str:
    """Markdown table: the loop (wall, best of the repeats, and CPU) and the CPU cost per frame of each part."""
    lines = [
        f"| task | prediction files | frames (distinct GT) | validate s | loop s, best of {args.repeat} (runs) "
        "| frames/s | loop CPU s (main + workers) | GT load | prediction decode | task metric | rings "
        "| ranges |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in results:
        kind = (
            "8-bit label PNG"
            if get_task(r.task).uses_classes
            else ("16-bit PNG" if r.prediction_format == "png" else ".npy")
        )
        runs = " / ".join(f"{s:.1f}" for s in r.loop_s)
        parts = " | ".join(
            f"{r.parts_ms[k]:.1f}" if k in r.parts_ms else "-"
            for k in ("gt", "prediction", "metric", "rings", "ranges")
        )
        lines.append(
            f"| {r.task} | {kind} | {r.frames} ({r.distinct_frames}) | {r.best_validate_s:.2f} "
            f"| **{r.best_loop_s:.1f}** ({runs}) | {r.frames_per_s:.1f} | {r.best_cpu_s:.1f} | {parts} |"
        )
    return "\n".join(lines)


def command_line(argv: Sequence[str]) -> str:
    return shlex.join(["python", "scripts/bench_evaluate.py", *argv])


def update_docs(section: str, doc: Path = DOCS) -> None:
    """Replace the section in ``doc`` or insert it before ``## Metrics`` (end of file if absent); one write."""
    text = doc.read_text()
    lines = text.split("\n")
    body = [*section.rstrip("\n").split("\n"), ""]
    if SECTION in lines:
        start = lines.index(SECTION)
        end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")), len(lines))
        lines[start:end] = body
    elif BEFORE in lines:
        at = lines.index(BEFORE)
        lines[at:at] = body
    else:
        lines += ["", *body]
    doc.write_text("\n".join(lines))


# ---------------------------------------------------------------------------------------------------- main
def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data", type=Path, default=Path("/tmp/afb_bench_eval"), help="cache of dataset + predictions"
    )
    parser.add_argument("--root", type=Path, default=None, help="use this dataset instead of generating one")
    parser.add_argument(
        "--size", type=int, default=512, help="served fisheye size (and generated fisheye size)"
    )
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--tasks", default=",".join(TASKS), help="comma-separated: seg, depth")
    parser.add_argument("--depth-format", choices=("png", "npy"), default="png")
    parser.add_argument("--batch-size", type=int, default=8)
    parser.add_argument("--workers", type=int, default=2, help="DataLoader workers")
    parser.add_argument("--repeat", type=int, default=2, help="loop repetitions (best reported)")
    parser.add_argument("--parts-frames", type=int, default=48, help="frames of the per-part timing")
    parser.add_argument(
        "--write-docs", action="store_true", help=f"put the table into {DOCS.relative_to(ROOT)}"
    )
    args = parser.parse_args(argv)
    args.tasks = [t.strip() for t in args.tasks.split(",") if t.strip()]
    unknown = set(args.tasks) - set(TASKS)
    if unknown or not args.tasks:
        parser.error(f"--tasks must be a subset of {TASKS}, got {args.tasks}")
    if args.repeat < 1:
        parser.error("--repeat must be >= 1")
    return args


def main(argv: Sequence[str] | None = None) -> list[TaskResult]:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parse_args(argv)
    data_dir = args.data.expanduser()
    data_dir.mkdir(parents=True, exist_ok=True)
    root = args.root or ensure_bench_dataset(data_dir, args.size)
    results = [bench_task(task, Path(root), data_dir, args) for task in args.tasks]
    distinct = results[0].distinct_frames
    table = format_table(results, args)
    notes = (
        f"`{command_line(argv)}`\n\n"
        f"{results[0].frames} frames at {args.size}^2 per task: the {distinct} distinct frames of a synthetic dataset "
        f"(`{Path(root).name}`, all splits, pre-rendered fisheye) repeated, each repetition under its own "
        "`sample_id` with its own prediction file, so every frame decodes its ground-truth files and its prediction "
        "(warm page cache). The loop is `evaluate_predictions(FilePredictor(...), ..., "
        f"batch_size={args.batch_size}, num_workers={args.workers}, num_panels=0)` with the task metric, "
        "incidence-angle rings and (depth) range bins; `validate` is the `FilePredictor` construction (submission "
        "check of every header). Loop CPU s: user + system time of the main process and the workers. The last "
        "five columns are CPU ms per frame of each part, measured separately in the main process on "
        f"{min(args.parts_frames, results[0].frames)} frames on one torch thread, as in a loader worker (where "
        f"the loop runs them): GT load (`dataset[i]`), `read_prediction`, then the metric updates. Machine: {machine()}."
    )
    print(notes, "", table, sep="\n")
    if args.write_docs:
        update_docs(f"{SECTION}\n\n{notes}\n\n{table}\n")
        print(f"\nwrote the table into {DOCS}")
    return results
