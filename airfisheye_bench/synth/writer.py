"""Write a synthetic dataset in the AirFisheye layout: deterministic, parallel, atomic and resumable.

:func:`generate_dataset` records every trajectory of a :class:`~airfisheye_bench.synth.presets.SynthConfig`
(scene, flight, lighting) and every frame (cube faces, fisheye, LiDAR, visibility; with a realistic scan model also
each point's beam and each frame's scan phase), then writes the split files,
``dataset.yaml`` and ``manifest.json`` (written last: a dataset with a manifest is complete).

* **Deterministic.** Each trajectory's scene, flight and lighting are seeded from ``(seed, environment,
  trajectory index)`` only, and a frame's files depend only on its trajectory and timestamp; the renderer is
  bit-exact under any batching/threading. So the bytes do not depend on the number of workers or on the order in
  which frames are done (PNG encoding uses a fixed zlib level).
* **Atomic and resumable.** Every file is written to a temporary name and renamed. The main process appends one
  line per finished unit (a trajectory's metadata or one frame) to a journal; an interrupted run started again
  with the same arguments skips the journaled units, redoes the rest and ends byte-identical to an
  uninterrupted run. The journal and state file are removed at the end.
* **Sharded.** Several processes, on one machine or many sharing a file system, can each write whole trajectories
  of the same folder (:mod:`~airfisheye_bench.synth.shards`): each keeps a journal of its own, every journal counts
  as done, and the dataset is finished (:func:`merge_journals`) once every unit of every trajectory is journaled.
  The files are the same bytes as one process would write.
* **Verifiable.** ``manifest.json`` lists every file's SHA-256; :func:`~airfisheye_bench.io.manifest.verify`
  checks a dataset against it.

What a trajectory is made of is :mod:`~airfisheye_bench.synth.recording`; its ``dataset.yaml`` is
:mod:`~airfisheye_bench.synth.dataset_yaml`; the cache of presets the datamodules read is
:mod:`~airfisheye_bench.synth.cache`.
"""

from __future__ import annotations

import hashlib
import json
import logging
import multiprocessing as mp
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.atomic import TEMP_GLOB, atomic_write_bytes, atomic_write_text, remove_stale_temporaries
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry import FACE_NAMES, CameraModel, CubemapToFisheye, ideal_camera
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.io import codecs
from airfisheye_bench.io.calib_yaml import Calibration
from airfisheye_bench.io.content import decoded_content
from airfisheye_bench.io.dataset_spec import DATASET_YAML, DatasetSpec, FileEncodings
from airfisheye_bench.io.layout import DatasetLayout
from airfisheye_bench.io.manifest import FileEntry, sha256_bytes, sha256_file, write_manifest
from airfisheye_bench.io.poses import ImuTable, PoseTable
from airfisheye_bench.io.progress_report import ProgressReport
from airfisheye_bench.io.splits import write_split
from airfisheye_bench.synth.dataset_yaml import dataset_spec, generator_identity
from airfisheye_bench.synth.presets import (
    SPLIT_NAMES,
    SynthConfig,
    TrajectoryPlan,
    get_preset,
    plan_trajectories,
)
from airfisheye_bench.synth.recording import (
    TrajectoryRecording,
    build_trajectory,
    frame_name,
    frame_phases,
    scan_rng,
)
from airfisheye_bench.synth.scene import ENVIRONMENTS
from airfisheye_bench.synth.sensors import ScanModel, render_frame

log = logging.getLogger(__name__)

STATE_NAME = ".airfisheye-generate.json"
JOURNAL_NAME = ".airfisheye-journal.jsonl"
#: Every journal of a folder: the one of a whole run (:data:`JOURNAL_NAME`) and each shard's.
JOURNAL_GLOB = ".airfisheye-journal*.jsonl"


def calib_camera(config: SynthConfig) -> CameraModel:
    """The camera in ``calib.yaml``: the pre-rendered fisheye, or (without one) a 190-deg default twice the face size."""
    return config.fisheye_camera() or ideal_camera(
        2 * config.face_size, 2 * config.face_size, fov_deg=config.fisheye_fov_deg
    )


