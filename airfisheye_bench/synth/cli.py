"""The synthetic generator's commands as functions: generate (a preset with overrides), verify, contact sheet,
the presets table and the frame-writer benchmark.

Their command line is ``airfisheye-generate`` (:func:`airfisheye_bench.cli.commands.generate`)::

    airfisheye-generate preset=tiny out=DIR [seed=0] [workers=2] [device=cpu] [verify=true] [contact_sheet=true]
    airfisheye-generate preset=quickstart                 # no out=: generate into the cache (ensure_dataset)
    airfisheye-generate preset=paper out=DIR shards=12 shard=3   # one shard of twelve (synth.shards); the last merges
    airfisheye-generate preset=paper out=DIR shards=12 shard=merge   # finish it explicitly (names what is missing)
    airfisheye-generate preset=tiny out=DIR face_size=96 total_frames=30 flight.altitude_m=[5,30]   # overrides
    airfisheye-generate preset=tiny out=DIR camera.calibration=image_02.yaml [camera.size=256]  # a calibrated lens
    airfisheye-generate verify root=DIR                   # check a dataset against its manifest.json
    airfisheye-generate contact_sheet root=DIR [sample=env/traj/frame] [png=PATH]   # default DIR/contact_sheet.png
    airfisheye-generate presets                           # list the presets
    airfisheye-generate bench [presets=[tiny,quickstart,small]] [frames=8]   # frames/s of the full frame writer

Any other ``key=value`` overrides a :class:`~airfisheye_bench.synth.presets.SynthConfig` field of the preset
(``flight.<field>`` for :class:`~airfisheye_bench.synth.trajectory.FlightConfig`); values are read in Hydra's
override grammar, as every option is.
"""

from __future__ import annotations

import dataclasses
import logging
import tempfile
import time
from pathlib import Path

import torch

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.serving import FITS, serve_camera
from airfisheye_bench.io.calibration_files import load_camera
from airfisheye_bench.io.content import content_identity
from airfisheye_bench.io.manifest import verify as verify_manifest
from airfisheye_bench.synth.cache import ensure_dataset
from airfisheye_bench.synth.contact_sheet import write_contact_sheet
from airfisheye_bench.synth.presets import PRESETS, SynthConfig, get_preset, plan_trajectories
from airfisheye_bench.synth.scene import ENVIRONMENTS
from airfisheye_bench.synth.shards import generate_shard, merge_shards
from airfisheye_bench.synth.writer import Job, Worker, generate_dataset

log = logging.getLogger(__name__)


#: ``camera.<key>`` options of the generator: a calibrated lens for the fisheye (see :func:`calibrated_fisheye`).
CAMERA_KEYS = ("calibration", "camera", "size", "fit")


def build_config(preset: str, overrides: dict[str, object]) -> SynthConfig:
    """The preset with ``overrides`` applied (``flight.x`` keys go to the flight config, ``camera.x`` keys choose a
    calibrated lens: :func:`calibrated_fisheye`).

    Raises:
        ConfigError: A key that is no field of :class:`SynthConfig`, of its flight config or of ``camera.``.

    Example:
        >>> build_config("tiny", {"face_size": 96, "flight.altitude_m": [5, 30]}).flight.altitude_m
        (5, 30)
    """
    cfg = get_preset(preset)
    camera = {k.split(".", 1)[1]: overrides[k] for k in overrides if k.startswith("camera.")}
    overrides = {k: v for k, v in overrides.items() if not k.startswith("camera.")}
    if camera:
        overrides = {**overrides, **calibrated_fisheye(cfg, camera)}
    top = {f.name for f in dataclasses.fields(SynthConfig)}
    flight_fields = {f.name for f in dataclasses.fields(type(cfg.flight))}
    changes: dict[str, object] = {}
    flight: dict[str, object] = {}
    for key, value in overrides.items():
        if isinstance(value, list):
            value = tuple(value)
        key = "lidar_preset" if key == "lidar.preset" else key  # the spelling of train.py's data.lidar.preset
        if key.startswith("flight."):
            name = key.split(".", 1)[1]
            if name not in flight_fields:
                raise ConfigError(f"unknown option {key!r}; flight fields: {sorted(flight_fields)}")
            flight[name] = value
        elif key in top and key != "flight":
            changes[key] = value
        else:
            raise ConfigError(
                f"unknown option {key!r}; expected a SynthConfig field {sorted(top - {'flight'})}"
            )
    if flight:
        changes["flight"] = flight
    if changes and "name" not in changes:
        changes["name"] = f"{preset}-custom"
    return cfg.replace(**changes) if changes else cfg


