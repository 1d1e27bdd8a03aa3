"""The GPU campaign: can the data loader feed one GPU for the paper recipes, and what does the GPU give?

``python scripts/gpu_campaign.py --commit <sha>`` on a machine with one GPU runs, in under 9 minutes of wall time
(``--budget-s 540``) including the generation of its own data, and writes ``docs/figures/gpu/campaign_<gpu>.json``:

1. **data** -- a synthetic release with the paper's sensors at the served size: 512^2 cube faces (PNG, the presets'
   encoding), 64 x 2048 LiDAR, 48 frames (``tiny``'s scene settings), generated with every core in a child
   process that is killed at its time box.
2. **train:<task>** -- for ``experiment=paper/seg|depth|completion`` at 512^2 with the recipe's batch and precision
   (``trainer=gpu``: 16-mixed), random initial weights (the machine is offline): steps on one batch kept on the
   device (the model's own ceiling: images/s, peak memory); the recipe's AMP against float32 on that batch (loss
   and output parity, and float32's images/s); then steps fed by the recipe's loader (15 workers, the recipe's
   ``data.pin_memory``) with ``remap_on=worker`` and with ``remap_on=device``, and on a GPU with ``remap_on=worker``
   pinned (``worker_pinned``) where the recipe does not pin: images/s, the host's wait in ``next()`` and the GPU's
   measured idle share (:mod:`~airfisheye_bench.studies.train_throughput`).
3. **loader** -- the loader alone (no model): samples/s of each task's training loader with 4, 8 and 15 workers
   (decode, remap, occlusion-corrected LiDAR, augmentation), and what the workers give under ``remap_on=device``
   (decode and LiDAR; the remap then runs on the GPU).
4. **extras** -- ``--extra module:function`` runs ``function(record, phase, context)`` in the time left (a hook for,
   e.g., seeds of the occlusion ablation).

Every phase is time-boxed and the JSON is rewritten atomically after every measurement
(:mod:`~airfisheye_bench.studies.campaign_record`): a kill at any moment leaves the measurements made so far.
The record carries its provenance: the full commit (``--commit``, else the checkout's), the command, the GPU, torch,
CUDA and cuDNN versions, the driver, the CPU model and count.

``--smoke`` does the same on the CPU at toy sizes (the ``tiny`` preset at 64^2, small models, batch 2, a few steps,
0 and 2 workers) in about a minute: the slow test suite runs it and checks the record's fields.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import gc
import importlib
import os
import platform
import re
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import hydra
import torch
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig
from torch.utils.data import DataLoader, RandomSampler

from airfisheye_bench.constants import config_dir
from airfisheye_bench.runs.results import portable_identity
from airfisheye_bench.studies.campaign_record import CampaignRecord, Phase
from airfisheye_bench.studies.provenance import git_commit, machine
from airfisheye_bench.studies.train_throughput import (
    Stepper,
    amp_of,
    amp_parity,
    cached_steps,
    fed_steps,
    to_device,
)
from airfisheye_bench.training import build
from datamodules.dataset import AirFisheyeDataset, collate
from datamodules.device_remap import CubeFaces

# The checkout this package sits in (benchmarks run from one).
ROOT = Path(__file__).resolve().parents[2]
OUT_DIR = ROOT / "docs" / "figures" / "gpu"
TASKS = ("seg", "depth", "completion")
REMAP_SITES = ("worker", "device")


@dataclass(frozen=True)
class Plan:
    """Sizes, counts and time boxes of one campaign (:data:`FULL` on a GPU, :data:`SMOKE` on a CPU)."""

    size: int
    data: dict[str, Any]  # generator overrides of the tiny preset
    loader_workers: tuple[int, ...]  # the loader alone
    train_workers: int  # the loader-fed steps
    warmup: int
    steps: int
    fp32_steps: int
    cached_warm_s: float  # the ceiling's warm-up, at least (clocks, cuDNN)
    fed_drain_s: float  # the loader-fed warm-up's wait for the workers' store to empty, at most
    window_s: float  # each timed run of steps, at least
    loader_warm_s: float
    loader_window_s: float
    budget_s: float
    budgets: dict[str, float]  # per phase kind: data, train (each task), loader
    overrides: dict[str, list[str]] = field(default_factory=dict)  # extra config overrides per task


FULL = Plan(
    size=512,
    data={
        "face_size": 512,
        "fisheye_source": "none",
        "fisheye_size": 0,
        "total_frames": 48,
        "num_trajectories": 4,
        "lidar_channels": 64,
        "lidar_points_per_channel": 2048,
    },
    loader_workers=(4, 8, 15),
    train_workers=15,
    warmup=3,
    steps=20,
    fp32_steps=8,
    cached_warm_s=2.0,
    fed_drain_s=12.0,
    window_s=3.0,
    loader_warm_s=1.0,
    loader_window_s=3.5,
    budget_s=540.0,
    budgets={"data": 120.0, "train": 95.0, "loader": 120.0},
)

SMOKE = Plan(
    size=64,
    data={"fisheye_source": "none", "fisheye_size": 0},
    loader_workers=(0, 2),
    train_workers=0,
    warmup=1,
    steps=2,
    fp32_steps=1,
    cached_warm_s=0.0,
    fed_drain_s=1.0,
    window_s=0.0,
    loader_warm_s=0.2,
    loader_window_s=0.5,
    budget_s=240.0,
    budgets={"data": 60.0, "train": 40.0, "loader": 40.0},
    overrides={
        "seg": ["model.encoder_name=resnet18", "data.batch_size=2"],
        "depth": [
            "model.encoder_name=resnet18",
            "model.patch_size=2",
            "model.n_bins=32",
            "data.batch_size=2",
        ],
        "completion": ["model.encoder_name=resnet18", "model.prop_steps=2", "data.batch_size=2"],
    },
)


# ------------------------------------------------------------------------------------------------ provenance
def provenance(command: str, commit: str | None, device: torch.device) -> dict[str, Any]:
    """Where the numbers come from: commit, command, GPU, library versions, CPU."""
    out: dict[str, Any] = {
        "commit": commit or git_commit(ROOT),
        "command": command,
        "started_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "cpu_count": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "python": platform.python_version(),
        "torch": torch.__version__,
        "cuda": torch.version.cuda,
        "cudnn": torch.backends.cudnn.version() if torch.backends.cudnn.is_available() else None,
        "device": str(device),
        "tf32": {
            "matmul": torch.backends.cuda.matmul.allow_tf32,
            "cudnn": torch.backends.cudnn.allow_tf32,
            "cudnn_benchmark": torch.backends.cudnn.benchmark,
        },
    }
    if device.type == "cuda":
        props = torch.cuda.get_device_properties(device)
        out |= {
            "device_name": props.name,
            "device_memory_gib": round(props.total_memory / 2**30, 1),
            "device_capability": f"{props.major}.{props.minor}",
            "driver": _driver_version(),
        }
    else:
        out["device_name"] = "cpu"
    return out


def _driver_version() -> str | None:
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        done = subprocess.run(
            ["nvidia-smi", "--query-gpu=driver_version", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        return done.stdout.strip().splitlines()[0] if done.returncode == 0 and done.stdout.strip() else None
    return None


def process_age_s() -> float:
    """Seconds since this process started (0 where ``/proc`` does not say)."""
    with contextlib.suppress(OSError, ValueError, IndexError):
        ticks = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        return max(uptime - ticks / os.sysconf("SC_CLK_TCK"), 0.0)
    return 0.0


def default_out(device_name: str, smoke: bool) -> Path:
    """``docs/figures/gpu/campaign_<gpu>.json`` (a temporary file in the smoke mode)."""
    if smoke:
        return Path(tempfile.gettempdir()) / "gpu_campaign_smoke.json"
    return OUT_DIR / f"campaign_{re.sub(r'[^a-z0-9]+', '-', device_name.lower()).strip('-')}.json"


# ------------------------------------------------------------------------------------------------------ data
def generate_data(record: CampaignRecord, phase: Phase, plan: Plan, root: Path) -> Path:
    """The campaign's dataset, by ``scripts/generate_synthetic.py`` in a child process group (killed at the box)."""
    workers = max(
        1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    )
    command = [
        sys.executable,
        str(ROOT / "scripts" / "generate_synthetic.py"),
        "preset=tiny",
        f"out={root}",
        f"workers={workers}",
        "progress=false",
        *(f"{k}={v}" for k, v in plan.data.items()),
    ]
    log = root.with_name(root.name + ".log")
    log.parent.mkdir(parents=True, exist_ok=True)
    started, box = time.monotonic(), max(phase.left(), 1.0)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    with log.open("w") as out:
        child = subprocess.Popen(
            command, stdout=out, stderr=subprocess.STDOUT, start_new_session=True, env=env
        )
        try:
            status = child.wait(timeout=box)
        except subprocess.TimeoutExpired:
            os.killpg(child.pid, signal.SIGKILL)  # the generator's worker processes too
            child.wait()
            raise TimeoutError(f"the generator did not finish in {box:.0f} s (its log: {log})") from None
    if status != 0:
        raise RuntimeError(
            f"the generator failed ({status}): " + " | ".join(log.read_text().splitlines()[-3:])
        )
    frames = {s: len((root / "splits" / f"{s}.txt").read_text().split()) for s in ("train", "val", "test")}
    record.set(
        "data",
        value={
            "root": str(root),
            "generator": shlex.join(command[1:]),
            "workers": workers,
            "seconds": round(time.monotonic() - started, 1),
            "frames": frames,
            # What the generator wrote, by content: the same data give the same identity on any machine.
            "dataset": portable_identity(root, "campaign"),
            "served_size": plan.size,
            **plan.data,
        },
    )
    return root


