"""Occlusion-correction study on a synthetic split: how well each method recovers the camera-visible LiDAR points.

The synthetic releases store, next to every scan, the exact camera visibility of each point
(``lidar_visible/<frame>.npy``, an exact ray cast from the camera centre). For every frame of a split and every
occlusion method of ``airfisheye_bench.geometry.occlusion_mask`` this measures, at the served camera size:

* point level (the definitions of ``scripts/bench_lidar.py``), with ``truth`` = visible and projects into the
  image under the motion-compensated ``T_cam_lidar``:
  precision = kept & truth / kept, recall = kept & truth / truth, F1, points kept, hidden points kept
  (kept & not visible) and the time of the ``occlusion_mask`` call (wall and process CPU, ms per frame);
* depth-map level, on the sparse map the completion network is fed (``lidar_depth_map`` at the served size,
  masked to the image circle, as ``AirFisheyeDataset`` builds it): the fraction of non-zero sparse pixels that
  differ from the served dense ground truth (``sample["depth"]`` of the same frame, 0 beyond ``max_depth``) by
  more than 5 %, over the sparse pixels that have ground truth; sparse pixels without ground truth are
  counted apart.

Rows: every method of ``airfisheye_bench.geometry.occlusion.OCCLUSION_METHODS`` (read when the script runs, so a
new method is studied without editing this file; ``--methods`` picks some) with the training transform (motion
compensation on); ``ordering (no MC)`` with the static extrinsics (``AirFisheyeDataset(motion_compensation=False)``;
the synthetic camera and LiDAR have different timestamps); and ``oracle``, the ground-truth visible points: its
point-level row is perfect by definition, its sparse map is the floor set by pixel sampling at depth edges, which no
method can beat. Method parameters other than the defaults: ``--option zbuffer.kernel=7`` (repeatable). Counts are
pooled over the split (sums, then ratios); means of the per-frame ratios are reported too, and the timing as mean
and median over the frames (single-threaded). The header line gives the hidden fraction: the projected points the
camera does not see, over all projected points (the errors a method without correction keeps).

    python scripts/occlusion_study.py --preset occlusion --split test --size 512 \\
        --json docs/figures/occlusion_study_occlusion.json
    python scripts/occlusion_study.py --preset quickstart --split test \\
        --figure docs/figures/occlusion_overlay.png --json docs/figures/occlusion_study.json
    python scripts/occlusion_study.py --root /path/to/synthetic --size 128 --frames 20

``--figure`` draws one frame (the one with the most hidden points that project, or ``--figure-frame``) at the
dataset's fisheye size: (a) all projected points (``none``), then the points kept by each other method; green =
truly visible, red = hidden.

The second half of the study, the completion ablation (train + evaluate with each method's sparse input, several
seeds), is ``scripts/occlusion_ablation.py``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from PIL import Image, ImageDraw

from airfisheye_bench.atomic import atomic_write_json
from airfisheye_bench.constants import IMAGENET_MEAN, IMAGENET_STD
from airfisheye_bench.geometry import CameraModel, LidarSpec, lidar_depth_map, occlusion, project_lidar
from airfisheye_bench.io.dataset_spec import DatasetSpec
from airfisheye_bench.studies.clustered import flight_of
from airfisheye_bench.studies.hidden_detection import (
    detection_counts,
    detection_table,
    hidden_detection,
    precision_recall_f1,
    ratio,
)
from airfisheye_bench.studies.provenance import provenance
from airfisheye_bench.synth.cache import ensure_dataset
from airfisheye_bench.viz import denormalize, make_panel, save_png
from datamodules.dataset import AirFisheyeDataset, CameraConfig

ORACLE = "oracle"
NO_MC = "ordering (no MC)"
WRONG_REL = 0.05  # a sparse pixel is wrong if |sparse - gt| > WRONG_REL * gt
QUICKSTART_SIZE = 128  # the size the quick-start trains at
COUNTS = ("kept", "tp", "hidden_kept", "truth", "sparse_px", "sparse_gt", "sparse_wrong", "sparse_no_gt")
Options = dict[str, dict[str, Any]]  # method -> keyword arguments of occlusion_mask
GREEN, RED = (0, 230, 0), (255, 30, 30)


@dataclass
class Frame:
    """What one frame needs: the scan, its ground-truth visibility and both transforms."""

    sample_id: str
    index: int
    points: np.ndarray  # float64 [N, 3], LiDAR frame
    visible: np.ndarray  # bool [N]
    spec: LidarSpec
    T: dict[bool, np.ndarray]  # motion compensation on / off -> T_cam_lidar


# ------------------------------------------------------------------------------------------------ rows
def variants(methods: Sequence[str] | None = None) -> list[tuple[str, str, bool]]:
    """``(row, occlusion method, motion compensation)`` of every measured row, ``oracle`` aside.

    ``methods`` defaults to every method of ``OCCLUSION_METHODS`` (``none`` always included: it defines the
    projected points); ``ordering (no MC)`` follows when ``ordering`` is measured.
    """
    available = tuple(occlusion.OCCLUSION_METHODS)
    chosen = list(available if methods is None else methods)
    unknown = [m for m in chosen if m not in available]
    if unknown:
        raise ValueError(f"--methods: unknown {unknown}; available: {', '.join(available)}")
    if "none" not in chosen:
        chosen.append("none")
    rows = [(m, m, True) for m in chosen]
    if "ordering" in chosen:
        rows.append((NO_MC, "ordering", False))
    return rows


def parse_options(items: Sequence[str]) -> Options:
    """``["zbuffer.kernel=7"]`` -> ``{"zbuffer": {"kernel": 7}}`` (values parsed as YAML)."""
    out: Options = {}
    for item in items:
        key, sep, value = item.partition("=")
        method, dot, name = key.partition(".")
        if not sep or not dot or not name or method not in occlusion.OCCLUSION_METHODS:
            raise ValueError(
                f"--option must look like METHOD.NAME=VALUE with METHOD one of {list(occlusion.OCCLUSION_METHODS)}, "
                f"got {item!r}"
            )
        out.setdefault(method, {})[name] = yaml.safe_load(value)
    return out


# ------------------------------------------------------------------------------------------------ data
def resolve_root(args: argparse.Namespace) -> Path:
    if args.root is not None:
        return Path(args.root)
    return ensure_dataset(args.preset, root=args.cache, progress=False)


def make_datasets(
    root: Path, split: str, source: str, size: int, max_depth: float
) -> dict[bool, AirFisheyeDataset]:
    """The served depth-task dataset at ``size``, with and without motion compensation (only T differs)."""
    return {
        mc: AirFisheyeDataset.from_root(
            root,
            split,
            "depth",
            source=source,
            camera=CameraConfig(size=size),
            motion_compensation=mc,
            max_depth=max_depth,
        )
        for mc in (True, False)
    }


def load_frame(datasets: dict[bool, AirFisheyeDataset], index: int) -> Frame:
    ds = datasets[True]
    sample_id = ds.sample_ids[index]
    scan = ds.reader.lidar(sample_id)
    visible = ds.reader.lidar_visible(sample_id)
    if len(visible) != len(scan):
        raise ValueError(f"{sample_id}: {len(visible)} visibility flags for {len(scan)} LiDAR points")
    return Frame(
        sample_id,
        index,
        scan[:, :3].astype(np.float64),
        visible,
        ds.reader.calib(sample_id).lidar_spec(),
        {mc: d.T_cam_lidar(sample_id) for mc, d in datasets.items()},
    )


def frame_indices(n: int, limit: int | None) -> list[int]:
    """All frames, or ``limit`` evenly spread over the split (its files are grouped by trajectory)."""
    if limit is None or limit >= n:
        return list(range(n))
    return sorted({int(i) for i in np.linspace(0, n - 1, limit).round()})


def sparse_map(
    points: np.ndarray,
    T: np.ndarray,
    camera: CameraModel,
    spec: LidarSpec,
    method: str,
    max_depth: float,
    valid: np.ndarray,
    **options: Any,
) -> np.ndarray:
    """The sparse input as ``AirFisheyeDataset`` serves it (no augmentation): range map times the circle mask."""
    return lidar_depth_map(points, T, camera, spec, method, max_depth=max_depth, **options) * valid


# ------------------------------------------------------------------------------------------------ measuring
def timed(fn: Callable[[], np.ndarray]) -> tuple[np.ndarray, float, float]:
    """``fn()`` with its wall-clock and process CPU time in ms."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, (time.perf_counter() - t0) * 1e3, (time.process_time() - c0) * 1e3


