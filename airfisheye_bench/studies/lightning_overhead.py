"""Lightning overhead: one training step through ``lightning.Trainer`` vs a plain PyTorch loop, same model and batch.

For each task the module is built as ``train.py`` builds it (the Hydra task and model configs of the quick start,
``airfisheye_bench.tasks.<Task>`` with the model dict and the task's optimizer partial; no LR scheduler on either
side), and one fixed synthetic batch (the keys and dtypes ``datamodules.dataset.collate`` produces) is served by a
``DataLoader`` over an in-memory dataset, so data cost is ~0 and identical on both sides. Variants:

- ``plain``: ``net.forward_with_aux`` + the task's ``loss_terms`` + backward + ``optimizer.step`` + ``zero_grad``;
- ``trainer``: ``Trainer.fit`` with the project's CPU trainer config, no logger, checkpointing, progress bar or
  validation (the task's ``training_step`` still calls ``self.log`` every step);
- ``trainer_csv``: the same with the default training logger (``CSVLogger``, ``log_every_n_steps`` from
  ``configs/trainer/cpu.yaml``), i.e. what ``train.py`` runs minus progress bar and checkpoints.

A step's time is the interval between the starts of consecutive steps (``on_train_batch_start`` for the Trainer, the
top of the loop body for the plain loop), so it covers everything between steps: hooks, logging, the optimizer and
fetching the next batch; Trainer start-up and tear-down are excluded and the first ``--warmup`` steps dropped.
Each interval is taken on two clocks: process CPU time (``time.process_time``; with one torch thread it leaves out
the time other jobs hold the shared cores, so it is the steadier one on a busy machine) and wall time.
Repetitions are interleaved (plain, trainer, trainer_csv, then the next repetition in rotated order) with fresh,
identically seeded modules; the table gives the median step time over all repetitions and the overhead
``median(variant) / median(plain) - 1``, plus the range of the per-repetition ratios as a noise indicator.

    python scripts/bench_lightning.py                                  # 128x128, batch 8, 1 thread, 3 tasks
    python scripts/bench_lightning.py --tasks seg --size 512 --batch 2 --steps 5
    python scripts/bench_lightning.py --write-docs -v                  # also update docs/benchmarks.md

Run from the repository root with the package importable (``pip install -e .`` or ``PYTHONPATH=.``).
"""

from __future__ import annotations

import argparse
import itertools
import logging
import shlex
import statistics
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import hydra
import lightning as L
import torch
from hydra import compose, initialize_config_dir
from lightning.pytorch.callbacks import Callback
from lightning.pytorch.loggers import CSVLogger
from omegaconf import DictConfig, OmegaConf
from torch.utils.data import DataLoader, Dataset

from airfisheye_bench.constants import config_dir
from airfisheye_bench.specs import get_task, task_names
from airfisheye_bench.synth.classes import TRAIN_CLASSES
from airfisheye_bench.tasks import BenchmarkTask
from datamodules.dataset import collate

# The checkout this package sits in (benchmarks run from one): its docs/benchmarks.md gets the tables.
ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs" / "benchmarks.md"
SECTION = "## Lightning overhead"
VARIANTS = ("plain", "trainer", "trainer_csv")
CLOCKS = ("cpu", "wall")