# ---------------------------------------------------------------------------------------------------- recipes
def clip_norm(cfg: DictConfig) -> float | None:
    """The recipe's gradient-norm clipping (``trainer.gradient_clip_val`` when the algorithm is ``norm``)."""
    if cfg.trainer.get("gradient_clip_algorithm", "norm") != "norm":
        return None
    return cfg.trainer.get("gradient_clip_val")


def compose_recipe(task: str, overrides: list[str]) -> DictConfig:
    """``experiment=paper/<task> trainer=gpu`` with random initial weights (these machines are offline), then
    ``overrides`` (the data, the loader)."""
    recipe = [f"experiment=paper/{task}", "trainer=gpu", "model.encoder_weights=null", *overrides]
    with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3"):
        return compose(config_name="train", overrides=recipe)


def recipe_config(task: str, plan: Plan, root: Path) -> DictConfig:
    """The recipe on the campaign's data at the plan's size, with the plan's loader and overrides."""
    data = [f"data.root={root}", "data.preset=null", f"data.camera.size={plan.size}"]
    return compose_recipe(
        task, [*data, f"data.num_workers={plan.train_workers}", *plan.overrides.get(task, [])]
    )


def kept_batch_stepper(
    cfg: DictConfig, module: torch.nn.Module, dataset, device: torch.device
) -> tuple[Stepper, dict[str, Any]]:
    """The recipe's training step (its precision and gradient clipping) and one batch of the recipe's size kept on
    ``device``: what the model's own ceiling is measured on."""
    amp_dtype, scaler, _ = amp_of(str(cfg.trainer.precision), device)
    stepper = Stepper(module, device, amp_dtype, scaler, clip_norm(cfg))
    batch_size = int(cfg.data.batch_size)
    return stepper, to_device(collate([dataset[i % len(dataset)] for i in range(batch_size)]), device)


