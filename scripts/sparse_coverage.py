"""How densely the sparse LiDAR input covers each incidence-angle ring of the served fisheye image, under every
return and under both readings of the paper's density, beside the paper's assumed sensor modelled on each reading's
image.

    python scripts/sparse_coverage.py --preset quickstart --split test --size 128 --every 8 \
        --json docs/figures/sparse_coverage_readings.json
    python scripts/sparse_coverage.py --preset quickstart --split test --size 128 --every 8 --density paper

Prints, per ring, the number of sparse-depth pixels per pixel with ground-truth depth, over every ``--every``-th
frame of the split: the completion input exactly as training serves it with each ``data.lidar.density`` of
``--density`` (default: every return, ``paper_1536`` and ``paper_512``), without augmentation; and beside them the
paper's side, which is *modelled*, not measured: the pixels of a 190 deg fisheye of 1536^2 and of 512^2 that a
nominal beam of the assumed 64 x 2048 sensor lands on where the frames have ground truth (docs/design.md, "Sparse
input density", states the assumptions; ``datamodules.coverage``). ``--json`` also writes them with the command,
the commit, the machine and the dataset's content identity.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_json
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_density import LIDAR_DENSITIES, PAPER_READINGS
from airfisheye_bench.studies.provenance import provenance
from datamodules import AirFisheyeDataModule
from datamodules.coverage import SERVED, sparse_coverage

#: The modelled columns, the 1536^2 image first.
MODELS = tuple(f"model_{size}" for size in sorted(set(PAPER_READINGS.values()), reverse=True))


def _sensor(spec: LidarSpec) -> str:
    lower, upper = spec.vfov_deg
    return (
        f"{spec.channels} x {spec.points_per_channel}, {spec.hfov_deg:g} deg horizontal, "
        f"{lower:g}..{upper:g} deg vertical"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", default=None, help="dataset root (default: the synthetic --preset)")
    parser.add_argument("--preset", default="quickstart")
    parser.add_argument("--split", default="test", choices=("train", "val", "test"))
    parser.add_argument("--size", type=int, default=128, help="served image size")
    parser.add_argument("--every", type=int, default=8, help="use every n-th frame")
    parser.add_argument(
        "--density",
        nargs="+",
        default=list(SERVED),
        choices=LIDAR_DENSITIES,
        help="data.lidar.density of the served inputs (default: %(default)s)",
    )
    parser.add_argument(
        "--json", type=Path, help="also write the ratios (and how they were made) to this file"
    )
    args = parser.parse_args(argv)

    served: dict[str, dict[str, float]] = {}
    modelled: dict[str, dict[str, float]] = {}
    for density in dict.fromkeys(args.density):
        dm = AirFisheyeDataModule(
            "completion",
            root=args.root,
            preset=None if args.root else args.preset,
            camera={"size": args.size},
            lidar={"density": density},
        )
        dataset = dm.split_dataset(args.split)
        # The modelled sensor depends on the frames, not on the served density: computed once.
        coverage = sparse_coverage(dataset, args.every, reference=None if modelled else LidarSpec())
        served[density] = coverage.pop("served")
        modelled = modelled or coverage
    frames = len(range(0, len(dataset), args.every))
    columns = [*(f"{d} {args.size}^2" for d in served), *(f"{m} (modelled)" for m in MODELS)]
    print(
        f"{frames} frames of {args.split}: sparse pixels per ground-truth pixel by ring, served at {args.size}^2 "
        "(data.lidar.density) and the paper's assumed 64 x 2048 sensor modelled on its 1536^2 and 512^2 images"
    )
    print(f"  {'ring':<12}" + "".join(f"{c:>{len(c) + 3}}" for c in columns))
    rings = []
    for key in served[next(iter(served))]:
        values = [*(served[d][key] for d in served), *(modelled[m][key] for m in MODELS)]
        print(f"  {key:<12}" + "".join(f"{v:>{len(c) + 3}.4f}" for c, v in zip(columns, values, strict=True)))
        lo, hi = (float(v) for v in key.removeprefix("ring_").split("-"))
        rings.append(
            {"theta_deg": [lo, hi], "served": {d: served[d][key] for d in served}}
            | {m: modelled[m][key] for m in MODELS}
        )
    print(
        "  (modelled: the nominal beam directions of an assumed sensor in an ideal 190 deg lens, not a "
        "measurement; docs/design.md, 'Sparse input density')"
    )
    if args.json is not None:
        root = dm.dataset_root()
        record = {
            "provenance": provenance("scripts/sparse_coverage.py", argv, root, root.name),
            "split": args.split,
            "size": args.size,
            "frames": frames,
            "densities": list(served),
            "modelled": {
                m: f"the assumed paper sensor ({_sensor(LidarSpec())}) on an ideal {m.removeprefix('model_')}^2, "
                "190 deg fisheye: nominal beam directions, not a measurement"
                for m in MODELS
            },
            "rings": rings,
        }
        atomic_write_json(args.json, record)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
