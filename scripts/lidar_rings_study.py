"""What a realistic channel layout changes for ``ordering``: rings from the truth, the firing order, the channel
table (with and without the beam origins) and a uniform grid, on a generated scan of a real sensor's layout.

The synthetic preset is generated with ``lidar_preset`` (e.g. ``hdl64e``: its 64-entry table, azimuth offsets and
beam origins 0.11-0.21 m above the base); ``lidar_beam`` holds every return's true laser and ``lidar_visible``
its exact visibility from the camera. For every frame of the chosen splits, the scan is re-stored in KITTI's
order (laser by laser, top first, from azimuth 0), and ``ordering`` runs with the rings of each source. Pooled
over the frames: the share of in-view returns each source removes, the hidden returns it keeps and the visible
ones it drops (against the ray-cast truth), and how many returns get their laser's ring.

    python scripts/lidar_rings_study.py --preset tiny --lidar hdl64e --json docs/figures/lidar_rings_study_tiny_hdl64e.json
    python scripts/generate_synthetic.py preset=occlusion out=DIR lidar.preset=hdl64e total_frames=48
    python scripts/lidar_rings_study.py --root DIR --json docs/figures/lidar_rings_study_occlusion_hdl64e.json

The JSON carries its provenance (commit, command, the dataset's content identity).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.lidar_layout import rings_from_elevation
from airfisheye_bench.geometry.occlusion import occlusion_mask
from airfisheye_bench.geometry.rings import resolve_rings
from airfisheye_bench.geometry.scan_filter import filter_scan
from airfisheye_bench.io import DatasetReader
from airfisheye_bench.studies.provenance import provenance
from airfisheye_bench.synth.cache import ensure_dataset


def sources(points: np.ndarray, truth: np.ndarray, spec: LidarSpec) -> dict[str, np.ndarray]:
    """Every source's rings of a scan stored in KITTI's order."""
    r, _, el = spherical_coordinates(points)
    bare = LidarSpec(
        elevations_deg=spec.elevations_deg, points_per_channel=spec.points_per_channel, hfov_deg=360.0
    )
    datasheet = LidarSpec(
        channels=spec.channels, vfov_deg=(-24.9, 2.0), hfov_deg=360.0
    )  # HDL-64E datasheet FOV
    return {
        "true rings (a ring field)": truth,
        "firing order (else the table, as resolve_rings does)": resolve_rings(points, spec, None, True)[0],
        "channel table + beam origins": rings_from_elevation(r, el, spec),
        "channel table, beams from the centre": rings_from_elevation(r, el, bare),
        "uniform grid over the datasheet FOV": rings_from_elevation(r, el, datasheet),
    }


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--preset", default="tiny")
    parser.add_argument("--lidar", default="hdl64e")
    parser.add_argument("--splits", nargs="+", default=["train", "val", "test"])
    parser.add_argument("--min-range", type=float, default=1.0)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument(
        "--root", type=Path, default=None, help="a generated dataset instead of --preset/--lidar"
    )
    args = parser.parse_args(argv)

    root = args.root or ensure_dataset(args.preset, lidar_preset=args.lidar, progress=False)
    source = provenance("scripts/lidar_rings_study.py", argv, root, root.name)  # before any output is written
    reader = DatasetReader(root)
    totals: dict[str, dict[str, int]] = {}
    frames = 0
    for split in args.splits:
        for sid in reader.split(split):
            calib = reader.calib(sid)
            spec, camera, T = calib.lidar_spec(), calib.fisheye_camera(), reader.T_cam_lidar(sid)
            scan = reader.lidar_scan(sid)
            visible = reader.lidar_visible(sid)
            truth = scan.rings
            order = np.lexsort((np.arange(len(truth)), -truth))  # channel-major, top laser first
            az = np.arctan2(scan.points[order, 1], scan.points[order, 0])
            order = order[np.lexsort((np.remainder(az, 2 * np.pi), -truth[order]))]  # from azimuth 0 round
            points, truth, visible = scan.points[order], truth[order], visible[order]
            kept = filter_scan(points, truth, args.min_range).keep
            points, truth, visible = points[kept], truth[kept], visible[kept]
            in_view = occlusion_mask(points, T, camera, spec, method="none")
            frames += 1
            for name, rings in sources(points, truth, spec).items():
                mask = occlusion_mask(points, T, camera, spec, rings=rings)
                row = totals.setdefault(
                    name,
                    dict.fromkeys(
                        (
                            "in_view",
                            "removed",
                            "hidden_kept",
                            "visible_dropped",
                            "right",
                            "returns",
                            "hidden",
                        ),
                        0,
                    ),
                )
                row["in_view"] += int(in_view.sum())
                row["removed"] += int((in_view & ~mask).sum())
                row["hidden"] += int((in_view & ~visible).sum())
                row["hidden_kept"] += int((mask & ~visible).sum())
                row["visible_dropped"] += int((in_view & visible & ~mask).sum())
                row["right"] += int((rings == truth).sum())
                row["returns"] += len(truth)
    print(
        f"{root.name}: {frames} frames ({', '.join(args.splits)}), {args.lidar}, returns within {args.min_range} m removed"
    )
    hidden = next(iter(totals.values()))["hidden"] / next(iter(totals.values()))["in_view"]
    print(f"{100 * hidden:.2f} % of the in-view returns are hidden from the camera (exact ray cast)\n")
    print("| rings from | laser's ring | in-view returns removed | hidden kept | visible dropped |")
    print("|---|---:|---:|---:|---:|")
    for name, row in totals.items():
        print(
            f"| {name} | {100 * row['right'] / row['returns']:.2f} % | {100 * row['removed'] / row['in_view']:.2f} % "
            f"| {row['hidden_kept']} | {row['visible_dropped']} |"
        )
    if args.json:
        record = {"dataset": root.name, "frames": frames, "totals": totals, "provenance": source}
        atomic_write_text(args.json, json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