def stream(dataset, batch_size: int, workers: int, batches: int, pin: bool, seed: int = 0) -> DataLoader:
    """A loader of ``batches`` batches drawn with replacement: no epoch boundary in the measurement."""
    return DataLoader(
        dataset,
        batch_size=batch_size,
        sampler=RandomSampler(
            range(len(dataset)),
            replacement=True,
            num_samples=batch_size * batches,
            generator=torch.Generator().manual_seed(seed),
        ),
        num_workers=workers,
        collate_fn=collate,
        pin_memory=pin,
        drop_last=True,
        timeout=120 if workers else 0,
    )


def served(dataset: AirFisheyeDataset, remap_on: str) -> AirFisheyeDataset | CubeFaces:
    """What the loader reads for a remap site (the datamodule's own choice, for a loader built here)."""
    return CubeFaces(dataset) if remap_on == "device" else dataset


# ----------------------------------------------------------------------------------------------------- train
def train_task(
    record: CampaignRecord, phase: Phase, task: str, plan: Plan, root: Path, device: torch.device
) -> None:
    """One recipe: the ceiling on a cached batch, AMP against float32, then the loader-fed steps."""
    started = time.monotonic()
    cfg = recipe_config(task, plan, root)
    datamodule, module = build(cfg)
    dataset = datamodule.split_dataset("train")
    amp_dtype, _, note = amp_of(str(cfg.trainer.precision), device)
    clip = clip_norm(cfg)
    batch_size = int(cfg.data.batch_size)
    key = ("tasks", task)
    record.set(
        *key,
        "recipe",
        value={
            "experiment": f"paper/{task}",
            "model": cfg.model.name,
            "encoder": cfg.model.get("encoder_name"),
            "batch": batch_size,
            "size": plan.size,
            "precision": str(cfg.trainer.precision),
            "amp_dtype": str(amp_dtype).removeprefix("torch.") if amp_dtype is not None else None,
            "amp_note": note,
            "gradient_clip_norm": clip,
            "parameters_m": round(sum(p.numel() for p in module.parameters()) / 1e6, 2),
            "build_s": round(time.monotonic() - started, 1),
        },
    )
    try:
        stepper, batch = kept_batch_stepper(cfg, module, dataset, device)
        timing = {"warm_s": plan.cached_warm_s, "window_s": plan.window_s}
        record.set(
            *key, "cached", value=cached_steps(stepper, batch, plan.warmup, plan.steps, phase, **timing)
        )
        record.set(*key, "amp_parity", value=amp_parity(stepper, batch))
        if not phase.expired("float32 steps"):
            fp32 = Stepper(module, device, None, False, clip)
            record.set(
                *key, "cached_fp32", value=cached_steps(fp32, batch, 1, plan.fp32_steps, phase, **timing)
            )
            del fp32
        # The training's own loader (the recipe's data.pin_memory) at each remap site; on a GPU, also pinned.
        recipe_pin = bool(cfg.data.get("pin_memory", False)) and device.type == "cuda"
        variants = [(site, recipe_pin, site) for site in REMAP_SITES]
        if device.type == "cuda" and not recipe_pin:
            variants.append(("worker", True, "worker_pinned"))
        for site, pin, name in variants:
            if phase.expired(f"loader-fed steps, {name}"):
                break
            finish = dataset.device_remap() if site == "device" else (lambda b: b)
            loader = stream(served(dataset, site), batch_size, plan.train_workers, 100_000, pin=pin)
            iterator = iter(loader)
            # At least the batches the workers prefetched while they started (2 each), then until their store is
            # empty (fed_steps): the measured steps get what the loader produces, not a buffer.
            warmup = plan.warmup + 2 * plan.train_workers
            try:
                result = fed_steps(
                    stepper, iterator, finish, warmup, plan.steps, phase, plan.fed_drain_s, plan.window_s
                )
            finally:
                del iterator
            record.set(*key, "fed", name, value=result | {"workers": plan.train_workers, "pin_memory": pin})
        record.set(*key, "summary", value=task_summary(record.data["tasks"][task]))
    finally:
        del datamodule, module
        gc.collect()
        if device.type == "cuda":
            torch.cuda.empty_cache()


