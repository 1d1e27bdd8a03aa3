"""Can 16 cores feed one GPU? An estimate of the images/s a GPU trains the paper's recipes at, set beside the images/s
15 loader workers make at the per-core rates measured on the CPU.

No published training rate of DeepLabV3+, AdaBins or NLSPN at 512^2 on an A100 or H100 was found; ResNet-50's is
published (:data:`RESNET50_A100_IMAGES_PER_S`). The estimate scales it by forward FLOPs: a recipe's model at its
size (batch 1, ``torch.utils.flop_counter.FlopCounterMode``, random weights) against ResNet-50 at 224^2, so at the
same FLOP rate an A100 trains the recipe at ``2470 * GFLOP(ResNet-50) / GFLOP(recipe)`` images/s. That is an
estimate, not a measurement (the GPU campaign, ``gpu_campaign.py``, measures the real figure). The loader's side
is read from a committed record of ``scripts/bench_loader.py`` (:data:`LOADER_RECORD`): samples/s per core for each
task, store (face size, encodings) and remap site, times :data:`WORKERS`.

``scripts/gpu_feed_estimate.py`` runs :func:`estimate` and writes the record (``docs/figures/gpu_feed_estimate.json``)
with the table ``docs/benchmarks.md`` shows ("Can 16 cores feed one H100?").
"""

from __future__ import annotations

import hashlib
import json
import subprocess
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import torch
import torchvision
from omegaconf import OmegaConf
from torch import Tensor, nn
from torch.utils.flop_counter import FlopCounterMode

import models
from airfisheye_bench.specs import get_task
from airfisheye_bench.studies.gpu_campaign import compose_recipe
from airfisheye_bench.studies.provenance import REPO

__all__ = [
    "CORES",
    "FASTER_GPU",
    "LOADER_RECORD",
    "RESNET50_A100_IMAGES_PER_S",
    "RESNET50_SIZE",
    "TASKS",
    "WORKERS",
    "Row",
    "a100_estimate",
    "estimate",
    "forward_gflop",
    "loader_record_source",
    "recipe_gflop",
    "resnet50_gflop",
    "rows_json",
    "store_rates",
    "table",
    "verdict",
]

#: ResNet-50 v1.5 training on one A100 80GB, mixed precision, 224^2, in images/s: NVIDIA DeepLearningExamples,
#: ``PyTorch/Classification/ConvNets/resnet50v1.5/README.md``, "Training performance: NVIDIA DGX A100 (8x A100
#: 80GB)", the 1-GPU row, pytorch-21.03 container. A published figure, not measured here.
RESNET50_A100_IMAGES_PER_S = 2470.0
#: The input side of that figure.
RESNET50_SIZE = 224
#: The cores of the machine in question, and the loader workers they run: one core is left to the training process.
CORES = 16
WORKERS = CORES - 1
#: How much faster than the A100 estimate the second figure assumes (an H100 is faster by a factor this estimate
#: cannot cite for these models).
FASTER_GPU = 2.0
#: The paper's recipes (``experiment=paper/<task>``).
TASKS = ("seg", "depth", "completion")
#: The per-core loader rates the estimate reads, relative to the repository.
LOADER_RECORD = "docs/figures/loader_per_core.json"

_MODEL_NAMES = {"deeplabv3plus": "DeepLabV3+", "adabins": "AdaBins", "nlspn": "NLSPN"}
_ENCODINGS = {"png": "PNG", "jpg": "JPEG", "png16": "PNG", "npy": "npy"}


# ------------------------------------------------------------------------------------------------------ FLOPs
def forward_gflop(model: nn.Module, inputs: Mapping[str, Tensor]) -> float:
    """Floating-point operations of one forward pass of ``model(**inputs)`` in eval mode, in GFLOP (torch's count: a
    multiply-add is two).

    Example:
        >>> conv = nn.Conv2d(1, 1, 3, padding=1, bias=False)  # 9 multiply-adds per output pixel
        >>> forward_gflop(conv, {"input": torch.zeros(1, 1, 10, 10)}) * 1e9
        1800.0
    """
    model = model.cpu().eval()
    counter = FlopCounterMode(display=False)
    with torch.no_grad(), counter:
        model(**inputs)
    return counter.get_total_flops() / 1e9