def calibrated_fisheye(cfg: SynthConfig, options: dict[str, object]) -> dict[str, object]:
    """``SynthConfig`` overrides that render the fisheye through a calibrated lens.

    ``options``: ``calibration`` (a calibration file of any format of :mod:`airfisheye_bench.io.calibration_files`),
    ``camera`` (which camera of a file with several), ``size`` (the fisheye's side in pixels; default the preset's
    ``fisheye_size``) and ``fit`` (``pad`` | ``crop`` for a non-square calibration). The lens is served at ``size x
    size`` by the rule of :mod:`airfisheye_bench.geometry.serving` (the pad or crop is logged).

    Raises:
        ConfigError: an unknown ``camera.`` key, no ``calibration``, a preset without a fisheye, or a bad file.
    """
    unknown = sorted(set(options) - set(CAMERA_KEYS))
    if unknown:
        raise ConfigError(f"unknown option camera.{unknown[0]}; camera options: {', '.join(CAMERA_KEYS)}")
    if not options.get("calibration"):
        raise ConfigError("camera.calibration=<file> is needed with the other camera. options")
    size = options.get("size") or cfg.fisheye_size
    if not isinstance(size, int) or isinstance(size, bool) or size < 8:
        raise ConfigError(f"camera.size={size!r}: expected an integer >= 8 (the fisheye's side in pixels)")
    fit = options.get("fit") or "pad"
    if fit not in FITS:
        raise ConfigError(f"camera.fit={fit!r}: expected one of {', '.join(FITS)}")
    if cfg.fisheye_source == "none":
        raise ConfigError("camera.calibration needs a preset with a fisheye image (fisheye_source is none)")
    try:
        lens = load_camera(str(options["calibration"]), options.get("camera"), option="camera.camera")
    except (ValueError, OSError) as err:
        raise ConfigError(f"camera.calibration: {err}") from None
    served = serve_camera(lens, int(size), str(fit))
    log.info("fisheye camera from %s: %s", options["calibration"], served.describe())
    return {"fisheye_size": int(size), "fisheye_calibration": served.camera.to_dict()}


def presets_table() -> str:
    """One line per preset: frames, trajectories, face and fisheye sizes, LiDAR pattern."""
    return "\n".join(
        f"{name:11s} {cfg.total_frames:6d} frames, {cfg.num_trajectories:2d} trajectories, faces {cfg.face_size}^2, "
        f"fisheye {cfg.fisheye_size}^2 ({cfg.fisheye_source}), LiDAR {cfg.lidar_channels}x{cfg.lidar_points_per_channel}"
        for name, cfg in PRESETS.items()
    )


def generate(
    preset: str,
    overrides: dict[str, object],
    out: Path | None,
    *,
    seed: int = 0,
    workers: int | None = None,
    device: str = "cpu",
    verify: bool = False,
    contact_sheet: bool = False,
    progress: bool = True,
    shards: int = 1,
    shard: object = None,
) -> int:
    """Generate ``preset`` with ``overrides`` into ``out`` (``None``: the cache); the exit status (1: not verified).

    With ``shard`` (an index below ``shards``, or ``"merge"``) only that shard is written into ``out``
    (:mod:`~airfisheye_bench.synth.shards`); the command that completes the dataset merges it and prints its content
    identity, and ``verify`` and ``contact_sheet`` then apply to it.

    Raises:
        ConfigError: An unknown override, overrides or shards without ``out``, or a bad ``shard`` / ``shards``.
    """
    config = build_config(preset, overrides)
    if shard is not None or shards != 1:
        root = _generate_sharded(config, out, shard, shards, seed, workers or 1, device, progress)
        if root is None:
            return 0
    elif out is None:
        if config != get_preset(preset):
            raise ConfigError("overrides need an explicit out=DIR (the cache holds unmodified presets only)")
        root = ensure_dataset(preset, seed=seed, workers=workers, device=device, progress=progress)
    else:
        root = generate_dataset(
            config, out, seed=seed, workers=workers or 1, device=device, progress=progress
        )
    print(f"dataset: {root}")
    status = verify_dataset(root, progress=progress) if verify else 0
    if contact_sheet:
        write_sheet(root)
    return status