def task_summary(entry: dict[str, Any]) -> dict[str, Any]:
    """The answer for one recipe: the ceiling, what the loader gives with either remap site, and whether it keeps up.

    The loader keeps up when the fed images/s reach 95 % of the cached ceiling; ``drained`` says whether the
    workers' store of prefetched batches emptied before the measurement (``fed_steps``).
    """
    ceiling = (entry.get("cached") or {}).get("images_per_s")
    out: dict[str, Any] = {"ceiling_images_per_s": ceiling}
    for site, fed in (entry.get("fed") or {}).items():
        rate = fed.get("images_per_s")
        out[f"fed_{site}_images_per_s"] = rate
        out[f"fed_{site}_device_idle_share"] = fed.get("device_idle_share")
        out[f"fed_{site}_drained"] = fed.get("drained")
        if rate and ceiling:
            out[f"fed_{site}_keeps_up"] = rate >= 0.95 * ceiling
    return out


# ---------------------------------------------------------------------------------------------------- loader
def loader_rates(
    record: CampaignRecord, phase: Phase, plan: Plan, root: Path, tasks: tuple[str, ...]
) -> None:
    """The loader alone: samples/s of each task's training loader by workers, and the device path's workers."""
    rows: list[dict[str, Any]] = []
    configs = [(w, "worker") for w in plan.loader_workers] + [(max(plan.loader_workers), "device")]
    for task in tasks:
        cfg = recipe_config(task, plan, root)
        datamodule = hydra.utils.instantiate(cfg.data)
        datamodule.prepare_data()
        datamodule.setup("fit")
        dataset = datamodule.split_dataset("train")
        for workers, site in configs:
            if phase.expired("loader alone"):
                break
            row = {"task": task, "workers": workers, "remap_on": site, "batch": int(cfg.data.batch_size)}
            row |= loader_rate(served(dataset, site), row["batch"], workers, plan, phase)
            rows.append(row)
            record.set("loader", value=rows)


