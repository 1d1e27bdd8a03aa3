"""What serving and scoring several sources (``data.sources``) adds: the same frames, one source against a mixture.

Loading: ms per training sample (CPU, one thread) of ``AirFisheyeDataset`` alone, and of the same frames through a
``MultiSourceDataset`` of two sources (the dataset and itself, the second with a ``class_map``, so that the label
lookup runs), measured alternately in one process, ``--repeats`` times each (minimum and median).

Scoring: ms per batch of ``TaskScorer.update`` on the whole batch (one source), and split by source into two
updates of the sources' scorers, as ``BenchmarkTask._score`` does for a mixture (the pooled scores are the sources'
added up once per epoch, ``TaskScorer.add``; its cost is printed too). The rows are one markdown table.

Usage:
    python scripts/bench_multi_source.py --root DIR [--size 128] [--samples 40] [--repeats 5] [--batch 8]
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from airfisheye_bench.metrics import DEFAULT_RING_EDGES_DEG
from airfisheye_bench.metrics.scorer import TaskScorer
from airfisheye_bench.specs import get_task
from datamodules import AirFisheyeDataset, CameraConfig, FisheyeAugment
from datamodules.multi_source import MultiSourceDataset
from datamodules.sources import CommonClasses, SourceConfig, class_lut


def loop_ms(dataset, n: int) -> float:
    """Mean CPU ms of ``dataset[i]`` over ``n`` samples."""
    t0 = time.process_time()
    for i in range(n):
        dataset[i % len(dataset)]
    return (time.process_time() - t0) / n * 1e3


def loading(root: str, size: int, samples: int, repeats: int) -> dict[str, list[float]]:
    kwargs = dict(camera=CameraConfig(size=size), augment=FisheyeAugment(hflip=0.5, rotate_deg=10.0))
    single = AirFisheyeDataset.from_root(root, "train", "seg", **kwargs)
    first, second = (
        AirFisheyeDataset.from_root(root, "train", "seg", **kwargs),
        AirFisheyeDataset.from_root(root, "train", "seg", **kwargs),
    )
    common = CommonClasses.benchmark("a + b")
    names = first.spec.train_class_names
    lut = class_lut(SourceConfig("b", root=root, class_map={n: n for n in names}), names, 255, common)
    mixture = MultiSourceDataset({"a": first, "b": second}, common, {"b": lut})
    for ds in (single, first, second):
        ds.warm_up()
    single[0], mixture[0]  # first calls compile kernels and fill caches
    times: dict[str, list[float]] = {"one source": [], "two sources": []}
    for _ in range(repeats):  # alternately, so that drift of the machine hits both alike
        times["one source"].append(loop_ms(single, samples))
        times["two sources"].append(loop_ms(mixture, samples))
    return times


def scoring(size: int, batch: int, repeats: int) -> dict[str, list[float]]:
    spec = get_task("seg")
    make = lambda: spec.make_metric(class_names=CommonClasses.benchmark("x").train_class_names)  # noqa: E731
    pooled, a, b = (TaskScorer(make, DEFAULT_RING_EDGES_DEG, None) for _ in range(3))
    generator = torch.Generator().manual_seed(0)
    pred = torch.randint(0, 13, (batch, size, size), generator=generator)
    target = torch.randint(0, 13, (batch, size, size), generator=generator)
    mask = torch.ones(batch, size, size, dtype=torch.bool)
    theta = torch.linspace(0, 95, size * size).view(size, size)
    sources = ["a"] * (batch // 2) + ["b"] * (batch - batch // 2)

    def whole() -> None:
        pooled.update(pred, target, theta=theta, mask=mask)

    def split() -> None:  # as BenchmarkTask._score: each source's rows into its own scorer
        for name, scorer in (("a", a), ("b", b)):
            rows = torch.tensor([i for i, s in enumerate(sources) if s == name])
            part = (pred[rows], target[rows], mask[rows])
            scorer.update(*part[:2], theta=theta, mask=part[2])

    times: dict[str, list[float]] = {"one source": [], "two sources": []}
    for _ in range(repeats):
        for label, step in (("one source", whole), ("two sources", split)):
            t0 = time.process_time()
            for _ in range(10):
                step()
            times[label].append((time.process_time() - t0) / 10 * 1e3)
        t0 = time.process_time()
        total = TaskScorer(make, DEFAULT_RING_EDGES_DEG, None)
        total.add(a)
        total.add(b)
        times.setdefault("pool: add", []).append((time.process_time() - t0) * 1e3)
    return times


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", required=True, help="a dataset in the AirFisheye layout")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--samples", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--batch", type=int, default=8)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    print(f"seg, {args.size}^2, one thread; min / median of {args.repeats} repeats, CPU ms\n")
    # A markdown table, so that a record of this output (scripts/bench_record.py) holds the table the docs show.
    print("| step | sources | ms (CPU, min) | ms (CPU, median) |")
    print("|---|---|---|---|")
    for what, times in (
        (
            f"load a training sample ({args.samples} samples)",
            loading(args.root, args.size, args.samples, args.repeats),
        ),
        (f"score a batch of {args.batch} (10 batches)", scoring(args.size, args.batch, args.repeats)),
    ):
        for label, values in times.items():
            print(f"| {what} | {label} | {min(values):.2f} | {statistics.median(values):.2f} |")


if __name__ == "__main__":
    main()