def resnet50_gflop(size: int = RESNET50_SIZE) -> float:
    """torchvision's ResNet-50 (v1.5, as the published figure's) at ``size^2``, batch 1, random weights."""
    torch.manual_seed(0)
    return forward_gflop(torchvision.models.resnet50(weights=None), {"x": torch.randn(1, 3, size, size)})


def recipe_inputs(task: str, size: int) -> dict[str, Tensor]:
    """Random inputs of batch 1 at ``size^2`` for the task's model (a LiDAR-like sparse map of ~5 % of the pixels
    where it takes one)."""
    g = torch.Generator().manual_seed(0)
    inputs = {"image": torch.randn(1, 3, size, size, generator=g)}
    for name in get_task(task).inputs:
        if name == "sparse_depth":
            depth = 1 + 99 * torch.rand(1, 1, size, size, generator=g)
            inputs[name] = depth * (torch.rand(1, 1, size, size, generator=g) < 0.05)
        elif name != "image":
            raise ValueError(f"task {task!r}: no random input for {name!r}")
    return inputs


def recipe_gflop(task: str) -> dict[str, Any]:
    """The recipe ``experiment=paper/<task>`` as configured (random initial weights): its model, encoder, batch and
    size, and its model's forward GFLOP at that size, batch 1."""
    cfg = compose_recipe(task, [])
    model_cfg = OmegaConf.to_container(cfg.model, resolve=True)
    name = model_cfg.pop("name")
    size = int(cfg.data.camera.size)
    torch.manual_seed(0)
    model = models.create_model(name, **model_cfg)
    return {
        "task": task,
        "experiment": f"paper/{task}",
        "model": name,
        "encoder": model_cfg.get("encoder_name"),
        "batch": int(cfg.data.batch_size),
        "size": size,
        "gflop": forward_gflop(model, recipe_inputs(task, size)),
    }


# ----------------------------------------------------------------------------------------------------- loader
def store_rates(
    loader: Mapping[str, Any], task: str, size: int, workers: int = WORKERS
) -> dict[str, dict[str, Any]]:
    """The samples/s ``workers`` cores make for ``task`` served at ``size^2``, per store the loader record measured
    (``"512^2 PNG"``: face size and encodings) and remap site: ``{store: {"face_size", "encoding", "worker",
    "device"}}`` (a site the record lacks is absent), in the record's order.

    Example:
        >>> row = {"task": "seg", "size": 512, "face_size": 512, "rgb_encoding": "png", "depth_encoding": "png16"}
        >>> record = {"results": [row | {"remap_on": "worker", "samples_per_s_per_core": 20.0},
        ...                       row | {"remap_on": "device", "samples_per_s_per_core": 30.0}]}
        >>> store_rates(record, "seg", 512)
        {'512^2 PNG': {'face_size': 512, 'encoding': 'PNG', 'worker': 300.0, 'device': 450.0}}
    """
    stores: dict[str, dict[str, Any]] = {}
    for row in loader["results"]:
        if row["task"] != task or row["size"] != size:
            continue
        encoding = _encoding(row["rgb_encoding"], row["depth_encoding"])
        store = stores.setdefault(
            f"{row['face_size']}^2 {encoding}", {"face_size": row["face_size"], "encoding": encoding}
        )
        store[row["remap_on"]] = workers * float(row["samples_per_s_per_core"])
    return stores


def _encoding(rgb: str, depth: str) -> str:
    """``PNG`` (PNG images, 16-bit PNG depth) or e.g. ``JPEG + npy``."""
    rgb_name, depth_name = _ENCODINGS.get(rgb, rgb), _ENCODINGS.get(depth, depth)
    return rgb_name if rgb_name == depth_name else f"{rgb_name} + {depth_name}"