def loader_rate(dataset, batch_size: int, workers: int, plan: Plan, phase: Phase) -> dict[str, Any]:
    """Samples/s after the workers started and the prefetched batches drained (``plan.loader_warm_s``)."""
    started = time.perf_counter()
    iterator = iter(stream(dataset, batch_size, workers, 100_000, pin=False))
    try:
        next(iterator)
        startup = time.perf_counter() - started
        warm_until, drained = time.perf_counter() + plan.loader_warm_s, 0
        while time.perf_counter() < warm_until or drained < 2 * workers:  # the prefetched batches drained
            next(iterator)
            drained += 1
        samples, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < plan.loader_window_s and not phase.expired("loader alone"):
            samples += len(next(iterator)["sample_id"])
        seconds = time.perf_counter() - t0
    finally:
        del iterator
    return {
        "startup_s": round(startup, 2),
        "samples": samples,
        "seconds": round(seconds, 2),
        "samples_per_s": samples / seconds if seconds > 0 else None,
    }


# ------------------------------------------------------------------------------------------------------- main
def run_extra(spec: str, record: CampaignRecord, phase: Phase, context: dict[str, Any]) -> None:
    """``module:function`` called as ``function(record, phase, context)`` (the hook for optional studies)."""
    module_name, _, function = spec.partition(":")
    getattr(importlib.import_module(module_name), function)(record, phase, context)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="the CPU mode at toy sizes (the test suite's)")
    parser.add_argument(
        "--out", default=None, help="the JSON file (default: docs/figures/gpu/campaign_<gpu>.json)"
    )
    parser.add_argument(
        "--data-dir", default=None, help="where the data is generated (default: a temporary folder)"
    )
    parser.add_argument("--commit", default=None, help="the commit measured (default: the checkout's HEAD)")
    parser.add_argument("--budget-s", type=float, default=None, help="wall-clock seconds for everything")
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    parser.add_argument("--extra", action="append", default=[], help="module:function, run in the time left")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Run the campaign; returns the record's contents."""
    args = parse_args(argv)
    plan = SMOKE if args.smoke else FULL
    if not args.smoke and not torch.cuda.is_available():
        raise SystemExit(
            "error: no CUDA device; python scripts/gpu_campaign.py --smoke runs the campaign on the CPU"
        )
    device = torch.device("cpu" if args.smoke else "cuda")
    command = shlex.join(["python", "scripts/gpu_campaign.py", *(sys.argv[1:] if argv is None else argv)])
    prov = provenance(command, args.commit, device)
    out = Path(args.out) if args.out else default_out(prov["device_name"], args.smoke)
    # As a script the budget counts from the process's start (the imports are part of the 9 minutes); called with
    # arguments from a longer-lived process (a test), from the call.
    started = process_age_s() if argv is None else 0.0
    budget = (args.budget_s if args.budget_s is not None else plan.budget_s) - started
    record = CampaignRecord(
        out,
        budget,
        {"schema": 1, "mode": "smoke" if args.smoke else "full", "provenance": prov, "plan": asdict(plan)},
    )
    try:
        print(f"gpu campaign ({record.data['mode']}, {prov['device_name']}): writing {out}", flush=True)
        data_dir = Path(args.data_dir) if args.data_dir else Path(tempfile.mkdtemp(prefix="gpu_campaign_"))
        root = data_dir / f"campaign{plan.size}"
        tasks = tuple(args.tasks)
        record.run_phase(
            "data", lambda p: generate_data(record, p, plan, root), plan.budgets["data"], minimum_s=10
        )
        for task in tasks:
            if "data" not in record.data:
                record.skip(f"train:{task}", "no data")
                continue
            record.run_phase(
                f"train:{task}",
                lambda p, t=task: train_task(record, p, t, plan, root, device),
                plan.budgets["train"],
            )
            print(f"train:{task}: {record.data['phases'][f'train:{task}']['status']}", flush=True)
        if "data" not in record.data:
            record.skip("loader", "no data")
        else:
            record.run_phase(
                "loader", lambda p: loader_rates(record, p, plan, root, tasks), plan.budgets["loader"]
            )
        context = {"root": root, "plan": plan, "device": device}
        for spec in args.extra:
            record.run_phase(
                f"extra:{spec}", lambda p, s=spec: run_extra(s, record, p, context), record.left() - 5.0
            )
        record.finish()
    finally:
        record.stand_down()
    print(f"gpu campaign: {record.data['status']} in {record.data['elapsed_s']:.0f} s -> {out}", flush=True)
    return record.data
