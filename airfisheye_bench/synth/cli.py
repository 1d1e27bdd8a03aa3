"""Command line of the synthetic generator (``scripts/generate_synthetic.py`` and ``airfisheye-generate``).

Hydra-style ``key=value`` arguments::

    airfisheye-generate preset=tiny out=DIR [seed=0] [workers=2] [device=cpu] [verify=true] [contact_sheet=true]
    airfisheye-generate preset=quickstart                 # no out=: generate into the cache (ensure_dataset)
    airfisheye-generate preset=tiny out=DIR face_size=96 total_frames=30 flight.altitude_m=[5,30]   # overrides
    airfisheye-generate verify root=DIR                   # check a dataset against its manifest.json
    airfisheye-generate contact_sheet root=DIR [sample=env/traj/frame] [png=sheet.png]
    airfisheye-generate presets                           # list the presets
    airfisheye-generate bench [presets=tiny,quickstart,small] [frames=8]   # frames/s of the full frame writer

Any other ``key=value`` overrides a :class:`~airfisheye_bench.synth.presets.SynthConfig` field of the preset
(``flight.<field>`` for :class:`~airfisheye_bench.synth.trajectory.FlightConfig`); values are parsed as YAML.
"""

from __future__ import annotations

import dataclasses
import logging
import sys
import tempfile
import time
from pathlib import Path

import torch
import yaml

from airfisheye_bench.errors import report_user_errors
from airfisheye_bench.io.manifest import verify
from airfisheye_bench.synth.contact_sheet import write_contact_sheet
from airfisheye_bench.synth.presets import PRESETS, SynthConfig, get_preset, plan_trajectories
from airfisheye_bench.synth.scene import ENVIRONMENTS
from airfisheye_bench.synth.writer import _Job, _Worker, ensure_dataset, generate_dataset

_RUN_KEYS = {
    "preset",
    "out",
    "seed",
    "workers",
    "device",
    "verify",
    "contact_sheet",
    "progress",
    "root",
    "sample",
    "png",
}
_COMMANDS = ("generate", "verify", "contact_sheet", "presets", "bench")


def parse_overrides(args: list[str]) -> dict[str, object]:
    """``["a=1", "b=[1, 2]"]`` -> ``{"a": 1, "b": [1, 2]}`` (values parsed as YAML; ``+`` prefixes ignored)."""
    out: dict[str, object] = {}
    for arg in args:
        if "=" not in arg:
            raise ValueError(f"arguments must look like key=value, got {arg!r}")
        key, value = arg.split("=", 1)
        key = key.lstrip("+")
        if not key:
            raise ValueError(f"empty key in {arg!r}")
        out[key] = yaml.safe_load(value) if value != "" else ""
    return out


def build_config(preset: str, overrides: dict[str, object]) -> SynthConfig:
    """The preset with ``overrides`` applied (``flight.x`` keys go to the flight config)."""
    cfg = get_preset(preset)
    top = {f.name for f in dataclasses.fields(SynthConfig)}
    flight_fields = {f.name for f in dataclasses.fields(type(cfg.flight))}
    changes: dict[str, object] = {}
    flight: dict[str, object] = {}
    for key, value in overrides.items():
        if isinstance(value, list):
            value = tuple(value)
        if key.startswith("flight."):
            name = key.split(".", 1)[1]
            if name not in flight_fields:
                raise ValueError(f"unknown override {key!r}; flight fields: {sorted(flight_fields)}")
            flight[name] = value
        elif key in top and key != "flight":
            changes[key] = value
        else:
            raise ValueError(
                f"unknown argument {key!r}; expected one of {sorted(_RUN_KEYS)} or a SynthConfig field {sorted(top)}"
            )
    if flight:
        changes["flight"] = flight
    if changes and "name" not in changes:
        changes["name"] = f"{preset}-custom"
    return cfg.replace(**changes) if changes else cfg


def _flag(value: object, name: str) -> bool:
    if isinstance(value, bool):
        return value
    raise ValueError(f"{name} must be true or false, got {value!r}")