# ------------------------------------------------------------------------------------------------ module and data
def compose_config(task: str, size: int) -> DictConfig:
    """The quick-start training config of ``task`` at ``size`` (no LR scheduler: the plain loop has none)."""
    overrides = [f"task={task}", f"data.camera.size={size}", "task.module.scheduler=null"]
    with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3"):
        cfg = compose(config_name="train", overrides=overrides)
    if cfg.model.name == "adabins":
        # As configs/model/adabins.yaml says: patch 4 at 128^2, 16 at 512^2 (the mini-ViT needs >= 129 patches).
        cfg.model.patch_size = max(1, size // 32)
    return cfg


def build_module(cfg: DictConfig, seed: int) -> BenchmarkTask:
    """The task module exactly as ``airfisheye_bench.training.build`` instantiates it, with seeded weights."""
    torch.manual_seed(seed)
    extra: dict[str, Any] = {}
    if get_task(cfg.task.name).uses_classes:
        extra = {
            "class_names": [c.name for c in TRAIN_CLASSES],
            "palette": [list(c.color) for c in TRAIN_CLASSES],
        }
    model_cfg = OmegaConf.to_container(cfg.model, resolve=True)
    return hydra.utils.instantiate(cfg.task.module, model=model_cfg, **extra, _convert_="partial")


def make_samples(task: str, batch: int, size: int, num_classes: int, seed: int) -> list[dict[str, Any]]:
    """``batch`` samples with the keys, shapes and dtypes ``AirFisheyeDataset`` serves for ``task``.

    The target and inputs are those of the task's spec: ``label`` (random classes) or range maps (``depth``
    uniform in 1-100 m, ``sparse_depth`` that depth at ~5 % of pixels, as LiDAR returns).
    """
    spec = get_task(task)
    g = torch.Generator().manual_seed(seed)
    yy, xx = torch.meshgrid(torch.arange(size), torch.arange(size), indexing="ij")
    c = (size - 1) / 2
    valid = (yy - c) ** 2 + (xx - c) ** 2 <= (size / 2) ** 2  # the fisheye image circle
    samples = []
    for i in range(batch):
        s: dict[str, Any] = {"sample_id": f"bench_{i:04d}"}
        if spec.target == "label":
            label = torch.randint(0, num_classes, (size, size), generator=g)
            s["label"] = torch.where(valid, label, 255).long()
        else:
            s[spec.target] = (1 + 99 * torch.rand(1, size, size, generator=g)) * valid
        if "sparse_depth" in spec.inputs:  # ~5 % of pixels with a LiDAR return
            s["sparse_depth"] = s[spec.target] * (torch.rand(1, size, size, generator=g) < 0.05)
        s["image"] = torch.randn(3, size, size, generator=g) * valid
        s["valid_mask"] = valid.clone()
        samples.append(s)
    return samples


class RepeatedBatch(Dataset):
    """``num_batches`` copies of the same samples: indexing is free, so both loops pay the same (collate only)."""

    def __init__(self, samples: list[dict[str, Any]], num_batches: int) -> None:
        self.samples, self.num_batches = samples, num_batches

    def __len__(self) -> int:
        return len(self.samples) * self.num_batches

    def __getitem__(self, index: int) -> dict[str, Any]:
        return self.samples[index % len(self.samples)]


def make_loader(samples: list[dict[str, Any]], num_batches: int) -> DataLoader:
    # In-process, unshuffled, the project's collate: the same batch every step.
    return DataLoader(RepeatedBatch(samples, num_batches), batch_size=len(samples), collate_fn=collate)


# ------------------------------------------------------------------------------------------------------- loops
def now() -> tuple[float, float]:
    """(process CPU, wall) seconds, in ``CLOCKS`` order."""
    return time.process_time(), time.perf_counter()


def intervals_ms(starts: Sequence[tuple[float, float]], warmup: int) -> dict[str, list[float]]:
    """Wall and CPU times between consecutive step starts, without the first ``warmup`` steps."""
    kept = starts[warmup:]
    return {
        clock: [(b[i] - a[i]) * 1e3 for a, b in itertools.pairwise(kept)] for i, clock in enumerate(CLOCKS)
    }


def run_plain(module: BenchmarkTask, loader: DataLoader) -> list[tuple[float, float]]:
    """Step start times of a hand-written loop over ``loader``."""
    net = module.net.train()
    optimizer = module.optimizer_factory(params=[p for p in module.parameters() if p.requires_grad])
    starts = []
    for batch in loader:
        starts.append(now())
        terms = module.loss_terms(net.forward_with_aux(*module.model_inputs(batch)), batch)
        terms["loss"].backward()
        optimizer.step()
        optimizer.zero_grad(set_to_none=True)
    return starts


class StepClock(Callback):
    """Records the start time of every training step."""

    def __init__(self) -> None:
        self.starts: list[tuple[float, float]] = []

    def on_train_batch_start(
        self, trainer: L.Trainer, pl_module: L.LightningModule, batch: Any, idx: int
    ) -> None:
        self.starts.append(now())


def run_trainer(
    module: BenchmarkTask, loader: DataLoader, cfg: DictConfig, csv: bool, root: str
) -> list[tuple[float, float]]:
    """Step start times of ``Trainer.fit`` with the project's trainer config (optionally its CSV logger)."""
    clock = StepClock()
    trainer: L.Trainer = hydra.utils.instantiate(
        cfg.trainer,
        default_root_dir=root,
        max_epochs=-1,
        max_steps=len(loader),
        logger=CSVLogger(root, name="", version="") if csv else False,
        callbacks=[clock],
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        num_sanity_val_steps=0,
        limit_val_batches=0,
    )
    trainer.fit(module, train_dataloaders=loader)
    return clock.starts


# -------------------------------------------------------------------------------------------------- benchmark
@dataclass
class TaskResult:
    """Per-step times (ms) by clock and variant, pooled over repetitions, and the per-repetition medians."""

    task: str
    model: str
    steps_ms: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    rep_medians: dict[str, dict[str, list[float]]] = field(default_factory=dict)

    def add(self, variant: str, intervals: dict[str, list[float]]) -> None:
        for clock, times in intervals.items():
            self.steps_ms.setdefault(clock, {}).setdefault(variant, []).extend(times)
            self.rep_medians.setdefault(clock, {}).setdefault(variant, []).append(statistics.median(times))

    def median(self, variant: str, clock: str) -> float:
        return statistics.median(self.steps_ms[clock][variant])

    def overhead_pct(self, variant: str, clock: str) -> float:
        return 100 * (self.median(variant, clock) / self.median("plain", clock) - 1)

    def overhead_range_pct(self, variant: str, clock: str) -> tuple[float, float]:
        medians = self.rep_medians[clock]
        ratios = [100 * (v / p - 1) for v, p in zip(medians[variant], medians["plain"], strict=True)]
        return min(ratios), max(ratios)


def bench_task(task: str, args: argparse.Namespace) -> TaskResult:
    cfg = compose_config(task, args.size)
    samples = make_samples(task, args.batch, args.size, len(TRAIN_CLASSES), args.seed)
    loader = make_loader(samples, args.warmup + args.steps + 1)  # +1: the last step's end is the next start
    result = TaskResult(task, describe_model(cfg))
    runners: dict[str, Callable[[BenchmarkTask, str], list[tuple[float, float]]]] = {
        "plain": lambda m, _: run_plain(m, loader),
        "trainer": lambda m, root: run_trainer(m, loader, cfg, csv=False, root=root),
        "trainer_csv": lambda m, root: run_trainer(m, loader, cfg, csv=True, root=root),
    }
    for rep in range(args.repeats):
        order = VARIANTS[rep % len(VARIANTS) :] + VARIANTS[: rep % len(VARIANTS)]  # rotate against drift
        for variant in order:
            module = build_module(cfg, args.seed)  # fresh and identical for every run
            with tempfile.TemporaryDirectory() as root:
                intervals = intervals_ms(runners[variant](module, root), args.warmup)
            result.add(variant, intervals)
            if args.verbose:
                cpu, wall = (statistics.median(intervals[c]) for c in CLOCKS)
                print(f"{task} rep {rep} {variant}: {cpu:.1f} ms CPU, {wall:.1f} ms wall", file=sys.stderr)
    return result


def describe_model(cfg: DictConfig) -> str:
    m = cfg.model
    details = {"deeplabv3plus": "OS {encoder_output_stride}", "adabins": "{n_bins} bins, patch {patch_size}"}
    details["nlspn"] = "{prop_steps} steps, {affinity}"
    extra = details.get(m.name, "").format(**OmegaConf.to_container(m, resolve=False))
    return f"{m.name} ({m.encoder_name}{', ' + extra if extra else ''})"


# ----------------------------------------------------------------------------------------------------- output
def format_table(results: list[TaskResult], args: argparse.Namespace) -> str:
    header = (
        "| task | model | input | clock | plain (ms/step) | Trainer (ms/step) | overhead | "
        "Trainer + CSVLogger (ms/step) | overhead |\n|---|---|---|---|---:|---:|---:|---:|---:|"
    )
    rows = [header]
    for r in results:
        for clock in CLOCKS:
            cells = [r.task, r.model, f"{args.batch}x{args.size}^2", clock, f"{r.median('plain', clock):.1f}"]
            for variant in ("trainer", "trainer_csv"):
                lo, hi = r.overhead_range_pct(variant, clock)
                pct = r.overhead_pct(variant, clock)
                cells += [f"{r.median(variant, clock):.1f}", f"{pct:+.1f}% ({lo:+.1f}..{hi:+.1f})"]
            rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows)