def depth_counts(sparse: np.ndarray, gt: np.ndarray) -> dict[str, int]:
    nz = sparse > 0
    has_gt = nz & (gt > 0)
    wrong = has_gt & (np.abs(sparse - gt) > WRONG_REL * gt)
    return {
        "sparse_px": int(nz.sum()),
        "sparse_gt": int(has_gt.sum()),
        "sparse_wrong": int(wrong.sum()),
        "sparse_no_gt": int((nz & ~has_gt).sum()),
    }


def measure_frame(
    frame: Frame,
    camera: CameraModel,
    gt: np.ndarray,
    valid: np.ndarray,
    max_depth: float,
    rows_to_measure: Sequence[tuple[str, str, bool]] | None = None,
    options: Options | None = None,
) -> dict[str, dict[str, float]]:
    """Counts and timings of every row (:func:`variants` by default, then ``oracle``) for one frame."""
    pts, spec = frame.points, frame.spec
    options = options or {}
    projects = project_lidar(pts, frame.T[True], camera, spec, "none").mask
    truth = projects & frame.visible  # what the camera really sees, whatever T a method is given
    rows: dict[str, dict[str, float]] = {}
    for name, method, mc in rows_to_measure or variants():
        T, kw = frame.T[mc], options.get(method, {})
        mask, wall, cpu = timed(
            lambda T=T, m=method, kw=kw: project_lidar(pts, T, camera, spec, m, **kw).mask
        )
        sparse = sparse_map(pts, T, camera, spec, method, max_depth, valid, **kw)
        rows[name] = {
            "kept": int(mask.sum()),
            "tp": int((mask & truth).sum()),
            "hidden_kept": int((mask & ~frame.visible).sum()),
            "truth": int(truth.sum()),
            "ms_wall": wall,
            "ms_cpu": cpu,
            **depth_counts(sparse, gt),
        }
    # Only the truly visible points, nearest per pixel: what a perfect occlusion test would feed the network.
    oracle = sparse_map(pts[truth], frame.T[True], camera, spec, "none", max_depth, valid)
    n = int(truth.sum())
    rows[ORACLE] = {"kept": n, "tp": n, "hidden_kept": 0, "truth": n, **depth_counts(oracle, gt)}
    rows["_frame"] = {
        "projected": int(projects.sum()),
        "hidden_projected": int((projects & ~frame.visible).sum()),
    }
    return rows