# =============================================================================================== units of work
class _UnitWriter:
    """Writes files of one unit (atomically) and remembers their checksums."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.files: dict[str, list] = {}

    def put(self, path: Path, data: bytes) -> None:
        atomic_write_bytes(path, data)
        self.files[path.relative_to(self.root).as_posix()] = [sha256_bytes(data), len(data)]

    def put_written(self, path: Path) -> None:
        self.files[path.relative_to(self.root).as_posix()] = [sha256_file(path), path.stat().st_size]


def _write_trajectory_meta(rec: TrajectoryRecording, config: SynthConfig, layout: DatasetLayout) -> dict:
    """``calib.yaml``, ``poses.csv`` and ``imu.csv`` of one trajectory."""
    plan, flight = rec.plan, rec.flight
    out = _UnitWriter(layout.root)
    calib = Calibration(
        camera=calib_camera(config).to_dict(),
        face_size=config.face_size or None,
        T_body_cam=flight.T_body_cam,
        T_body_lidar=flight.T_body_lidar,
        lidar=config.lidar_spec().to_dict(),
        extras={
            "gimbal_pitch_deg": round(flight.gimbal_pitch_deg, 6),
            "lidar_delay_s": round(flight.lidar_delay_s, 9),
            "frame_rate_hz": config.flight.frame_rate_hz,
            "imu_rate_hz": config.flight.imu_rate_hz,
        },
    )
    calib.save(layout.calib(plan.key))
    out.put_written(layout.calib(plan.key))
    frames = [frame_name(i) for i in range(plan.num_frames)]
    PoseTable(frames, flight.t_cam, rec.T_world_body_cam, flight.t_lidar, rec.T_world_body_lidar).save(
        layout.poses(plan.key)
    )
    out.put_written(layout.poses(plan.key))
    t_imu = flight.imu_times()
    accel, gyro = flight.imu(t_imu)
    ImuTable(t_imu, accel, gyro).save(layout.imu(plan.key))
    out.put_written(layout.imu(plan.key))
    if not config.scan_model().ideal:
        out.put(layout.lidar_scan(plan.key), codecs.encode_scan_phases(frames, frame_phases(rec, config)))
    return out.files


def _write_frame(
    rec: TrajectoryRecording, index: int, config: SynthConfig, sensors: _Sensors, layout: DatasetLayout
) -> dict:
    """Render and write every file of frame ``index`` of a trajectory."""
    rng = scan_rng(rec.scan_seed, index)
    phase = sensors.scan.frame_phase(sensors.lidar, rec.flight.t_lidar[index], rng)
    frame = render_frame(
        rec.scene,
        rec.lighting,
        rec.T_world_cam(index),
        rec.T_world_lidar(index),
        face_size=config.face_size,
        lidar=sensors.lidar,
        camera=sensors.camera,
        fisheye_source=config.fisheye_source,
        max_dist=config.render_max_dist,
        remapper=sensors.remapper,
        scan=sensors.scan,
        scan_phase=phase,
        scan_rng=rng,
    )
    sid = f"{rec.plan.key}/{frame_name(index)}"
    files = layout.files
    rgb_suffix = "." + files.extension("rgb")
    depth_suffix = "." + files.extension("depth")
    out = _UnitWriter(layout.root)
    if frame.cube_rgb is not None:
        for f, face in enumerate(FACE_NAMES):
            out.put(layout.cubemap(sid, face, "rgb"), codecs.encode_rgb(frame.cube_rgb[f], rgb_suffix))
            out.put(layout.cubemap(sid, face, "seg"), codecs.encode_label(frame.cube_seg[f]))
            out.put(
                layout.cubemap(sid, face, "depth"),
                codecs.encode_depth(frame.cube_depth[f], depth_suffix, files.depth_scale),
            )
    if frame.fisheye_rgb is not None:
        out.put(layout.fisheye(sid, "rgb"), codecs.encode_rgb(frame.fisheye_rgb, rgb_suffix))
        out.put(layout.fisheye(sid, "seg"), codecs.encode_label(frame.fisheye_seg))
        out.put(
            layout.fisheye(sid, "depth"),
            codecs.encode_depth(frame.fisheye_depth, depth_suffix, files.depth_scale),
        )
    out.put(layout.lidar(sid), codecs.npy_bytes(frame.lidar.astype(np.float32)))
    out.put(layout.lidar_visible(sid), codecs.npy_bytes(frame.lidar_visible.astype(bool)))
    if not sensors.scan.ideal or not sensors.lidar.is_uniform:
        out.put(layout.lidar_beam(sid), codecs.npy_bytes(frame.lidar_beam.astype(np.int32)))
    return out.files


@dataclass
class _Sensors:
    """Sensor models built once per process (they cache ray grids and remap tables)."""

    lidar: LidarSpec
    camera: CameraModel | None
    remapper: CubemapToFisheye | None
    scan: ScanModel

    @classmethod
    def from_config(cls, config: SynthConfig) -> _Sensors:
        camera = config.fisheye_camera()
        remapper = CubemapToFisheye(camera, config.face_size) if config.fisheye_source == "remap" else None
        return cls(config.lidar_spec(), camera, remapper, config.scan_model())


@dataclass(frozen=True)
class Job:
    """One unit of work of :func:`generate_dataset`: a trajectory's metadata (``frame=-1``) or one frame."""

    traj: int  # index into the plans
    frame: int  # -1: trajectory metadata

    @property
    def key(self) -> str:
        return f"{self.traj}:{self.frame}"