def docs_section(table: str, command: str, args: argparse.Namespace) -> str:
    return (
        f"{SECTION}\n\n`{command}`\n\n"
        f"One training step through `lightning.Trainer` vs a plain PyTorch loop (`forward_with_aux`, the task's "
        f"loss, backward, optimizer step, `zero_grad`) with the same quick-start module, optimizer and batch "
        f"(batch {args.batch} at {args.size}^2, random weights, data served from memory), on the 2-core CPU "
        f"(no GPU) with {args.threads} torch thread(s). A step is the time between the starts of consecutive "
        f"steps (hooks, `self.log`, optimizer and next batch included; start-up excluded), median over "
        f"{args.repeats} interleaved repetitions of {args.steps} steps after {args.warmup} warm-up steps; in "
        f"brackets the range of the per-repetition overheads. `Trainer` has no logger (the task still calls "
        f"`self.log` every step); `+ CSVLogger` is the default training logger. `cpu` is process CPU time "
        f"(steadier on the shared machine), `wall` wall-clock time.\n\n{table}\n"
    )


def update_docs(section: str, path: Path = DOCS) -> None:
    """Replace the ``## Lightning overhead`` section, or insert it before ``## Models`` (else append)."""
    text = path.read_text()
    if SECTION in text:
        start = text.index(SECTION)
        end = text.find("\n## ", start + len(SECTION))
        text = text[:start] + section + ("\n" + text[end + 1 :] if end >= 0 else "")
    elif "\n## Models" in text:
        at = text.index("\n## Models") + 1
        text = text[:at] + section + "\n" + text[at:]
    else:
        text = text.rstrip("\n") + "\n\n" + section
    path.write_text(text)


