"""How densely the sparse LiDAR input covers each incidence-angle ring of the served fisheye image.

    python scripts/sparse_coverage.py --preset quickstart --split test --size 128 --every 8

Prints, per ring, the number of sparse-depth pixels per pixel with ground-truth depth, over every ``--every``-th
frame of the split (the completion input exactly as training serves it, without augmentation).
"""

from __future__ import annotations

import argparse
import itertools

import torch

from airfisheye_bench.metrics import DEFAULT_RING_EDGES_DEG, bin_index
from datamodules import AirFisheyeDataModule


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", default=None, help="dataset root (default: the synthetic --preset)")
    parser.add_argument("--preset", default="quickstart")
    parser.add_argument("--split", default="test", choices=("train", "val", "test"))
    parser.add_argument("--size", type=int, default=128, help="served image size")
    parser.add_argument("--every", type=int, default=8, help="use every n-th frame")
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
    for k, (lo, hi) in enumerate(itertools.pairwise(DEFAULT_RING_EDGES_DEG)):
        print(f"  theta {lo:g}-{hi:g} deg: {float(sparse[k] / truth[k]):.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
