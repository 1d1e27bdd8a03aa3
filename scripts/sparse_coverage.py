"""How densely the sparse LiDAR input covers each incidence-angle ring of the served fisheye image.

    python scripts/sparse_coverage.py --preset quickstart --split test --size 128 --every 8 \
        --json docs/figures/sparse_coverage.json

Prints, per ring, the number of sparse-depth pixels per pixel with ground-truth depth, over every ``--every``-th
frame of the split (the completion input exactly as training serves it, without augmentation); ``--json`` also
writes them with the command, the commit and the dataset's content identity (``docs/results.md`` section 5 reads
that file).
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import torch

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.evaluation.quickstart import git_commit
from airfisheye_bench.io.content import content_identity
from airfisheye_bench.metrics import DEFAULT_RING_EDGES_DEG, bin_index
from datamodules import AirFisheyeDataModule


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", default=None, help="dataset root (default: the synthetic --preset)")
    parser.add_argument("--preset", default="quickstart")
    parser.add_argument("--split", default="test", choices=("train", "val", "test"))
    parser.add_argument("--size", type=int, default=128, help="served image size")
    parser.add_argument("--every", type=int, default=8, help="use every n-th frame")
    parser.add_argument(
        "--json", type=Path, help="also write the ratios (and how they were made) to this file"
    )
    args = parser.parse_args(argv)

    dm = AirFisheyeDataModule(
        "completion", root=args.root, preset=None if args.root else args.preset, camera={"size": args.size}
    )
    dataset = dm.split_dataset(args.split)
    ring = bin_index(torch.rad2deg(dataset.camera.theta_grid()), DEFAULT_RING_EDGES_DEG, include_lowest=True)
    count = len(DEFAULT_RING_EDGES_DEG) - 1
    sparse, truth = torch.zeros(count), torch.zeros(count)
    frames = range(0, len(dataset), args.every)
    for index in frames:
        sample = dataset[index]
        for k in range(count):
            sparse[k] += ((sample["sparse_depth"][0] > 0) & (ring == k)).sum()
            truth[k] += ((sample["depth"][0] > 0) & (ring == k)).sum()
    print(
        f"{len(frames)} frames of {args.split}, {args.size}^2: sparse pixels per ground-truth pixel by ring"
    )
    rings = []
    for k, (lo, hi) in enumerate(itertools.pairwise(DEFAULT_RING_EDGES_DEG)):
        ratio = float(sparse[k] / truth[k])
        rings.append({"theta_deg": [lo, hi], "sparse_per_truth_pixel": ratio})
        print(f"  theta {lo:g}-{hi:g} deg: {ratio:.3f}")
    if args.json is not None:
        root = dm.dataset_root()
        identity = content_identity(root)
        record = {
            "command": "python scripts/sparse_coverage.py "
            + " ".join(sys.argv[1:] if argv is None else argv),
            "commit": git_commit(Path(__file__).resolve().parents[1]),
            "dataset": {"root_name": root.name, "content_sha256": identity["content_sha256"]},
            "split": args.split,
            "size": args.size,
            "frames": len(frames),
            "rings": rings,
        }
        atomic_write_text(args.json, json.dumps(record, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
