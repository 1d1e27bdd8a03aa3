"""Data-loading speed: ms per sample (one process, one thread; samples/s from CPU time) for every task and source at a served resolution.

A sample is everything ``AirFisheyeDataset.__getitem__`` does: decode the files, remap the cube faces (cubemap
source), map labels, project the LiDAR scan with occlusion correction (completion) and augment (flip, colour jitter,
rotation). Also reports the resident memory growth over the loop (it should stay flat).

Each configuration runs ``--repeats`` times (the loop over ``--samples`` samples); the table gives the minimum and
the median over the repeats of the mean CPU time per sample (single runs on a shared machine vary by +-20%).

Usage:
    python scripts/bench_loader.py [--root DIR | --preset small] [--size 512] [--samples 40] [--repeats 5]
        [--tasks seg depth completion] [--sources cubemap fisheye]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time

import torch

from airfisheye_bench.specs import task_names
from airfisheye_bench.synth.cache import ensure_dataset
from datamodules import AirFisheyeDataset, CameraConfig, FisheyeAugment


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


def bench(root, task: str, source: str, size: int, samples: int, repeats: int) -> dict[str, float]:
    """CPU ms per sample (min and median over ``repeats`` loops), wall ms, decode ms and RSS growth (MB)."""
    augment = FisheyeAugment(hflip=0.5, rotate_deg=10.0)
    ds = AirFisheyeDataset(
        root, "train", task, source=source, camera=CameraConfig(size=size), augment=augment
    )
    ds.warm_up()
    n = min(samples, len(ds))
    ds[0]  # first call compiles kernels and fills caches
    rss0 = rss_mb()
    cpu, wall = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(n):
            ds[i % len(ds)]
        wall.append((time.perf_counter() - t0) / n * 1e3)
        cpu.append((time.process_time() - c0) / n * 1e3)
    return {
        "cpu_min": min(cpu),
        "cpu_median": statistics.median(cpu),
        "wall_min": min(wall),
        "decode": decode_ms(ds, n),
        "rss_growth": rss_mb() - rss0,
    }


def main(argv: list[str] | None = None) -> list[dict]:
    """Run the table; returns one result per (task, source) with the keys of :func:`bench` plus both names."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", default=None, help="dataset root (default: generate/reuse --preset)")
    parser.add_argument("--preset", default="small")
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--samples", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=1, help="loops per configuration (min and median)")
    parser.add_argument("--tasks", nargs="+", default=list(task_names()))
    parser.add_argument("--sources", nargs="+", default=["cubemap", "fisheye"])
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    root = args.root
    if root is None:
        root = ensure_dataset(args.preset)
    print(
        f"dataset: {root}; served size {args.size}^2; one process, one thread; "
        f"{args.samples} samples x {args.repeats} repeat(s)"
    )
    print(
        "| task | source | ms / sample (CPU, min) | ms / sample (CPU, median) | ms / sample (wall, min) "
        "| of which file decode (CPU) | samples/s per worker (CPU, min) | RSS growth (MB) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    results = []
    for task in args.tasks:
        for source in args.sources:
            r = bench(root, task, source, args.size, args.samples, args.repeats)
            results.append({"task": task, "source": source, **r})
            print(
                f"| {task} | {source} | {r['cpu_min']:.1f} | {r['cpu_median']:.1f} | {r['wall_min']:.1f} "
                f"| {r['decode']:.1f} | {1e3 / r['cpu_min']:.1f} | {r['rss_growth']:.1f} |"
            )
    return results