def ratios(c: dict[str, float]) -> dict[str, float]:
    """A row's point-level scores (the visible points kept: ``tp`` of ``kept``, of ``truth``) and depth-map fractions."""
    return {
        **precision_recall_f1(c["tp"], c["kept"], c["truth"]),
        "sparse_wrong_frac": ratio(c["sparse_wrong"], c["sparse_gt"]),
        "sparse_no_gt_frac": ratio(c["sparse_no_gt"], c["sparse_px"]),
    }


def summarize(per_frame: list[dict[str, float]]) -> dict[str, Any]:
    """Pooled (sum of counts, then ratios) and mean-per-frame (ratios, then mean) statistics of one row."""
    pooled: dict[str, Any] = {k: int(sum(f[k] for f in per_frame)) for k in COUNTS}
    pooled.update(ratios(pooled))
    frame_ratios = [ratios(f) for f in per_frame]
    mean = {k: _nanmean([r[k] for r in frame_ratios]) for k in frame_ratios[0]}
    mean.update({k: float(np.mean([f[k] for f in per_frame])) for k in COUNTS})
    timing = {}
    for clock in ("ms_wall", "ms_cpu"):
        if clock in per_frame[0]:
            mean[clock] = float(np.mean([f[clock] for f in per_frame]))
            timing[f"{clock}_median"] = float(np.median([f[clock] for f in per_frame]))
            timing[f"{clock}_min"] = float(np.min([f[clock] for f in per_frame]))
    return {"pooled": pooled, "mean_per_frame": mean, **({"timing": timing} if timing else {})}