class Worker:
    """Per-process state: the configuration and a small cache of built trajectories; :meth:`run` does one
    :class:`Job` (the frame-writer benchmark of ``airfisheye-generate bench`` times it)."""

    def __init__(
        self, config: SynthConfig, seed: int, root: str, plans: list[TrajectoryPlan], device: str
    ) -> None:
        self.config, self.seed, self.plans, self.device = config, seed, plans, device
        spec_files = FileEncodings(rgb=config.rgb_format, seg="png", depth=config.depth_format)
        self.layout = DatasetLayout(root, files=spec_files)
        self._cache: dict[int, TrajectoryRecording] = {}
        self.sensors = _Sensors.from_config(config)

    def recording(self, traj: int) -> TrajectoryRecording:
        if traj not in self._cache:
            self._cache.clear()  # jobs arrive grouped by trajectory: one cached scene is enough
            self._cache[traj] = build_trajectory(self.config, self.seed, self.plans[traj], self.device)
        return self._cache[traj]

    def run(self, job: Job) -> tuple[str, dict]:
        rec = self.recording(job.traj)
        if job.frame < 0:
            return job.key, _write_trajectory_meta(rec, self.config, self.layout)
        return job.key, _write_frame(rec, job.frame, self.config, self.sensors, self.layout)


_WORKER: Worker | None = None


def _init_worker(args: tuple, threads: int) -> None:
    global _WORKER
    torch.set_num_threads(threads)
    _WORKER = Worker(*args)


def _run_in_worker(job: Job) -> tuple[str, dict]:
    assert _WORKER is not None
    return _WORKER.run(job)


# =============================================================================================== driver
def generate_dataset(
    config: SynthConfig | str,
    out_dir: str | Path,
    seed: int = 0,
    workers: int = 1,
    device: str = "cpu",
    progress: bool = True,
) -> Path:
    """Generate (or finish generating) a synthetic dataset.

    Args:
        config: A :class:`SynthConfig` or a preset name (``tiny``, ``quickstart``, ``small``, ``medium``, ``paper``, ``occlusion``).
        out_dir: Output folder: new, empty, a partial run of the same config and seed (resumed; units that shards
            of :mod:`~airfisheye_bench.synth.shards` wrote count as done), or a complete dataset of the same config
            and seed (returned as is).
        seed: Base seed.
        workers: Processes rendering frames (the output does not depend on it).
        device: Torch device for ray casting (``cpu``; ``cuda`` when available).
        progress: Report progress: a bar in a terminal, else a log line every tenth of the frames.

    Returns:
        ``out_dir``.

    Raises:
        ConfigError: ``out_dir`` holds something else (another dataset, another config/seed, unrelated files).

    Example:
        >>> root = generate_dataset("tiny", "/tmp/airfisheye-tiny", workers=2)     # doctest: +SKIP
        >>> from airfisheye_bench.io.manifest import verify; verify(root).ok   # doctest: +SKIP
        True
    """
    config = as_config(config)
    if int(workers) < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    root = Path(out_dir)
    if open_output(root, generator_identity(config, seed)):
        log.info("%s is already complete", root)
        return root
    remove_stale_temporaries(root)
    plans = plan_trajectories(config, ENVIRONMENTS)
    every = range(len(plans))
    write_trajectories(
        root, (config, seed, plans), every, root / JOURNAL_NAME, int(workers), device, progress, config.name
    )
    missing = merge_journals(root, config, seed, plans)
    if missing:  # every unit was just written: only files removed meanwhile (by another process) lead here
        raise RuntimeError(f"{root}: units vanished while it was written, in {sorted(missing)}; run it again")
    return root