@report_user_errors
def main(argv: list[str] | None = None) -> int:
    """Run the generator CLI; returns the process exit code (0 = success, 1 = verification failed)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    command = "generate"
    if argv and "=" not in argv[0]:
        command = argv.pop(0)
        if command not in _COMMANDS:
            print(
                f"unknown command {command!r}; expected one of {list(_COMMANDS)}\n\n{__doc__}",
                file=sys.stderr,
            )
            return 2
    if argv and argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0
    try:
        args = parse_overrides(argv)
        return _dispatch(command, args)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def _dispatch(command: str, args: dict[str, object]) -> int:
    if command == "presets":
        for name, cfg in PRESETS.items():
            print(
                f"{name:11s} {cfg.total_frames:6d} frames, {cfg.num_trajectories:2d} trajectories, faces {cfg.face_size}^2, "
                f"fisheye {cfg.fisheye_size}^2 ({cfg.fisheye_source}), LiDAR {cfg.lidar_channels}x{cfg.lidar_points_per_channel}"
            )
        return 0
    if command == "bench":
        names = args.pop("presets", "tiny,quickstart,small")
        names = names.split(",") if isinstance(names, str) else list(names)
        frames = int(args.pop("frames", 8))
        device = str(args.pop("device", "cpu"))
        if args:
            raise ValueError(f"unknown bench arguments {sorted(args)}")
        print(bench_markdown(names, frames, device))
        return 0
    if command == "verify":
        root = args.pop("root", None) or args.pop("out", None)
        if root is None or args:
            raise ValueError("usage: verify root=DIR")
        report = verify(Path(str(root)), progress=True)
        print(report.summary())
        return 0 if report.ok else 1
    if command == "contact_sheet":
        root = args.pop("root", None) or args.pop("out", None)
        if root is None:
            raise ValueError("usage: contact_sheet root=DIR [sample=env/traj/frame] [png=PATH]")
        return _contact_sheet(Path(str(root)), args.pop("sample", None), args.pop("png", None))

    preset = str(args.pop("preset", "tiny"))
    out = args.pop("out", None)
    seed = int(args.pop("seed", 0))
    workers = args.pop("workers", None)
    device = str(args.pop("device", "cpu"))
    do_verify = _flag(args.pop("verify", False), "verify")
    sheet = _flag(args.pop("contact_sheet", False), "contact_sheet")
    progress = _flag(args.pop("progress", True), "progress")
    config = build_config(preset, args)
    if out is None:
        if config != get_preset(preset):
            raise ValueError("overrides need an explicit out=DIR (the cache holds unmodified presets only)")
        root = ensure_dataset(
            preset,
            seed=seed,
            workers=None if workers is None else int(workers),
            device=device,
            progress=progress,
        )
    else:
        root = generate_dataset(
            config, Path(str(out)), seed=seed, workers=int(workers or 1), device=device, progress=progress
        )
    print(f"dataset: {root}")
    status = 0
    if do_verify:
        report = verify(root, progress=progress)
        print(report.summary())
        status = 0 if report.ok else 1
    if sheet:
        _contact_sheet(root, None, None)
    return status


def bench_frame_writer(preset: str, frames: int = 8, device: str = "cpu") -> dict[str, float]:
    """Time the full per-frame work (render faces + fisheye, LiDAR, visibility, encode, write) of ``preset``.

    Runs in this process with one torch thread on the first trajectory of the preset, after one warm-up frame;
    the one-off scene + flight construction is timed separately.
    """
    cfg = get_preset(preset)
    plans = plan_trajectories(cfg, ENVIRONMENTS)
    frames = max(1, min(frames, plans[0].num_frames - 1))
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            worker = _Worker(cfg, 0, tmp, plans, device)
            start = time.perf_counter()
            worker.recording(0)
            build = time.perf_counter() - start
            worker.run(_Job(0, 0))  # warm-up (lazy tables, allocator)
            start = time.perf_counter()
            for i in range(1, frames + 1):
                worker.run(_Job(0, i))
            per_frame = (time.perf_counter() - start) / frames
    finally:
        torch.set_num_threads(previous)
    cam = cfg.fisheye_camera()
    fisheye_rays = int(cam.valid_mask().sum()) if cam is not None and cfg.fisheye_source == "raycast" else 0
    lidar_rays = cfg.lidar_channels * cfg.lidar_points_per_channel
    rays = (
        5 * cfg.face_size**2 + fisheye_rays + 2 * lidar_rays
    )  # + one visibility segment per LiDAR return (upper bound)
    return {
        "build_s": build,
        "frame_s": per_frame,
        "fps": 1.0 / per_frame,
        "rays": rays,
        "rays_per_s": rays / per_frame,
    }


def bench_markdown(presets: list[str], frames: int = 8, device: str = "cpu") -> str:
    """Markdown table of :func:`bench_frame_writer` for several presets."""
    lines = [
        "| preset | faces | fisheye | LiDAR | rays/frame | scene+flight (s) | s/frame | frames/s (1 process) | rays/s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name in presets:
        cfg = get_preset(name)
        r = bench_frame_writer(name, frames, device)
        lines.append(
            f"| {name} | {cfg.face_size}^2 | {cfg.fisheye_size}^2 {cfg.fisheye_source} | "
            f"{cfg.lidar_channels}x{cfg.lidar_points_per_channel} | {r['rays'] / 1e3:.0f}k | {r['build_s']:.2f} | "
            f"{r['frame_s']:.3f} | {r['fps']:.2f} | {r['rays_per_s'] / 1e6:.2f}M |"
        )
    return "\n".join(lines)


def _contact_sheet(root: Path, sample: object, png: object) -> int:
    path = Path(str(png)) if png else root.parent / f"{root.name}_contact_sheet.png"
    write_contact_sheet(root, path, sample_id=None if sample is None else str(sample))
    print(f"contact sheet: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