def _generate_sharded(
    config: SynthConfig,
    out: Path | None,
    shard: object,
    shards: int,
    seed: int,
    workers: int,
    device: str,
    progress: bool,
) -> Path | None:
    """Write one shard, or merge (``shard="merge"``); the dataset's folder once it is complete, else ``None``."""
    if out is None:
        raise ConfigError(
            "shards= and shard= need out=DIR, the folder every shard writes into (the cache is generated by one "
            "process)"
        )
    if shard is None:
        raise ConfigError(
            f"shards={shards} needs shard=0 .. shard={shards - 1} (one per job, e.g. shard=$SLURM_ARRAY_TASK_ID), "
            "or shard=merge"
        )
    if shard == "merge":
        root = merge_shards(config, out, seed=seed, shards=shards if shards > 1 else None)
    elif isinstance(shard, int) and not isinstance(shard, bool):
        report = generate_shard(config, out, shard, shards, seed, workers, device, progress)
        print(report.summary(plan_trajectories(config, ENVIRONMENTS)))
        if not report.complete:
            return None
        root = report.root
    else:
        raise ConfigError(f"shard={shard}: expected a shard index 0 .. {max(shards - 1, 0)}, or merge")
    identity = content_identity(root, progress=progress)
    print(f"content: {identity['content_sha256']} ({identity['files']} files)")
    return root


def verify_dataset(root: Path, progress: bool = True) -> int:
    """Check ``root`` against its ``manifest.json`` and print the summary; the exit status (1: a mismatch)."""
    report = verify_manifest(root, progress=progress)
    print(report.summary())
    return 0 if report.ok else 1


def write_sheet(root: Path, sample: str | None = None, png: str | Path | None = None) -> int:
    """Write the contact sheet of one frame of ``root`` (default: ``<root>/contact_sheet.png``); exit status 0."""
    path = write_contact_sheet(root, Path(png) if png else None, sample_id=sample)
    print(f"contact sheet: {path}")
    return 0


def bench_frame_writer(preset: str, frames: int = 8, device: str = "cpu") -> dict[str, float]:
    """Time the full per-frame work (render faces + fisheye, LiDAR, visibility, encode, write) of ``preset``.

    Runs in this process with one torch thread on the first trajectory of the preset, after one warm-up frame;
    the one-off scene + flight construction is timed separately. ``frame_cpu_s`` is the process's CPU time per
    frame (one thread: what a core not shared with other work takes, whatever else ran). ``content_sha256`` is the content identity
    (:func:`~airfisheye_bench.io.content.content_identity`) of the frames it wrote: what was timed.
    """
    cfg = get_preset(preset)
    plans = plan_trajectories(cfg, ENVIRONMENTS)
    frames = max(1, min(frames, plans[0].num_frames - 1))
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            worker = Worker(cfg, 0, tmp, plans, device)
            start = time.perf_counter()
            worker.recording(0)
            build = time.perf_counter() - start
            worker.run(Job(0, 0))  # warm-up (lazy tables, allocator)
            start, cpu = time.perf_counter(), time.process_time()
            for i in range(1, frames + 1):
                worker.run(Job(0, i))
            per_frame = (time.perf_counter() - start) / frames
            cpu_per_frame = (time.process_time() - cpu) / frames
            content = str(content_identity(tmp)["content_sha256"])
    finally:
        torch.set_num_threads(previous)
    cam = cfg.fisheye_camera()
    fisheye_rays = int(cam.valid_mask().sum()) if cam is not None and cfg.fisheye_source == "raycast" else 0
    lidar_rays = cfg.lidar_channels * cfg.lidar_points_per_channel
    rays = (
        5 * cfg.face_size**2 + fisheye_rays + 2 * lidar_rays
    )  # + one visibility segment per LiDAR return (upper bound)
    return {
        "frames": frames,
        "build_s": build,
        "frame_s": per_frame,
        "frame_cpu_s": cpu_per_frame,
        "fps": 1.0 / per_frame,
        "rays": rays,
        "rays_per_s": rays / per_frame,
        "content_sha256": content,
    }


def bench_markdown(timings: dict[str, dict[str, float]]) -> str:
    """Markdown table of :func:`bench_frame_writer`'s timings, one row per preset."""
    lines = [
        "| preset | faces | fisheye | LiDAR | rays/frame | scene+flight (s) | s/frame | CPU s/frame "
        "| frames/s (1 process) | rays/s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in timings.items():
        cfg = get_preset(name)
        lines.append(
            f"| {name} | {cfg.face_size}^2 | {cfg.fisheye_size}^2 {cfg.fisheye_source} | "
            f"{cfg.lidar_channels}x{cfg.lidar_points_per_channel} | {r['rays'] / 1e3:.0f}k | {r['build_s']:.2f} | "
            f"{r['frame_s']:.3f} | {r['frame_cpu_s']:.3f} | {r['fps']:.2f} | {r['rays_per_s'] / 1e6:.2f}M |"
        )
    return "\n".join(lines)
