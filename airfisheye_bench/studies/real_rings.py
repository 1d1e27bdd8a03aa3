"""Rings estimated on a real sweep against the sensor's own ring field: how many returns land in their laser's ring.

A nuScenes ``LIDAR_TOP`` sweep (``.pcd.bin``: x, y, z, intensity, ring; an HDL-32E) is read as a user with a
ring-less export of it would read it: the points in the file's order, its ring field held back as the truth. The
rings :func:`~airfisheye_bench.geometry.rings.resolve_rings` assigns (from the order where it holds, else from the
channel table) and those of the channel table alone are compared with it, for the returns beyond 2 m and beyond 5 m
of the sensor (range). Per ring, the median elevation of the returns beyond 2 m and beyond 5 m is set against the
preset's table and against a uniform grid over the datasheet's field of view; the distance the vehicle drove during
the sweep (nuScenes compensates its sweeps for it) is read from the no-returns (:func:`sweep_motion`).

The sweep's licence (nuScenes: CC BY-NC-SA 4.0) keeps it and its points out of this repository: the record holds
counts, shares and per-ring medians, with the file's name and SHA-256.

    python scripts/check_real_rings.py --nuscenes FILE [--lidar hdl32e] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.lidar_layout import rings_from_elevation
from airfisheye_bench.geometry.rings import resolve_rings
from airfisheye_bench.io.manifest import sha256_file
from airfisheye_bench.io.scan import load_scan
from airfisheye_bench.studies.provenance import provenance

__all__ = ["BEYOND_M", "main", "measure_nuscenes", "misses", "shares", "sweep_motion"]

#: The ranges (metres from the sensor) beyond which the shares are counted.
BEYOND_M = (2.0, 5.0)


def shares(estimated: np.ndarray, truth: np.ndarray, r: np.ndarray) -> dict[str, dict[str, float | int]]:
    """``{"beyond_2m": {"returns", "in_their_ring", "share"}, "beyond_5m": ...}`` of rings against the truth.

    Example:
        >>> shares(np.array([0, 1, 1]), np.array([0, 1, 2]), np.array([3.0, 6.0, 9.0]))["beyond_5m"]
        {'returns': 2, 'in_their_ring': 1, 'share': 0.5}
    """
    out: dict[str, dict[str, float | int]] = {}
    for beyond in BEYOND_M:
        far = (r > beyond) & (truth >= 0)
        right = int((estimated[far] == truth[far]).sum())
        out[f"beyond_{beyond:g}m"] = {
            "returns": int(far.sum()),
            "in_their_ring": right,
            "share": right / max(int(far.sum()), 1),
        }
    return out


def _median_elevations(
    el: np.ndarray, truth: np.ndarray, far: np.ndarray, channels: int
) -> list[float | None]:
    """Per ring, the median elevation (degrees) of its returns in ``far``; ``None`` for a ring without any."""
    out: list[float | None] = []
    for ring in range(channels):
        values = el[far & (truth == ring)]
        out.append(round(math.degrees(float(np.median(values))), 4) if len(values) else None)
    return out


def sweep_motion(points: np.ndarray) -> dict[str, float | int]:
    """How far the sensor moved during a column-ordered sweep compensated for it, read from its no-returns.

    A sweep moved into the sensor's frame at its last firing moves every point by where the sensor was when it fired
    it, the no-returns (zeros) too: they end on a line along the driving direction. The returns within 1 m on the x
    axis (``|y| < 1 mm``) are fitted against their firing's place in the sweep (index / N), again without those
    5 cm off the line: the slope is the distance driven during the revolution.

    Example:
        >>> x = np.linspace(-0.5, 0.0, 100)
        >>> sweep_motion(np.column_stack([x, np.zeros(100), np.zeros(100)]))["driven_m"]
        0.5
    """
    r = np.linalg.norm(points, axis=1)
    on_axis = np.flatnonzero((r < 1.0) & (np.abs(points[:, 1]) < 1e-3))
    if len(on_axis) < 2:
        return {"points_on_axis": len(on_axis), "driven_m": float("nan")}
    when, x = on_axis / (len(points) - 1), points[on_axis, 0]
    fit = np.polyfit(when, x, 1)
    line = np.abs(x - np.polyval(fit, when)) < 0.05  # refit without what is not on the line (a self-hit)
    if line.sum() >= 2:
        fit = np.polyfit(when[line], x[line], 1)
    return {"points_on_axis": int(line.sum()), "driven_m": round(float(fit[0]), 4)}


def misses(estimated: np.ndarray, truth: np.ndarray, r: np.ndarray, beyond: float) -> dict[str, Any]:
    """The returns beyond ``beyond`` metres not in their laser's ring: how many per true ring, and by how many rings
    off (estimated minus true).

    Example:
        >>> misses(np.array([0, 0, 2]), np.array([0, 1, 2]), np.full(3, 9.0), 5.0)
        {'by_ring': [0, 1, 0], 'by_offset': {'-1': 1}}
    """
    far = (r > beyond) & (truth >= 0)
    wrong = far & (estimated != truth)
    offsets, counts = np.unique(estimated[wrong] - truth[wrong], return_counts=True)
    return {
        "by_ring": np.bincount(truth[wrong], minlength=int(truth.max()) + 1).tolist(),
        "by_offset": {str(int(o)): int(c) for o, c in zip(offsets, counts, strict=True)},
    }


def measure_nuscenes(path: str | Path, lidar: str = "hdl32e") -> dict[str, Any]:
    """The record of one nuScenes sweep read without its ring field (see the module docstring)."""
    path = Path(path)
    scan = load_scan(path)
    if scan.rings is None:
        raise ValueError(f"{path}: no ring field to check the rings against")
    spec = LidarSpec.from_preset(lidar)
    truth = scan.rings
    r, _, el = spherical_coordinates(scan.points)
    # resolve_rings as a file without a ring field reaches it: the points in the file's order
    estimated, source = resolve_rings(scan.points, spec, None, scan.firing_order)
    table_rings = rings_from_elevation(r, el, spec)
    lower, upper = spec.vfov_deg
    uniform = LidarSpec(channels=spec.channels, vfov_deg=(lower, upper), hfov_deg=360.0)
    tables = {"preset": spec, "uniform": uniform}
    per_ring: dict[str, Any] = {
        f"{key}_table_deg": [round(float(v), 4) for v in np.degrees(s.channel_elevations())]
        for key, s in tables.items()
    }
    for beyond in BEYOND_M:
        medians = _median_elevations(el, truth, r > beyond, spec.channels)
        per_ring[f"median_elevation_deg_beyond_{beyond:g}m"] = medians
        for key in tables:
            per_ring[f"median_beyond_{beyond:g}m_minus_{key}_table_deg"] = [
                None if m is None else round(m - t, 4)
                for m, t in zip(medians, per_ring[f"{key}_table_deg"], strict=True)
            ]
    return {
        "scan": {
            "file": path.name,
            "sha256": sha256_file(path),
            "format": scan.format,
            "points": len(scan.points),
            "read_as": "the file's order without its ring field; the ring field is the truth",
        },
        "lidar": {"preset": lidar, "channels": spec.channels, "uniform": f"{lower:g}..{upper:g} deg"},
        "rings": {
            "resolve_rings": {"source": source, **shares(estimated, truth, r)},
            "channel_table": shares(table_rings, truth, r),
            "uniform_grid": shares(rings_from_elevation(r, el, uniform), truth, r),
        },
        "channel_table_misses_beyond_5m": misses(table_rings, truth, r, BEYOND_M[-1]),
        "per_ring": per_ring,
        "motion": sweep_motion(scan.points),
    }


def _print(record: dict[str, Any]) -> None:
    scan = record["scan"]
    print(
        f"{scan['file']} (sha256 {scan['sha256']}), {scan['points']} points, read as {record['lidar']['preset']}"
    )
    print(f"{'rings from':<44} {'beyond 2 m':>22} {'beyond 5 m':>22}")
    labels = {
        "resolve_rings": f"resolve_rings ({record['rings']['resolve_rings']['source']})",
        "channel_table": "the preset's channel table alone",
        "uniform_grid": "a uniform grid over the datasheet FOV",
    }
    for key, row in record["rings"].items():
        name = labels[key]
        cells = [
            f"{row[k]['share']:8.2%} ({row[k]['in_their_ring']}/{row[k]['returns']})"
            for k in row
            if "beyond" in k
        ]
        print(f"{name:<44} {cells[0]:>22} {cells[1]:>22}")
    missed = record["channel_table_misses_beyond_5m"]
    print(
        f"the channel table's misses beyond 5 m by true ring: {missed['by_ring']}, by offset: {missed['by_offset']}"
    )
    motion = record["motion"]
    print(
        f"driven during the sweep: {motion['driven_m']} m (fitted to its {motion['points_on_axis']} returns within "
        "1 m on the x axis)"
    )
    for name, diffs in record["per_ring"].items():
        if "_minus_" in name:
            print(f"{name}: up to {max(abs(v) for v in diffs if v is not None):.3f}")


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--nuscenes", type=Path, required=True, help="a nuScenes LIDAR_TOP .pcd.bin sweep")
    parser.add_argument("--lidar", default="hdl32e", help="the preset to read it as")
    parser.add_argument("--json", type=Path, default=None, help="write the record here")
    args = parser.parse_args(argv)
    record = measure_nuscenes(args.nuscenes, args.lidar)
    record["provenance"] = provenance("scripts/check_real_rings.py", argv)
    _print(record)
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    return record
