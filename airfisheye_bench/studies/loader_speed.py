"""Data-loading speed: ms per sample (one process, one thread; samples/s from CPU time) for every task and source at a served resolution.

A sample is everything ``AirFisheyeDataset.__getitem__`` does: decode the files, remap the cube faces (cubemap
source), map labels, project the LiDAR scan with occlusion correction (completion) and augment (flip, colour jitter,
rotation). Also reports the resident memory growth over the loop (it should stay flat).

``--remap-on device`` times what a worker does under ``data.remap_on=device`` instead (``load_faces``: decode the
faces, check the texels the fisheye sees, project the LiDAR, draw the augmentation; the remap, augmentation and
normalisation then run on the model's device, which this CPU benchmark does not time).

One process with one thread is one loader worker on one core, so ``1000 / ms`` is the samples/s **per core**; a
machine with ``N`` cores feeds at most about ``N - 1`` times that (the main process drives the model). Each
configuration runs ``--repeats`` times (the loop over ``--samples`` samples); the table gives the minimum and the
median over the repeats of the mean CPU time per sample (single runs on a shared machine vary by +-20%).

Several datasets at once: ``--root A B --size 512 1024`` serves ``A`` at 512^2 and ``B`` at 1024^2 (one size for
every root, or one root at every size, also work). ``--out FILE`` writes the rows as JSON with their provenance
(commit, command, machine, the load average before and after, and each root's dataset identity under ``datasets``:
name, root and content SHA-256, :func:`~airfisheye_bench.runs.results.dataset_identity`).

``--lenses fixed drawn pooled`` times the same configuration with the split's one lens (``fixed``), with a lens
drawn per sample (``drawn``: :data:`DRAWN_LENSES` with :data:`DRAWN_JITTER`, the lens study's arm b) and with the
epoch's lenses drawn from a pool of :data:`POOL` (``pooled``), their repeats interleaved so all see the same
machine. Each loop serves an epoch no earlier loop served, so a drawn lens is one a long training would meet (a
jittered lens is rarely served twice). ``pooled`` loops twice over its epoch: the first builds the pool's tables
(``cold_*``: what an epoch pays once per worker), the second serves from them (the row's times: every later sample
of the epoch).

Usage:
    python scripts/bench_loader.py [--root DIR ... | --preset small] [--size 512 ...] [--samples 40] [--repeats 5]
        [--tasks seg depth completion] [--sources cubemap fisheye] [--remap-on worker device]
        [--lenses fixed drawn] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shlex
import statistics
import sys
import time
from pathlib import Path

import torch

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.io.dataset_spec import REMAP_SITES
from airfisheye_bench.runs.results import dataset_identity
from airfisheye_bench.specs import task_names
from airfisheye_bench.studies.provenance import git_commit, machine
from airfisheye_bench.synth.cache import ensure_dataset
from datamodules import AirFisheyeDataset, CameraConfig, FisheyeAugment

# The checkout this package sits in (benchmarks run from one).
ROOT = Path(__file__).resolve().parents[2]
#: ``--lenses drawn``: the lens study's training lenses and jitter (:mod:`airfisheye_bench.studies.lens_study`).
DRAWN_LENSES = (
    {"model": "equidistant", "fov_deg": 190},
    {"model": "equisolid", "fov_deg": 170},
    {"model": "stereographic", "fov_deg": 150},
    {"model": "equidistant", "fov_deg": 100},
)
DRAWN_JITTER = {"focal": 0.05, "principal_point_px": 2, "distortion": 0.05}
#: ``--lenses pooled``: the same with a pool of this many lenses per epoch (``data.camera.jitter.pool``).
POOL = 16


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def decode_ms(ds: AirFisheyeDataset, n: int) -> float:
    """CPU ms per sample spent reading and decoding the files alone (the storage format's share)."""
    # The dataset's modality files of the task's target ("label" is read from the "seg" files).
    modalities = ["rgb"] + (["seg"] if "label" in ds.sample_keys else ["depth"])
    t0 = time.process_time()
    for i in range(n):
        sid = ds.sample_ids[i % len(ds)]
        for m in modalities:
            ds.reader.cubemap(sid, m) if ds.source == "cubemap" else ds.reader.fisheye(sid, m)
        if "sparse_depth" in ds.sample_keys:
            ds.reader.lidar(sid)
    return (time.process_time() - t0) / n * 1e3


def bench(
    root, task: str, source: str, size: int, samples: int, repeats: int, remap_on: str = "worker"
) -> dict[str, float]:
    """CPU ms per sample (min and median over ``repeats`` loops), wall ms, decode ms and RSS growth (MB)."""
    return bench_lenses(root, task, source, size, samples, repeats, remap_on, ("fixed",))["fixed"]


def _dataset(root, task: str, source: str, size: int, lenses: str) -> AirFisheyeDataset:
    augment = FisheyeAugment(hflip=0.5, rotate_deg=10.0)
    jitter = {**DRAWN_JITTER, "pool": POOL} if lenses == "pooled" else DRAWN_JITTER
    camera = (
        CameraConfig(size=size)
        if lenses == "fixed"
        else CameraConfig(size=size, lenses=DRAWN_LENSES, jitter=jitter)
    )
    ds = AirFisheyeDataset.from_root(root, "train", task, source=source, camera=camera, augment=augment)
    ds.warm_up()
    return ds


def bench_lenses(
    root,
    task: str,
    source: str,
    size: int,
    samples: int,
    repeats: int,
    remap_on: str = "worker",
    lenses: tuple[str, ...] = ("fixed",),
) -> dict[str, dict[str, float]]:
    """:func:`bench`'s numbers for each of ``lenses`` (``fixed``, ``drawn``), their loops interleaved."""
    datasets = {name: _dataset(root, task, source, size, name) for name in lenses}
    loads = {name: ds.load_faces if remap_on == "device" else ds.__getitem__ for name, ds in datasets.items()}
    n = min(samples, len(next(iter(datasets.values()))))
    for load in loads.values():
        load(0)  # first call compiles kernels and fills caches
    rss0 = rss_mb()
    cpu: dict[str, list[float]] = {name: [] for name in lenses}
    wall: dict[str, list[float]] = {name: [] for name in lenses}
    cold: list[float] = []
    for repeat in range(repeats):
        for name, load in loads.items():
            datasets[name].set_epoch(repeat + 1)  # new draws: a lens no earlier loop served
            if name == "pooled":  # the first pass builds the epoch's pool
                c0 = time.process_time()
                for i in range(n):
                    load(i % len(datasets[name]))
                cold.append((time.process_time() - c0) / n * 1e3)
            t0, c0 = time.perf_counter(), time.process_time()
            for i in range(n):
                load(i % len(datasets[name]))
            wall[name].append((time.perf_counter() - t0) / n * 1e3)
            cpu[name].append((time.process_time() - c0) / n * 1e3)
    out = {name: _summary(datasets[name], source, n, cpu[name], wall[name], rss0) for name in lenses}
    if cold:
        out["pooled"] |= {"cold_cpu_median": statistics.median(cold), "pool": POOL}
    return out


def _summary(
    ds: AirFisheyeDataset, source: str, n: int, cpu: list[float], wall: list[float], rss0: float
) -> dict[str, float]:
    return {
        "samples": n,  # --samples, or the split's frames where it has fewer
        "cpu_min": min(cpu),
        "cpu_median": statistics.median(cpu),
        "wall_min": min(wall),
        "wall_median": statistics.median(wall),
        "decode": decode_ms(ds, n),
        "rss_growth": rss_mb() - rss0,
        "face_size": ds.face_size if source == "cubemap" else None,
        "rgb_encoding": ds.spec.files.rgb,
        "depth_encoding": ds.spec.files.depth,
    }


def pairs(roots: list, sizes: list[int]) -> list[tuple]:
    """``(root, size)`` to serve: zipped, or one size for every root, or one root at every size.

    Example:
        >>> pairs(["a", "b"], [512, 1024]), pairs(["a", "b"], [512]), pairs(["a"], [512, 1024])
        ([('a', 512), ('b', 1024)], [('a', 512), ('b', 512)], [('a', 512), ('a', 1024)])
    """
    if len(sizes) == 1:
        return [(r, sizes[0]) for r in roots]
    if len(roots) == 1:
        return [(roots[0], s) for s in sizes]
    if len(roots) != len(sizes):
        raise SystemExit(f"--root and --size: {len(roots)} roots and {len(sizes)} sizes do not pair up")
    return list(zip(roots, sizes, strict=True))


def main(argv: list[str] | None = None) -> list[dict]:
    """Run the table; returns one result per (root, size, task, source, remap site) with :func:`bench`'s keys."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", nargs="+", default=None, help="dataset root(s) (default: --preset)")
    parser.add_argument("--preset", default="small")
    parser.add_argument(
        "--size", nargs="+", type=int, default=[512], help="served size(s), paired with --root"
    )
    parser.add_argument("--samples", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=1, help="loops per configuration (min and median)")
    parser.add_argument("--tasks", nargs="+", default=list(task_names()))
    parser.add_argument("--sources", nargs="+", default=["cubemap", "fisheye"])
    parser.add_argument(
        "--remap-on", nargs="+", default=["worker"], choices=REMAP_SITES, help="data.remap_on (cubemap only)"
    )
    parser.add_argument(
        "--lenses",
        nargs="+",
        default=["fixed"],
        choices=["fixed", "drawn", "pooled"],
        help="one lens, one drawn per sample, or from a per-epoch pool",
    )
    parser.add_argument(
        "--out", default=None, help="also write the rows with their provenance to this JSON file"
    )
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    roots = args.root or [ensure_dataset(args.preset)]
    commit = git_commit(ROOT)  # the code this process runs (the tree may change while it measures)
    load_before = os.getloadavg()
    print(
        f"one process, one thread; up to {args.samples} samples (a split with fewer serves each of its frames) "
        f"x {args.repeats} repeat(s); load {load_before}"
    )
    print(
        "| dataset | size | task | source | remap on | lenses | samples | ms / sample (CPU, min) | ms / sample (CPU, median) "
        "| ms / sample (wall, median) | of which file decode (CPU) | samples/s per core (CPU, median) "
        "| RSS growth (MB) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    results = []
    for root, size in pairs(roots, args.size):
        for task in args.tasks:
            for source in args.sources:
                for remap_on in args.remap_on:
                    if remap_on == "device" and source != "cubemap":
                        continue  # nothing to remap
                    lenses = tuple(args.lenses) if source != "fisheye" else ("fixed",)
                    measured = bench_lenses(
                        root, task, source, size, args.samples, args.repeats, remap_on, lenses
                    )
                    for name, r in measured.items():
                        row = {
                            "root": str(root),
                            "size": size,
                            "task": task,
                            "source": source,
                            "remap_on": remap_on,
                            "lenses": name,
                        }
                        row |= r | {"samples_per_s_per_core": 1e3 / r["cpu_median"]}
                        results.append(row)
                        print(
                            f"| {Path(root).name} | {size} | {task} | {source} | {remap_on} | {name} | {r['samples']} "
                            f"| {r['cpu_min']:.1f} | {r['cpu_median']:.1f} | {r['wall_median']:.1f} "
                            f"| {r['decode']:.1f} | {row['samples_per_s_per_core']:.1f} | {r['rss_growth']:.1f} |"
                        )
    if args.out:
        record = {
            "command": shlex.join(
                ["python", "scripts/bench_loader.py", *(sys.argv[1:] if argv is None else argv)]
            ),
            "commit": commit,
            "machine": machine(),
            "threads": 1,
            "samples": args.samples,
            "repeats": args.repeats,
            "load_average_before": list(load_before),
            "load_average_after": list(os.getloadavg()),
            "datasets": [dataset_identity(root, Path(root).name) for root in dict.fromkeys(map(str, roots))],
            "results": results,
        }
        atomic_write_text(args.out, json.dumps(record, indent=1) + "\n")
    return results
