"""Can 16 cores feed one GPU? The A100 estimate of each paper recipe's training images/s beside what 15 loader
workers make, printed as ``docs/benchmarks.md``'s table and written as a record.

    python scripts/gpu_feed_estimate.py [--loader docs/figures/loader_per_core.json] \
        [--out docs/figures/gpu_feed_estimate.json]

Counts the forward FLOPs of ResNet-50 at 224^2 and of the three recipes' models at their size (CPU, random weights,
no download; a minute or two), scales ResNet-50's published A100 rate by them, and reads the loader's per-core rates
from a committed ``scripts/bench_loader.py`` record. The logic is ``airfisheye_bench.studies.gpu_feed``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.studies import gpu_feed
from airfisheye_bench.studies.provenance import REPO, provenance


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--loader", type=Path, default=REPO / gpu_feed.LOADER_RECORD, help="bench_loader.py record"
    )
    parser.add_argument(
        "--out", type=Path, help="write the record here (e.g. docs/figures/gpu_feed_estimate.json)"
    )
    args = parser.parse_args()
    loader = json.loads(args.loader.read_text(encoding="utf-8"))
    resnet50 = gpu_feed.resnet50_gflop()
    recipes = []
    for task in gpu_feed.TASKS:
        recipes.append(gpu_feed.recipe_gflop(task))
        print(f"{task}: {recipes[-1]['gflop']:.1f} GFLOP", flush=True)
    rows = gpu_feed.estimate(recipes, resnet50, loader)
    output = (
        f"ResNet-50 at {gpu_feed.RESNET50_SIZE}^2: {resnet50:.2f} GFLOP; {gpu_feed.RESNET50_A100_IMAGES_PER_S:.0f} "
        f"images/s on one A100 (published)\n\n{gpu_feed.table(rows)}\n"
    )
    print(f"\n{output}", end="")
    if args.out is not None:
        record = {
            "provenance": provenance("scripts/gpu_feed_estimate.py"),
            "what": "an estimate, not a measurement: ResNet-50's published A100 training rate scaled by forward "
            "FLOPs, beside the loader's measured per-core rates times the workers",
            "resnet50": {
                "images_per_s_a100": gpu_feed.RESNET50_A100_IMAGES_PER_S,
                "source": "NVIDIA DeepLearningExamples, PyTorch/Classification/ConvNets/resnet50v1.5/README.md, "
                "'Training performance: NVIDIA DGX A100 (8x A100 80GB)', 1 GPU, mixed precision, pytorch-21.03",
                "size": gpu_feed.RESNET50_SIZE,
                "gflop": resnet50,
            },
            "cores": gpu_feed.CORES,
            "workers": gpu_feed.WORKERS,
            "faster_gpu": gpu_feed.FASTER_GPU,
            "loader_record": gpu_feed.loader_record_source(args.loader),
            "rows": gpu_feed.rows_json(rows),
            "output": output,
        }
        atomic_write_text(args.out, json.dumps(record, indent=2) + "\n")
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
