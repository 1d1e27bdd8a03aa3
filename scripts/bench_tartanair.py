"""Loading speed of ``data.format=tartanair`` against the synthetic AirFisheye layout, side by side in one run.

Both datasets hold the same kind of frames: 256^2 cube faces (PNG RGB, labels; depth as each format stores it: the
synthetic release's 16-bit PNG range, TartanAir's float32-in-RGBA planar depth) and a 16-channel LiDAR. The
TartanAir one is the test fixture's analytic scene (:mod:`airfisheye_bench.studies.miniature_datasets.tartanair`,
written in the toolkit's layout) with the dataset's own VLP-16 pattern (16 x 3600 beams); the synthetic one is the
``tiny`` preset at the same face size with a 16 x 1800 LiDAR. Per task, the two are timed alternately,
``--repeats`` times each, one process and one thread, served from the cube faces at ``--size``^2 with training
augmentation; the table gives the minimum and the median CPU ms per sample.

Usage:
    python scripts/bench_tartanair.py [--size 256] [--samples 12] [--repeats 5] [--work /tmp/afb_bench_tartanair]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from pathlib import Path

import torch

from airfisheye_bench.studies.miniature_datasets.tartanair import write_tartanair_fixture
from airfisheye_bench.synth.presets import get_preset
from airfisheye_bench.synth.writer import generate_dataset
from datamodules import AirFisheyeDataset, CameraConfig, FisheyeAugment

FACE = 256


def datasets(work: Path) -> dict[str, tuple[Path, str, dict]]:
    """``name -> (root, data.format, format_options)``, written on first use."""
    tartanair = work / "tartanair"
    if not tartanair.is_dir():
        write_tartanair_fixture(tartanair, size=FACE, frames=4, azimuths=3600)
    cfg = dataclasses.replace(
        get_preset("tiny"),
        face_size=FACE,
        fisheye_size=FACE,
        lidar_channels=16,
        lidar_points_per_channel=1800,
    )
    synthetic = generate_dataset(cfg, work / "synthetic", seed=0, workers=1, progress=False)
    return {
        "synthetic (airfisheye)": (synthetic, "airfisheye", {}),
        "tartanair": (tartanair, "tartanair", {"split_period": 3}),
    }


def loader(root: Path, fmt: str, options: dict, task: str, size: int) -> AirFisheyeDataset:
    ds = AirFisheyeDataset.from_root(
        root,
        "train",
        task,
        source="cubemap",
        camera=CameraConfig(size=size, model="equidistant", fov_deg=190.0),
        augment=FisheyeAugment(hflip=0.5, rotate_deg=10.0),
        format=fmt,
        format_options=options,
    )
    ds.warm_up()
    # Compile the kernels and fill the per-trajectory caches (TartanAir: the LiDAR axes check).
    for i in range(len(ds)):
        ds[i]
    return ds


def cpu_ms(ds: AirFisheyeDataset, samples: int) -> float:
    t0 = time.process_time()
    for i in range(samples):
        ds[i % len(ds)]
    return (time.process_time() - t0) / samples * 1e3


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--samples", type=int, default=12)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--tasks", nargs="+", default=["seg", "depth", "completion"])
    parser.add_argument("--work", default="/tmp/afb_bench_tartanair")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    data = datasets(Path(args.work))
    print(
        f"served {args.size}^2 from {FACE}^2 faces; one process, one thread; {args.samples} samples x {args.repeats}"
    )
    print("| task | dataset | ms / sample (CPU, min) | ms / sample (CPU, median) |")
    print("|---|---|---|---|")
    results = []
    for task in args.tasks:
        loaders = {name: loader(*spec, task, args.size) for name, spec in data.items()}
        times: dict[str, list[float]] = {name: [] for name in loaders}
        for _ in range(args.repeats):  # alternate, so that load changes hit both alike
            for name, ds in loaders.items():
                times[name].append(cpu_ms(ds, args.samples))
        for name, t in times.items():
            results.append({"task": task, "dataset": name, "min": min(t), "median": statistics.median(t)})
            print(f"| {task} | {name} | {min(t):.1f} | {statistics.median(t):.1f} |")
    return results


if __name__ == "__main__":
    main()
