"""Test-time cross-over: one trained completion model tested with every sparse input, by region.

The logic is :mod:`airfisheye_bench.studies.crossover`; this script builds the inputs and prints the tables.

    # one model, every input, on the test split of the data it was trained on, served at 256²
    python scripts/occlusion_crossover.py --ckpt runs/xover --size 256 --json docs/figures/occlusion_crossover_256.json
    # without a model: how much each input differs from `none`, at several sizes (and with a real sensor's layout)
    python scripts/occlusion_crossover.py --preset occlusion --size 128 256 512 --json docs/figures/occlusion_inputs.json
    python scripts/occlusion_crossover.py --preset occlusion --lidar-preset hdl64e --size 256

With ``--ckpt`` the release, source, LiDAR and bounds are the run's (its ``config.yaml``); ``--size`` overrides the
served size (default: the run's). Without it, ``--preset`` (generated if missing) or ``--root`` is served with
``--source`` (default fisheye). ``--radius`` dilates the affected pixels (+- px), ``--near`` bounds the near range.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch

from airfisheye_bench.atomic import atomic_write_json
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation.predictors import CheckpointPredictor
from airfisheye_bench.geometry.lidar_density import LIDAR_DENSITIES
from airfisheye_bench.metrics.regions import DEFAULT_NEAR_M, DEFAULT_RADIUS_PX
from airfisheye_bench.runs import resolve_checkpoint, run_config
from airfisheye_bench.studies.crossover import (
    CROSSOVER_ARMS,
    arm_datasets,
    arm_datasets_from_config,
    crossover,
    crossover_table,
    difference_table,
    paired_frames_table,
    window_radius_share,
)
from airfisheye_bench.studies.provenance import provenance
from airfisheye_bench.synth.cache import ensure_dataset
from airfisheye_bench.tasks.checkpoint import load_task


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--ckpt", help="a completion checkpoint or run directory (omit: input differences only)"
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--root", help="dataset root (without --ckpt)")
    where.add_argument("--preset", default="occlusion", help="synthetic preset (without --ckpt)")
    parser.add_argument("--source", default="fisheye", choices=("fisheye", "cubemap"), help="without --ckpt")
    parser.add_argument(
        "--lidar-preset",
        help="with --preset: the rig flown with this real sensor (e.g. hdl64e), as data.lidar.preset",
    )
    parser.add_argument("--size", type=int, nargs="+", help="served sizes (with --ckpt: one)")
    parser.add_argument(
        "--density",
        default="native",
        choices=LIDAR_DENSITIES,
        help="without --ckpt: data.lidar.density (paper = paper_1536, paper_512: the paper sensor's returns per "
        "pixel of its 1536^2 or 512^2 image, at every size)",
    )
    parser.add_argument("--split", default="test")
    parser.add_argument(
        "--arms",
        type=lambda v: [a for a in v.split(",") if a],
        default=list(CROSSOVER_ARMS),
        help=f"comma-separated sparse inputs (default {','.join(CROSSOVER_ARMS)}; none and oracle are needed)",
    )
    parser.add_argument(
        "--radius", type=int, default=DEFAULT_RADIUS_PX, help="dilation of the affected pixels"
    )
    parser.add_argument("--near", type=float, default=DEFAULT_NEAR_M, help="near-range bound in metres")
    parser.add_argument("--frames", type=int, help="at most this many frames, spread over the split")
    parser.add_argument("--batch-size", type=int, default=4)
    parser.add_argument("--json", type=Path, help="write the numbers here")
    args = parser.parse_args(argv)
    if args.ckpt and args.size and len(args.size) > 1:
        parser.error("--ckpt takes one --size")
    return args


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    args = parse_args(argv)
    torch.set_num_threads(1)
    results: dict[str, Any] = {}
    payload: dict[str, Any] = {
        "command": "python scripts/occlusion_crossover.py "
        + " ".join(sys.argv[1:] if argv is None else argv),
        "split": args.split,
        "arms": args.arms,
        "results": results,
    }
    if args.ckpt:
        checkpoint = resolve_checkpoint(args.ckpt)
        module = load_task(checkpoint)
        if module.task != "completion":
            raise ConfigError(
                f"--ckpt {checkpoint}: a {module.task} model; the cross-over needs a completion model"
            )
        run = run_config(checkpoint)
        if run is None:
            raise ConfigError(
                f"--ckpt {checkpoint}: no config.yaml of its run next to it (its data is unknown)"
            )
        datasets = arm_datasets_from_config(
            run.data, args.split, args.arms, args.size[0] if args.size else None
        )
        predictor = CheckpointPredictor(module, checkpoint)
        payload.update(
            checkpoint=str(checkpoint), trained_with=run.data.get("occlusion"), model=dict(run.model)
        )
        payload["provenance"] = provenance("scripts/occlusion_crossover.py", argv)
        max_depth = float(run.data.get("max_depth", 120.0))
        plan = [datasets]
    else:
        root = (
            Path(args.root)
            if args.root
            else ensure_dataset(args.preset, progress=False, lidar_preset=args.lidar_preset)
        )
        payload.update(
            dataset=str(root), source=args.source, lidar_preset=args.lidar_preset, lidar_density=args.density
        )
        payload["provenance"] = provenance(
            "scripts/occlusion_crossover.py", argv, root, f"airfisheye-synthetic-{args.preset}"
        )
        predictor, max_depth = None, 120.0
        plan = [
            arm_datasets(root, args.split, args.arms, args.source, size, lidar_density=args.density)
            for size in args.size or [None]
        ]
    for datasets in plan:
        first = next(iter(datasets.values()))
        result = crossover(
            predictor, datasets, args.radius, args.near, max_depth, args.batch_size, args.frames
        )
        result["zbuffer_window_radius_share"] = window_radius_share(first)
        results[str(first.camera.width)] = result
        zero = result["zbuffer_window_radius_share"].get("0", 0.0)
        aff = result["affected"]
        print(
            f"\n## {first.camera.width}² ({result['frames']} frames of {args.split}, {result['seconds']:.0f} s)"
        )
        print(
            f"affected pixels: {aff['differing_px']:,} differ between none and oracle, {aff['dilated_px']:,} within "
            f"±{args.radius} px ({100 * aff['dilated_px'] / aff['valid_px']:.2f} % of {aff['valid_px']:,} valid px); "
            f"the derived z-buffer window has radius 0 over {100 * zero:.1f} % of the image circle\n"
        )
        print(difference_table(result))
        if result["arms"]:
            print()
            print(crossover_table(result))
            print(
                "\nPer frame, against `none` (the same model and frame), mean [95 % t-interval over frames]:\n"
            )
            print(paired_frames_table(result))
    if args.json is not None:
        atomic_write_json(args.json, payload)
    return payload


if __name__ == "__main__":
    main()
