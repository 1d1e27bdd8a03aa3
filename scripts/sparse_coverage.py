"""How densely the sparse LiDAR input covers each incidence-angle ring of the served fisheye image.

    python scripts/sparse_coverage.py --preset quickstart --split test --size 128 --every 8 \
        --json docs/figures/sparse_coverage.json
    python scripts/sparse_coverage.py --preset quickstart --split test --size 128 --every 8 --density paper

Prints, per ring, the number of sparse-depth pixels per pixel with ground-truth depth, over every ``--every``-th
frame of the split (the completion input exactly as training serves it with ``data.lidar.density=--density``,
without augmentation), beside the paper's sensor (64 x 2048) on the paper's 1536^2 image over the same frames
(computed from the LiDAR spec and the camera where the frames have ground truth: ``datamodules.coverage``);
``--json`` also writes them with the command, the commit and the dataset's content identity (``docs/results.md``
section 5 reads that file).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_density import LIDAR_DENSITIES
from airfisheye_bench.io.content import content_identity
from airfisheye_bench.studies.provenance import git_commit
from datamodules import AirFisheyeDataModule
from datamodules.coverage import sparse_coverage


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", default=None, help="dataset root (default: the synthetic --preset)")
    parser.add_argument("--preset", default="quickstart")
    parser.add_argument("--split", default="test", choices=("train", "val", "test"))
    parser.add_argument("--size", type=int, default=128, help="served image size")
    parser.add_argument("--every", type=int, default=8, help="use every n-th frame")
    parser.add_argument(
        "--density", default="native", choices=LIDAR_DENSITIES, help="data.lidar.density of the served input"
    )
    parser.add_argument(
        "--json", type=Path, help="also write the ratios (and how they were made) to this file"
    )
    args = parser.parse_args(argv)

    dm = AirFisheyeDataModule(
        "completion",
        root=args.root,
        preset=None if args.root else args.preset,
        camera={"size": args.size},
        lidar={"density": args.density},
    )
    dataset = dm.split_dataset(args.split)
    frames = range(0, len(dataset), args.every)
    coverage = sparse_coverage(dataset, args.every, reference=LidarSpec())
    print(
        f"{len(frames)} frames of {args.split}: sparse pixels per ground-truth pixel by ring, served at "
        f"{args.size}^2 (data.lidar.density={args.density}) and the paper's 64 x 2048 sensor at 1536^2"
    )
    print(f"  {'ring':<12}{'served':>9}{'paper':>9}{'ratio':>8}")
    rings = []
    for key, served in coverage["served"].items():
        paper = coverage["paper_1536"][key]
        lo, hi = (float(v) for v in key.removeprefix("ring_").split("-"))
        rings.append({"theta_deg": [lo, hi], "sparse_per_truth_pixel": served, "paper_1536": paper})
        print(f"  {key:<12}{served:>9.4f}{paper:>9.4f}{served / paper:>8.2f}")
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
            "density": args.density,
            "frames": len(frames),
            "rings": rings,
        }
        atomic_write_text(args.json, json.dumps(record, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