def loader_record_source(path: Path, repo: Path = REPO) -> dict[str, Any]:
    """What identifies the loader record read: its path, SHA-256, the commit and command that wrote it, the commit
    that last changed the file, and the datasets it measured (their content identities)."""
    record = json.loads(path.read_text(encoding="utf-8"))
    last = subprocess.run(
        ["git", "log", "-1", "--format=%H", "--", str(path)], cwd=repo, capture_output=True, text=True
    ).stdout.strip()
    return {
        "path": str(path.resolve().relative_to(repo.resolve())),
        "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
        "commit": record.get("commit"),
        "command": record.get("command"),
        "machine": record.get("machine"),
        "committed_in": last or None,
        "datasets": record.get("datasets", []),
    }


# --------------------------------------------------------------------------------------------------- estimate
def a100_estimate(gflop: float, resnet50: float, rate: float = RESNET50_A100_IMAGES_PER_S) -> float:
    """The images/s an A100 trains a model of ``gflop`` forward GFLOP at, at ResNet-50's FLOP rate.

    Example:
        >>> round(a100_estimate(73.2, 8.18))
        276
    """
    return rate * resnet50 / gflop


@dataclass(frozen=True)
class Row:
    """One recipe of the table: its model's GFLOP, the A100 estimate, and what the loader's stores give it."""

    task: str
    experiment: str
    model: str
    encoder: str | None
    batch: int
    size: int
    gflop: float
    a100_images_per_s: float
    stores: dict[str, dict[str, Any]]

    @property
    def label(self) -> str:
        """``paper/seg`` (DeepLabV3+ R50, batch 8)."""
        name = _MODEL_NAMES.get(self.model, self.model)
        encoder = (self.encoder or "").replace("resnet", "R")
        return f"`{self.experiment}` ({name}{' ' + encoder if encoder else ''}, batch {self.batch})"

    def needed_per_core(self, factor: float = 1.0) -> float:
        """The samples/s each of the :data:`WORKERS` must make to feed ``factor`` times the A100 estimate."""
        return factor * self.a100_images_per_s / WORKERS


def estimate(recipes: Sequence[Mapping[str, Any]], resnet50: float, loader: Mapping[str, Any]) -> list[Row]:
    """The table's rows: each recipe (:func:`recipe_gflop`) with its A100 estimate and the loader's stores."""
    return [
        Row(
            **{k: r[k] for k in ("task", "experiment", "model", "encoder", "batch", "size", "gflop")},
            a100_images_per_s=a100_estimate(r["gflop"], resnet50),
            stores=store_rates(loader, r["task"], r["size"]),
        )
        for r in recipes
    ]


def verdict(a100: float, stores: Mapping[str, Mapping[str, Any]], size: int) -> str:
    """Whether 15 cores feed the recipe, from its A100 estimate and its stores' rates, by fixed rules.

    Faces stored at the served size in PNG (``<size>^2 PNG``) and at twice it are each judged against the A100
    estimate and :data:`FASTER_GPU` times it (both remap sites, worker / device); when faces at the served size do
    not feed the faster GPU, the stores and sites that would are named.

    Example:
        >>> stores = {"512^2 PNG": {"worker": 290.0, "device": 420.0},
        ...           "512^2 JPEG + npy": {"worker": 440.0, "device": 830.0},
        ...           "1024^2 PNG": {"worker": 115.0, "device": 135.0}}
        >>> verdict(276.0, stores, 512)
        'feeds an A100-class GPU from 512^2 PNG faces (1.05x / 1.52x the estimate, worker / device); a 2x faster \
one only from 512^2 JPEG + npy faces with `remap_on=device` (830/s); **starved from 1024^2 PNG faces** (0.42x / \
0.49x the A100 estimate)'
    """
    clauses = []
    primary = stores.get(f"{size}^2 PNG")
    if primary is not None:
        fed_faster = max(_sites(primary).values()) >= FASTER_GPU * a100
        clauses.append(_clause(f"{size}^2 PNG faces", primary, a100, say_faster=fed_faster))
        if not fed_faster:
            clauses.append(_faster_gpu(a100, stores))
    larger = stores.get(f"{2 * size}^2 PNG")
    if larger is not None:
        clauses.append(_clause(f"{2 * size}^2 PNG faces", larger, a100))
    return "; ".join(clauses)