# ------------------------------------------------------------------------------------------------------- main
def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", choices=task_names(), default=list(task_names()))
    parser.add_argument(
        "--size", type=int, default=128, help="square input size (quick start: 128, paper: 512)"
    )
    parser.add_argument("--batch", type=int, default=8, help="batch size (quick start: 8)")
    parser.add_argument("--steps", type=int, default=8, help="measured steps per repetition")
    parser.add_argument("--warmup", type=int, default=2, help="steps dropped at the start of every run")
    parser.add_argument("--repeats", type=int, default=3, help="interleaved repetitions of every variant")
    parser.add_argument("--threads", type=int, default=1, help="torch.set_num_threads")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--write-docs", action="store_true", help=f"update the section in {DOCS.name}")
    parser.add_argument("-v", "--verbose", action="store_true", help="print every run's median to stderr")
    args = parser.parse_args(argv)
    if args.steps < 1 or args.warmup < 0 or args.repeats < 1:
        parser.error("--steps and --repeats must be >= 1, --warmup >= 0")
    return args


def quiet_lightning() -> None:
    # The in-process loader and the short runs are intended: drop Lightning's advice about them.
    warnings.filterwarnings("ignore", message=".*does not have many workers.*")
    warnings.filterwarnings("ignore", message=".*smaller than the logging interval.*")
    warnings.filterwarnings("ignore", message=".*no `val_dataloader`.*")
    warnings.filterwarnings("ignore", message=".*LeafSpec.*is deprecated.*")  # lightning vs torch 2.14
    for name in ("lightning.pytorch", "lightning.fabric"):
        logging.getLogger(name).setLevel(logging.ERROR)


def main(argv: Sequence[str] | None = None) -> list[TaskResult]:
    args = parse_args(argv)
    torch.set_num_threads(args.threads)
    quiet_lightning()
    results = [bench_task(task, args) for task in args.tasks]
    table = format_table(results, args)
    print(table)
    if args.write_docs:
        command = "python scripts/bench_lightning.py " + shlex.join(
            a for a in (argv if argv is not None else sys.argv[1:]) if a != "--write-docs"
        )
        update_docs(docs_section(table, command.strip(), args))
    return results