def as_config(config: SynthConfig | str) -> SynthConfig:
    """``config`` itself, or the preset it names."""
    if isinstance(config, str):
        config = get_preset(config)
    if not isinstance(config, SynthConfig):
        raise ValueError(f"config must be a SynthConfig or a preset name, got {type(config).__name__}")
    return config


def open_output(root: Path, identity: dict) -> bool:
    """Make ``root`` ready to write the dataset of ``identity`` (its state file in place); ``True``: it is complete
    already and nothing is to be written.

    Raises:
        ConfigError: ``root`` holds another dataset, an unfinished one of other settings, or unrelated files.
    """
    return _is_complete(root, identity) or _prepare_output(root, identity)


def write_trajectories(
    root: Path,
    run: tuple[SynthConfig, int, list[TrajectoryPlan]],
    trajectories: Sequence[int],
    journal: Path,
    workers: int,
    device: str,
    progress: bool,
    label: str,
) -> int:
    """Write every unit (metadata, frames) of ``trajectories`` (indices into the plans) that no journal of ``root``
    holds yet, appending each finished one to ``journal``; the number of frames rendered.

    ``run``: the config, seed and plans. Journals of other processes writing other trajectories of the same folder
    are read, never written: each process appends to its own.
    """
    config, seed, plans = run
    done = read_journals(root)
    jobs = [
        Job(t, f) for t in trajectories for f in range(-1, plans[t].num_frames) if Job(t, f).key not in done
    ]
    total_frames = sum(plans[t].num_frames for t in trajectories)
    to_render = sum(1 for j in jobs if j.frame >= 0)
    bar = ProgressReport(total_frames, f"generate {label}", "frame", progress, total_frames - to_render, log)
    try:
        with open(journal, "a", encoding="utf-8") as jf:
            for key, files in _execute(jobs, (config, seed, str(root), plans, device), workers):
                jf.write(json.dumps({"unit": key, "files": files}, sort_keys=True) + "\n")
                jf.flush()
                if not key.endswith(":-1"):
                    bar.update(1)
    finally:
        bar.close()
    return to_render


def missing_units(plans: list[TrajectoryPlan], done: dict[str, dict]) -> dict[str, int]:
    """Trajectories not finished in ``done``: their key and how many of their units (metadata, frames) are missing.

    Example:
        >>> plans = plan_trajectories(get_preset("tiny"), ENVIRONMENTS)
        >>> missing_units(plans, {"0:-1": {}, **{f"0:{i}": {} for i in range(8)}})
        {'modular_houses/traj00': 3, 'town/traj00': 3}
    """
    missing = {}
    for t, plan in enumerate(plans):
        count = sum(1 for f in range(-1, plan.num_frames) if Job(t, f).key not in done)
        if count:
            missing[plan.key] = count
    return missing


def merge_journals(root: Path, config: SynthConfig, seed: int, plans: list[TrajectoryPlan]) -> dict[str, int]:
    """Finish the dataset of ``root`` if every unit of every trajectory is journaled (by any process): its split
    files, ``dataset.yaml`` and ``manifest.json``, then the journals and state file are removed. The trajectories
    still missing units (:func:`missing_units`; empty: the dataset is complete).

    Several processes may call it at once: what they write is the same, file by file, and each write is atomic.
    """
    if _is_complete(root, generator_identity(config, seed)):
        return {}
    done = read_journals(root)
    missing = missing_units(plans, done)
    if not missing:
        _finalize(root, config, seed, plans, done)
    return missing


