"""Speed of the metric updates on CPU: how long evaluating a split of N frames spends in the metrics.

Updates each metric with synthetic ``[B, ., H, W]`` batches until ``--frames`` frames were seen, on one
thread by default, and prints a markdown table of ms/frame and the extrapolated seconds per 1000 frames.

    python scripts/bench_metrics.py                      # 1000 frames at 512x512, batch 8, 13 classes
    python scripts/bench_metrics.py --frames 64 --size 256
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import torch

from airfisheye_bench.metrics import BinnedMetrics, CompletionMetrics, DepthMetrics, SegmentationMetrics


def _theta_grid(size: int, fov_deg: float = 190.0) -> torch.Tensor:
    """Equidistant incidence angle in degrees, image circle inscribed (stand-in for the camera's grid)."""
    c = (size - 1) / 2
    v, u = torch.meshgrid(torch.arange(size) - c, torch.arange(size) - c, indexing="ij")
    return torch.hypot(u, v) / (size / 2) * (fov_deg / 2)


def _time(update: Callable[[], None], n_updates: int, frames: int) -> tuple[float, float]:
    """Wall-clock and process CPU milliseconds per frame (CPU time stays meaningful on a busy machine)."""
    update()  # warm-up (allocator, first-call overheads)
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(n_updates):
        update()
    return (time.perf_counter() - wall) / frames * 1e3, (time.process_time() - cpu) / frames * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--size", type=int, default=512, help="square frame side in pixels")
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--classes", type=int, default=13)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)

    g = torch.Generator().manual_seed(0)
    b, s, c = args.batch, args.size, args.classes
    gt = torch.rand(b, 1, s, s, generator=g) * 130.0
    gt[torch.rand(b, 1, s, s, generator=g) < 0.3] = 0.0
    pred = gt * torch.exp(0.2 * torch.randn(b, 1, s, s, generator=g)) + 0.1
    logits = torch.randn(b, c, s, s, generator=g)
    labels = torch.randint(0, c, (b, s, s), generator=g)
    labels[:, :, : s // 10] = 255
    pred_labels = logits.argmax(1)
    theta = _theta_grid(s)

    seg, seg_labels, depth, completion = (
        SegmentationMetrics(c),
        SegmentationMetrics(c),
        DepthMetrics(),
        CompletionMetrics(),
    )
    rings = BinnedMetrics(DepthMetrics, key="theta")
    ranges = BinnedMetrics(CompletionMetrics, key="depth")
    cases: list[tuple[str, Callable[[], None]]] = [
        (f"SegmentationMetrics, logits [B, {c}, H, W]", lambda: seg.update(logits, labels)),
        ("SegmentationMetrics, labels [B, H, W]", lambda: seg_labels.update(pred_labels, labels)),
        ("DepthMetrics", lambda: depth.update(pred, gt)),
        ("CompletionMetrics", lambda: completion.update(pred, gt)),
        ("BinnedMetrics(DepthMetrics), 4 theta rings", lambda: rings.update(pred, gt, theta=theta)),
        ("BinnedMetrics(CompletionMetrics), 5 depth ranges", lambda: ranges.update(pred, gt)),
    ]
    n_updates = max(1, round(args.frames / b))
    frames = n_updates * b
    print(f"{frames} frames of {s}x{s}, batch {b}, {args.threads} thread(s), torch {torch.__version__}\n")
    print("| metric update | wall ms/frame | CPU ms/frame | wall s per 1000 frames |")
    print("|---|---:|---:|---:|")
    total_wall = total_cpu = 0.0
    for i, (name, update) in enumerate(cases):
        wall, cpu = _time(update, n_updates, frames)
        if i in (0, 2, 3):  # the three task metrics as evaluated after a segmentation/depth/completion run
            total_wall, total_cpu = total_wall + wall, total_cpu + cpu
        print(f"| {name} | {wall:.2f} | {cpu:.2f} | {wall:.1f} |")
    print(
        f"| **seg (logits) + depth + completion** | **{total_wall:.2f}** | **{total_cpu:.2f}** | **{total_wall:.1f}** |"
    )
    start = time.perf_counter()
    for metric in (seg, depth, completion, rings, ranges):
        metric.compute()
    print(f"\ncompute() of all metrics: {(time.perf_counter() - start) * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