def _nanmean(values: list[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]  # a frame with nothing kept has no precision
    return float(np.mean(finite)) if finite else math.nan


def run_size(
    root: Path, args: argparse.Namespace, size: int | None, limit: int | None
) -> tuple[dict[str, Any], dict[str, int]]:
    """All frames at one served size -> (summary, hidden projected points per sample id)."""
    rows_to_measure, options = variants(args.methods), parse_options(args.option)
    datasets = make_datasets(root, args.split, args.source, size, args.max_depth)
    ds = datasets[True]
    valid = ds.valid_mask.numpy()
    indices = frame_indices(len(ds), limit)
    warm = load_frame(datasets, indices[0])  # compile the numba kernels outside the timings
    for _, method, _ in rows_to_measure:
        project_lidar(warm.points, warm.T[True], ds.camera, warm.spec, method, **options.get(method, {}))
    rows: dict[str, list[dict[str, float]]] = {}
    hidden: dict[str, int] = {}
    by_location: dict[str, dict[str, list[dict[str, float]]]] = {}  # environment -> row -> frames
    by_flight: dict[
        str, dict[str, list[dict[str, int]]]
    ] = {}  # flight -> row -> hidden-point detection counts
    projected = 0
    for k, index in enumerate(indices):
        frame = load_frame(datasets, index)
        gt = ds[index]["depth"][0].numpy()  # the served target: clipped to max_depth, 0 = invalid
        result = measure_frame(frame, ds.camera, gt, valid, args.max_depth, rows_to_measure, options)
        counts = result.pop("_frame")
        hidden[frame.sample_id] = counts["hidden_projected"]
        projected += counts["projected"]
        location = frame.sample_id.split("/", 1)[0]
        flight = by_flight.setdefault(flight_of(frame.sample_id), {})
        for name, row in result.items():
            rows.setdefault(name, []).append(row)
            by_location.setdefault(location, {}).setdefault(name, []).append(row)
            if name != ORACLE:
                flight.setdefault(name, []).append(detection_counts(row, counts["hidden_projected"]))
        if (k + 1) % 25 == 0:
            print(f"  {ds.camera.width}px: {k + 1}/{len(indices)} frames", file=sys.stderr)
    summary = {
        "camera": ds.camera.to_dict(),
        "frames": len(indices),
        "projected": projected,
        "hidden_projected": sum(hidden.values()),
        "hidden_fraction": ratio(sum(hidden.values()), projected),
        "sample_ids": list(hidden),
        "options": options,
        "rows": {name: summarize(per_frame) for name, per_frame in rows.items()},
        # Pooled per test location (the environment of the sample id): a pooled gap can come from one place.
        "per_location": {
            loc: {name: summarize(frames)["pooled"] for name, frames in loc_rows.items()}
            for loc, loc_rows in by_location.items()
        },
        # Hidden points as the positive class, per flight, with intervals over the flights.
        "hidden_detection": hidden_detection(by_flight, [name for name, _, _ in rows_to_measure]),
    }
    return summary, hidden


def location_table(results: dict[str, dict[str, Any]]) -> str:
    """Per size and location: each row's F1 and wrong sparse pixels (pooled over that location's frames)."""
    lines = [
        "| size | location | frames | method | F1 | hidden kept | sparse px wrong > 5 % |",
        "|" + "---|" * 7,
    ]
    for size, summary in results.items():
        for loc, loc_rows in summary.get("per_location", {}).items():
            for name, p in loc_rows.items():
                frames = len([1 for sid in summary.get("sample_ids", []) if sid.startswith(loc + "/")]) or "-"
                lines.append(
                    f"| {size}² | {loc} | {frames} | {name} | {p['f1']:.4f} | {p['hidden_kept']} "
                    f"| {100 * p['sparse_wrong_frac']:.2f} % ({p['sparse_wrong']} / {p['sparse_gt']}) |"
                )
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------ report
def markdown_table(results: dict[str, dict[str, Any]]) -> str:
    head = (
        "| size | method | precision | recall | F1 | kept | hidden kept | ms/frame (wall median / CPU median) "
        "| mean P / R / F1 per frame | sparse px | wrong >5% | no GT |"
    )
    lines = [head, "|" + "---|" * 12]
    for size, summary in results.items():
        for name, row in summary["rows"].items():
            p, m, t = row["pooled"], row["mean_per_frame"], row.get("timing")
            ms = f"{t['ms_wall_median']:.1f} / {t['ms_cpu_median']:.1f}" if t else "-"
            lines.append(
                f"| {size}² | {name} | {p['precision']:.4f} | {p['recall']:.4f} | {p['f1']:.4f} "
                f"| {p['kept']} | {p['hidden_kept']} | {ms} "
                f"| {m['precision']:.4f} / {m['recall']:.4f} / {m['f1']:.4f} | {p['sparse_px']} "
                f"| {100 * p['sparse_wrong_frac']:.2f}% | {100 * p['sparse_no_gt_frac']:.2f}% |"
            )
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------ figure
def draw_points(image: np.ndarray, uv: np.ndarray, colors: np.ndarray, scale: int) -> np.ndarray:
    """2x2-pixel dots at pixel coordinates ``uv`` of the unscaled image, on ``image`` upscaled ``scale`` x."""
    out = np.repeat(np.repeat(image, scale, axis=0), scale, axis=1)
    h, w = out.shape[:2]
    # Pixel centres scale about the image corner (-0.5, -0.5); the dot covers the two pixels nearest it.
    xy = np.floor((uv + 0.5) * scale - 1.0).astype(np.int64)
    for dy in (0, 1):
        for dx in (0, 1):
            x, y = xy[:, 0] + dx, xy[:, 1] + dy
            ok = (x >= 0) & (x < w) & (y >= 0) & (y < h)
            out[y[ok], x[ok]] = colors[ok]
    return out


def labelled(tile: np.ndarray, lines: Sequence[str]) -> np.ndarray:
    """``tile`` under a black strip holding ``lines`` of text (default font, ~11 px a line)."""
    strip = Image.new("RGB", (tile.shape[1], 4 + 12 * len(lines)), (0, 0, 0))
    ImageDraw.Draw(strip).multiline_text((4, 2), "\n".join(lines), fill=(255, 255, 255), spacing=1)
    return np.concatenate([np.asarray(strip), tile], axis=0)


def overlay_figure(
    datasets: dict[bool, AirFisheyeDataset], index: int, scale: int, methods: Sequence[str] | None = None
) -> tuple[np.ndarray, dict[str, Any]]:
    """One panel per method: all projected points (``none``) first, then the points each other method keeps;
    green visible, red hidden."""
    ds = datasets[True]
    frame = load_frame(datasets, index)
    image = denormalize(ds[index]["image"], IMAGENET_MEAN, IMAGENET_STD)
    colors = np.where(frame.visible[:, None], np.array(GREEN, np.uint8), np.array(RED, np.uint8))
    tiles, info = [], {"sample_id": frame.sample_id, "size": ds.camera.width, "scale": scale, "panels": {}}
    methods = ["none"] + [m for _, m, mc in variants(methods) if mc and m != "none"]
    for k, method in enumerate(methods):
        tag = chr(ord("a") + k)
        uv, _, mask = project_lidar(frame.points, frame.T[True], ds.camera, frame.spec, method)
        hidden = int((mask & ~frame.visible).sum())
        order = np.argsort(~frame.visible[mask], kind="stable")  # hidden (red) dots drawn last, on top
        tile = draw_points(image, uv[mask][order], colors[mask][order], scale)
        title = "all projected (none)" if method == "none" else method
        tiles.append(labelled(tile, [f"({tag}) {title}", f"{int(mask.sum())} kept, {hidden} hidden (red)"]))
        info["panels"][method] = {"kept": int(mask.sum()), "hidden_kept": hidden}
    return make_panel([tiles], gap=4), info


def figure_index(ds: AirFisheyeDataset, requested: str | None, hidden: dict[str, int]) -> int:
    """``--figure-frame`` (sample id or index in the split), else the measured frame with most hidden points."""
    if requested is None:
        return ds.sample_ids.index(max(hidden, key=hidden.get))
    if requested in ds.sample_ids:
        return ds.sample_ids.index(requested)
    if requested.isdigit() and int(requested) < len(ds):
        return int(requested)
    raise ValueError(
        f"--figure-frame must be a sample id or an index of split {ds.split!r}, got {requested!r}"
    )


# ------------------------------------------------------------------------------------------------ main
def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--root", help="dataset root (holds dataset.yaml; needs lidar_visible)")
    where.add_argument("--preset", default="quickstart", help="synthetic preset, generated if missing")
    parser.add_argument("--cache", help="cache folder of --preset (default $AIRFISHEYE_DATA)")
    parser.add_argument("--split", default="test")
    parser.add_argument(
        "--size", type=int, nargs="+", help=f"served sizes (default: the fisheye's and {QUICKSTART_SIZE})"
    )
    parser.add_argument("--frames", type=int, help="at most this many frames, evenly spread over the split")
    parser.add_argument(
        "--source",
        choices=("cubemap", "fisheye"),
        help="as in training (default: cubemap if the release has cube faces, else fisheye)",
    )
    parser.add_argument(
        "--methods",
        type=lambda v: [m for m in v.split(",") if m],
        help="comma-separated occlusion methods (default: every one of OCCLUSION_METHODS)",
    )
    parser.add_argument(
        "--option", action="append", default=[], metavar="METHOD.NAME=VALUE", help="a method parameter"
    )
    parser.add_argument("--max-depth", type=float, default=120.0)
    parser.add_argument("--figure", type=Path, help="write the overlay PNG here")
    parser.add_argument("--figure-frame", help="sample id or split index of the figure's frame")
    parser.add_argument("--figure-scale", type=int, default=3, help="integer upscaling of the figure panels")
    parser.add_argument("--json", type=Path, help="write the numbers here")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    args = parse_args(argv)
    torch.set_num_threads(1)  # single-threaded timings, as in scripts/bench_lidar.py
    parse_options(args.option)  # bad options fail before any work
    variants(args.methods)
    root = resolve_root(args)
    if args.source is None:
        args.source = "cubemap" if DatasetSpec.load(root).has("cubemap") else "fisheye"
    calibrated = AirFisheyeDataset.from_root(
        root, args.split, "depth", source=args.source
    ).calibrated_camera.width
    sizes = list(dict.fromkeys(args.size or [calibrated, QUICKSTART_SIZE]))
    results: dict[str, dict[str, Any]] = {}
    hidden: dict[str, int] = {}
    for size in sizes:
        results[str(size)], frame_hidden = run_size(root, args, size, args.frames)
        hidden = hidden or frame_hidden
    first = next(iter(results.values()))
    print(f"{root} split={args.split}: {first['frames']} frames, source={args.source}")
    print(
        f"hidden: {first['hidden_projected']} of {first['projected']} projected points "
        f"({100 * first['hidden_fraction']:.2f} %) are not seen by the camera\n"
    )
    print(markdown_table(results))
    print()
    print(location_table(results))
    for size, result in results.items():
        print(
            f"\nHidden points as the positive class at {size} px, over {result['hidden_detection']['flights']} flights:\n"
        )
        print(detection_table(result["hidden_detection"]))
    payload: dict[str, Any] = {
        "dataset": str(root),
        "split": args.split,
        "frames": first["frames"],
        "source": args.source,
        "methods": [name for name, _, _ in variants(args.methods)] + [ORACLE],
        "max_depth": args.max_depth,
        "wrong_rel": WRONG_REL,
        "command": "python scripts/occlusion_study.py " + " ".join(sys.argv[1:] if argv is None else argv),
        "provenance": provenance("scripts/occlusion_study.py", argv, root, root.name),
        "results": results,
    }
    if args.figure is not None:
        datasets = make_datasets(root, args.split, args.source, calibrated, args.max_depth)
        index = figure_index(datasets[True], args.figure_frame, hidden)
        panel, payload["figure"] = overlay_figure(datasets, index, args.figure_scale, args.methods)
        save_png(args.figure, panel)
        payload["figure"]["path"] = str(args.figure)
        print(f"\nfigure: {args.figure} ({payload['figure']['sample_id']})")
    if args.json is not None:
        atomic_write_json(args.json, payload)  # NaN (e.g. no frame kept anything) -> null
    return payload