def stale_file(root: str | Path, config: SynthConfig | str, seed: int = 0, device: str = "cpu") -> str | None:
    """The first file of a generated dataset that this version of the generator writes differently (or ``None``).

    A cached dataset is only as current as the code that wrote it: when the generator's output changes and
    ``GENERATOR_VERSION`` is not bumped, the cache would keep serving the old data under the preset's name. This
    re-renders, in a scratch folder, the metadata and first frame of the first trajectory of every environment (about
    0.3 s each on one core; ``quickstart`` has four) and compares each file's decoded content
    (:func:`~airfisheye_bench.io.content.decoded_content`) with the dataset's, after checking that ``dataset.yaml``
    names this config and seed. It is a sample, not a proof: a change that spares those frames goes unseen. In an
    unfinished dataset (no manifest) the files not written yet are skipped.

    Returns:
        The relative path of the first file that differs or is missing (``dataset.yaml`` for another config or seed),
        or ``None`` when every sampled file is what this generator writes.

    Example:
        >>> root = generate_dataset("tiny", "/tmp/airfisheye-tiny", workers=2)     # doctest: +SKIP
        >>> stale_file(root, "tiny") is None                                         # doctest: +SKIP
        True
    """
    if isinstance(config, str):
        config = get_preset(config)
    root = Path(root)
    complete = (root / "manifest.json").is_file()
    if complete and DatasetSpec.load(root).generator != generator_identity(config, seed):
        return DATASET_YAML
    with tempfile.TemporaryDirectory(prefix="airfisheye-probe-") as scratch:
        for rel in _render_sample(config, seed, Path(scratch), device):
            if not (root / rel).is_file():
                if complete:
                    return rel
                continue
            if decoded_content(root / rel) != decoded_content(Path(scratch) / rel):
                return rel
    return None


def sample_identity(config: SynthConfig | str, seed: int = 0, device: str = "cpu") -> str:
    """SHA-256 of the decoded content of the sample :func:`stale_file` renders (the metadata and first frame of the
    first trajectory of every environment): a preset's content in seconds, for checks that the generator writes
    the same data on every CPU without generating all of it.

    Example:
        >>> len(sample_identity("tiny"))                                             # doctest: +SKIP
        64
    """
    if isinstance(config, str):
        config = get_preset(config)
    digest = hashlib.sha256()
    with tempfile.TemporaryDirectory(prefix="airfisheye-sample-") as scratch:
        for rel in sorted(_render_sample(config, seed, Path(scratch), device)):
            kind, data = decoded_content(Path(scratch) / rel)
            digest.update(f"{rel}\0{kind}\0{len(data)}\0".encode())
            digest.update(data)
    return digest.hexdigest()


def _render_sample(config: SynthConfig, seed: int, folder: Path, device: str) -> Iterator[str]:
    """Render the metadata and first frame of the first trajectory of every environment into ``folder``, on one
    thread; yields each written file's relative path as it is written."""
    plans = plan_trajectories(config, ENVIRONMENTS)
    first_of_env: dict[str, int] = {}
    for t, plan in enumerate(plans):
        first_of_env.setdefault(plan.env, t)
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        worker = Worker(config, seed, str(folder), plans, device)
        for t in first_of_env.values():
            for job in (Job(t, -1), Job(t, 0)):
                yield from worker.run(job)[1]
    finally:
        torch.set_num_threads(previous)


def _execute(jobs: list[Job], args: tuple, workers: int) -> Iterator[tuple[str, dict]]:
    if not jobs:
        return
    # One torch thread per process: the ray caster's many small ops scale badly with intra-op threads (4x slower
    # with 2 threads on a busy 2-core machine), so parallelism comes from worker processes. Results do not
    # depend on the thread count.
    if workers == 1 or len(jobs) == 1:
        previous = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            worker = Worker(*args)
            for job in jobs:
                yield worker.run(job)
        finally:
            torch.set_num_threads(previous)
        return
    # spawn: no fork of a process that already runs OpenMP / torch threads.
    ctx = mp.get_context("spawn")
    with ctx.Pool(min(workers, len(jobs)), initializer=_init_worker, initargs=(args, 1)) as pool:
        yield from pool.imap_unordered(_run_in_worker, jobs, chunksize=1)