def _sites(store: Mapping[str, Any]) -> dict[str, float]:
    return {site: store[site] for site in ("worker", "device") if site in store}


def _clause(name: str, store: Mapping[str, Any], a100: float, say_faster: bool = True) -> str:
    """How ``store`` feeds the A100 estimate (and, with ``say_faster``, whether a faster GPU)."""
    sites = _sites(store)
    ratios = " / ".join(f"{rate / a100:.2f}x" for rate in sites.values())
    which = " / ".join(sites)
    low, high = min(sites.values()) / a100, max(sites.values()) / a100
    best = max(sites, key=sites.get)
    if low >= FASTER_GPU:
        return f"**keeps up** from {name}, a {FASTER_GPU:g}x faster GPU too ({ratios} the A100 estimate, {which})"
    if low >= 1:
        faster = (
            f"; a {FASTER_GPU:g}x faster one with `remap_on={best}`"
            if high >= FASTER_GPU
            else f", not a {FASTER_GPU:g}x faster one"
        )
        faster = faster if say_faster else ""
        return f"feeds an A100-class GPU from {name} ({ratios} the estimate, {which}){faster}"
    if high >= 1:
        return f"feeds an A100-class GPU from {name} only with `remap_on={best}` ({ratios} the estimate, {which})"
    return f"**starved from {name}** ({ratios} the A100 estimate)"


def _faster_gpu(a100: float, stores: Mapping[str, Mapping[str, Any]]) -> str:
    """Which stores and sites reach :data:`FASTER_GPU` times the A100 estimate."""
    enough = [
        f"{name} faces with `remap_on={site}` ({rate:.0f}/s)"
        for name, store in stores.items()
        for site, rate in _sites(store).items()
        if rate >= FASTER_GPU * a100
    ]
    if not enough:
        return f"no measured store feeds a {FASTER_GPU:g}x faster one"
    return f"a {FASTER_GPU:g}x faster one only from " + ", ".join(enough)


def table(rows: Sequence[Row]) -> str:
    """The markdown table of ``docs/benchmarks.md`` ("Can 16 cores feed one H100?")."""
    (size,) = {row.size for row in rows}
    header = (
        f"| recipe | forward GFLOP at {size}^2 | A100 estimate (images/s) | needed per core, A100 estimate / "
        f"{FASTER_GPU:g}x | {WORKERS} cores give ({size}^2 PNG faces, worker / device) | from {2 * size}^2 PNG "
        "faces | verdict |"
    )
    lines = [header, "|---|---:|---:|---|---:|---:|---|"]
    for row in rows:
        lines.append(
            f"| {row.label} | {row.gflop:.1f} | {row.a100_images_per_s:.0f} | {row.needed_per_core():.1f} / "
            f"{row.needed_per_core(FASTER_GPU):.1f} | {_pair(row.stores.get(f'{size}^2 PNG'))} | "
            f"{_pair(row.stores.get(f'{2 * size}^2 PNG'))} | {verdict(row.a100_images_per_s, row.stores, size)} |"
        )
    return "\n".join(lines)


def _pair(store: Mapping[str, Any] | None) -> str:
    if store is None:
        return "–"
    return " / ".join(f"{rate:.0f}" for rate in _sites(store).values())


def rows_json(rows: Sequence[Row]) -> list[dict[str, Any]]:
    """The rows as the record keeps them (each with its verdict and per-core needs)."""
    return [
        asdict(row)
        | {
            "needed_per_core": row.needed_per_core(),
            f"needed_per_core_{FASTER_GPU:g}x": row.needed_per_core(FASTER_GPU),
            "verdict": verdict(row.a100_images_per_s, row.stores, row.size),
        }
        for row in rows
    ]
