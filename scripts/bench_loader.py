"""Data-loading speed: ms per sample (one process, one thread; samples/s from CPU time) for every task and source at a served resolution.

A sample is everything ``AirFisheyeDataset.__getitem__`` does: decode the files, remap the cube faces (cubemap
source), map labels, project the LiDAR scan with occlusion correction (completion) and augment (flip, colour jitter,
rotation). Also reports the resident memory growth over the loop (it should stay flat).

Usage:
    python scripts/bench_loader.py [--root DIR | --preset small] [--size 512] [--samples 40]
"""

from __future__ import annotations

import argparse
import resource
import time

import torch

from datamodules import AirFisheyeDataset, CameraConfig, FisheyeAugment


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def decode_ms(ds: AirFisheyeDataset, n: int) -> float:
    """CPU ms per sample spent reading and decoding the files alone (the storage format's share)."""
    modalities = ["rgb"] + (["seg"] if ds.task == "seg" else ["depth"])
    t0 = time.process_time()
    for i in range(n):
        sid = ds.sample_ids[i % len(ds)]
        for m in modalities:
            ds.reader.cubemap(sid, m) if ds.source == "cubemap" else ds.reader.fisheye(sid, m)
        if ds.task == "completion":
            ds.reader.lidar(sid)
    return (time.process_time() - t0) / n * 1e3


def bench(root, task: str, source: str, size: int, samples: int) -> tuple[float, float, float, float]:
    augment = FisheyeAugment(hflip=0.5, rotate_deg=10.0)
    ds = AirFisheyeDataset(
        root, "train", task, source=source, camera=CameraConfig(size=size), augment=augment
    )
    ds.warm_up()
    n = min(samples, len(ds))
    ds[0]  # first call compiles kernels and fills caches
    rss0 = rss_mb()
    t0, c0 = time.perf_counter(), time.process_time()
    for i in range(n):
        ds[i % len(ds)]
    wall = (time.perf_counter() - t0) / n * 1e3
    cpu = (time.process_time() - c0) / n * 1e3
    return wall, cpu, decode_ms(ds, n), rss_mb() - rss0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", default=None, help="dataset root (default: generate/reuse --preset)")
    parser.add_argument("--preset", default="small")
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--samples", type=int, default=40)
    args = parser.parse_args()
    torch.set_num_threads(1)
    root = args.root
    if root is None:
        from airfisheye_bench.synth.writer import ensure_dataset

        root = ensure_dataset(args.preset)
    print(f"dataset: {root}; served size {args.size}^2; one process, one thread")
    print(
        "| task | source | ms / sample (wall) | ms / sample (CPU) | of which file decode (CPU) "
        "| samples/s per worker (CPU) | RSS growth (MB) |"
    )
    print("|---|---|---|---|---|---|---|")
    for task in ("seg", "depth", "completion"):
        for source in ("cubemap", "fisheye"):
            wall, cpu, dec, grow = bench(root, task, source, args.size, args.samples)
            print(
                f"| {task} | {source} | {wall:.1f} | {cpu:.1f} | {dec:.1f} | {1e3 / cpu:.1f} | {grow:.1f} |"
            )


if __name__ == "__main__":
    main()