def _finalize(root: Path, config: SynthConfig, seed: int, plans: list[TrajectoryPlan], done: dict) -> None:
    layout = DatasetLayout(root)
    files: dict[str, FileEntry] = {}
    for unit_files in done.values():
        for rel, (sha, size) in unit_files.items():
            files[rel] = FileEntry(sha, size)
    spec = dataset_spec(config, seed, plans)
    for split in SPLIT_NAMES:
        ids = [f"{p.key}/{frame_name(i)}" for p in plans if p.split == split for i in range(p.num_frames)]
        path = layout.split_file(spec.splits.files[split])
        write_split(path, ids)
        files[path.relative_to(root).as_posix()] = FileEntry(sha256_file(path), path.stat().st_size)
    spec.save(root / DATASET_YAML)
    files[DATASET_YAML] = FileEntry(sha256_file(root / DATASET_YAML), (root / DATASET_YAML).stat().st_size)
    write_manifest(root, files)  # its presence (without the state file) marks a complete dataset
    (root / STATE_NAME).unlink(missing_ok=True)
    for journal in root.glob(JOURNAL_GLOB):
        journal.unlink(missing_ok=True)


def _is_complete(root: Path, identity: dict) -> bool:
    if not (root / "manifest.json").is_file() or (root / STATE_NAME).exists():
        return False
    spec = DatasetSpec.load(root)
    if spec.generator != identity:
        raise ConfigError(
            f"out={root} already holds a complete dataset generated with different settings "
            f"(generator {spec.generator and spec.generator.get('config', {}).get('name')!r}, seed "
            f"{spec.generator and spec.generator.get('seed')}); choose another folder or delete it"
        )
    return True


def _prepare_output(root: Path, identity: dict) -> bool:
    """Write the state file of a new dataset, or check an unfinished one's; ``True`` when ``root`` turned out to be
    complete (another process finished it meanwhile)."""
    state = root / STATE_NAME
    if state.is_file():
        previous = json.loads(state.read_text(encoding="utf-8"))
        if previous != identity:
            raise ConfigError(
                f"out={root} holds an unfinished dataset of different settings (seed/config differ); resume it "
                "with the same preset, options and seed, or delete the folder"
            )
        return False
    # Shards started together race to write the state file: the generator's own hidden files are no obstacle.
    foreign = [p.name for p in root.iterdir() if not is_generator_file(p.name)] if root.exists() else []
    if foreign:
        if "manifest.json" in foreign:  # completed by another process since it was checked
            return _is_complete(root, identity)
        raise ConfigError(f"out={root} exists and is not empty (and is not a dataset being generated)")
    root.mkdir(parents=True, exist_ok=True)
    atomic_write_text(state, json.dumps(identity, sort_keys=True))
    return False


def is_generator_file(name: str) -> bool:
    """Whether a file name at a dataset's top is the generator's own state (state file, journals, temporaries)."""
    return name.startswith(".airfisheye-") or Path(name).match(TEMP_GLOB)


def read_journals(root: Path) -> dict[str, dict]:
    """Finished units of every journal of ``root`` (the whole run's and each shard's), by unit key."""
    done: dict[str, dict] = {}
    for journal in sorted(root.glob(JOURNAL_GLOB)):
        done.update(_read_journal(journal, root))
    return done


def _read_journal(journal: Path, root: Path) -> dict[str, dict]:
    """Finished units from the journal, keeping only those whose files are all present with the right size."""
    done: dict[str, dict] = {}
    if not journal.is_file():
        return done
    for line in journal.read_text(encoding="utf-8").splitlines():
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut short by the interruption
        files = entry.get("files", {})
        if all(
            (root / rel).is_file() and (root / rel).stat().st_size == size for rel, (_, size) in files.items()
        ):
            done[entry["unit"]] = files
    return done
