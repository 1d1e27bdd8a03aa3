"""The dataset writer: layout, dataset.yaml, determinism, resume, verify, ground-truth consistency, CLI."""

from __future__ import annotations

import shutil
import threading
from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.cli import generate as cli_main
from airfisheye_bench.geometry import FACE_NAMES, CubemapToFisheye, face_rotation
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.transforms import make_transform, transform_points
from airfisheye_bench.io import DatasetReader, DatasetSpec, trajectory_of
from airfisheye_bench.io.content import CONTENT_CACHE_NAME
from airfisheye_bench.io.manifest import read_manifest, verify
from airfisheye_bench.synth import cache, recording, writer
from airfisheye_bench.synth.classes import RAW_CLASSES, RAW_ID, RAW_TO_TRAIN, TRAIN_CLASSES
from airfisheye_bench.synth.presets import PRESETS, get_preset, plan_trajectories
from airfisheye_bench.synth.scene import ENVIRONMENTS
from airfisheye_bench.synth.sensors import lidar_visibility, scan_lidar
from tests.helpers.commands import exit_status

#: A very small configuration for the tests that generate several times.
MICRO = get_preset("tiny").replace(
    name="micro",
    total_frames=6,
    face_size=16,
    fisheye_size=24,
    lidar_channels=8,
    lidar_points_per_channel=32,
    scene_size_m=100.0,
)


def _all_ids(reader: DatasetReader) -> list[str]:
    return [sid for split in reader.split_names for sid in reader.split(split)]


def _tree_bytes(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


# ----------------------------------------------------------------------------------------------- layout
def test_layout_and_dataset_yaml(tiny_dataset):
    spec = DatasetSpec.load(tiny_dataset)
    assert [c.name for c in spec.raw_classes] == [c.name for c in RAW_CLASSES]
    assert [c.name for c in spec.train_classes] == [c.name for c in TRAIN_CLASSES]
    assert spec.raw_to_train == RAW_TO_TRAIN and spec.ignore_index == 255
    assert set(spec.contents) == {"cubemap", "fisheye", "lidar", "lidar_visible", "poses", "imu"}
    assert "camera centre" in spec.sensors["visibility"] and spec.generator["seed"] == 0

    reader = DatasetReader(tiny_dataset)
    cfg = get_preset("tiny")
    plans = plan_trajectories(cfg, ENVIRONMENTS)
    splits = {name: reader.split(name) for name in ("train", "val", "test")}
    assert sum(map(len, splits.values())) == cfg.total_frames
    locations = {name: {trajectory_of(s) for s in ids} for name, ids in splits.items()}
    assert not (locations["train"] & locations["val"]) and not (locations["train"] & locations["test"])
    assert not (locations["val"] & locations["test"])  # split by location
    assert {p.key: p.split for p in plans} == spec.splits.locations

    s = cfg.face_size
    for sid in _all_ids(reader):
        assert reader.cubemap(sid, "rgb").shape == (5, s, s, 3)
        assert reader.cubemap(sid, "seg").max() < len(RAW_CLASSES)
        fish_seg = reader.fisheye(sid, "seg")
        outside = ~CubemapToFisheye(reader.calib(sid).fisheye_camera(), s).valid_mask.numpy()
        assert (fish_seg[outside] == 255).all() and (reader.fisheye(sid, "depth")[outside] == 0).all()
        points = reader.lidar(sid)
        assert len(points) == len(reader.lidar_visible(sid)) > 0
        assert (np.linalg.norm(points[:, :3], axis=1) <= cfg.lidar_max_range + 1e-3).all()
    for traj in reader.trajectories():
        poses, calib = reader.poses(traj), reader.calib(traj)
        assert np.allclose(np.diff(poses.t_cam), 0.1) and (poses.t_lidar - poses.t_cam > 0.019).all()
        assert calib.face_size == s and calib.lidar_spec() == cfg.lidar_spec()
        assert reader.imu(traj).rate_hz == cfg.flight.imu_rate_hz

    # No journal, state or temporary files. The content identity's cache (io.content) and the preset cache's
    # marker (synth.cache) are the readers', written when another test of the session used this shared dataset.
    leftovers = [
        p.name
        for p in tiny_dataset.rglob("*")
        if p.name.startswith(".") and p.name not in (CONTENT_CACHE_NAME, cache.CURRENT_MARKER)
    ]
    assert leftovers == []
    assert verify(tiny_dataset).ok


# --------------------------------------------------------------------------------- ground truth checks
def _face_pixel(p_cam: np.ndarray, s: int):
    """Independent cube lookup: face with the largest component along its axis, nearest pixel."""
    R = np.stack([face_rotation(f) for f in FACE_NAMES])
    along = p_cam @ R[:, :, 2].T
    face = along.argmax(1)
    local = np.einsum("nji,nj->ni", R[face], p_cam)
    u = local[:, 0] / local[:, 2] * s / 2 + (s - 1) / 2
    v = local[:, 1] / local[:, 2] * s / 2 + (s - 1) / 2
    return (
        face,
        np.clip(np.round(v), 0, s - 1).astype(int),
        np.clip(np.round(u), 0, s - 1).astype(int),
        along.max(1) > 0,
    )


def test_lidar_ranges_agree_with_face_depth_for_visible_points(tiny_dataset):
    reader = DatasetReader(tiny_dataset)
    errors, labels_agree = [], []
    for sid in _all_ids(reader):
        points, visible = reader.lidar(sid), reader.lidar_visible(sid)
        depth = reader.cubemap(sid, "depth")
        p_cam = transform_points(reader.T_cam_lidar(sid), points[:, :3].astype(np.float64))
        face, row, col, on_cube = _face_pixel(p_cam, depth.shape[1])
        keep = visible & on_cube
        rng = np.linalg.norm(p_cam[keep], axis=1)
        errors.append(np.abs(depth[face[keep], row[keep], col[keep]] - rng) / rng)
        # Labels agree too (the LiDAR's raw id is the class of the surface it hit).
        seg = reader.cubemap(sid, "seg")[face[keep], row[keep], col[keep]]
        labels_agree.append(seg == points[keep, 3])
    err = np.concatenate(errors)
    assert np.median(err) < 0.02 and (err < 0.05).mean() > 0.85  # pixel-centre rays vs exact LiDAR rays
    assert np.concatenate(labels_agree).mean() > 0.8  # thin classes (lane markings, poles) differ at 48^2


def test_lidar_points_and_visibility_match_exact_ray_casts(tiny_dataset):
    """Re-create a trajectory's scene and cast from the camera centre (read from poses.csv + calib.yaml) to every
    LiDAR point: visible points are hit at their own range, hidden ones earlier. With the static (not
    motion-compensated) extrinsics the ranges disagree by the distance flown between the two timestamps."""
    reader = DatasetReader(tiny_dataset)
    cfg = get_preset("tiny")
    plan = next(p for p in plan_trajectories(cfg, ENVIRONMENTS) if p.split == "train")
    scene = recording.build_trajectory(cfg, 0, plan).scene
    calib = reader.calib(plan.key)
    for i in (0, plan.num_frames - 1):
        sid = f"{plan.key}/{i:06d}"
        points, visible = reader.lidar(sid), reader.lidar_visible(sid)
        poses = reader.poses(sid)
        T_world_cam = poses.T_world_body_cam[i] @ calib.T_body_cam
        errors = []
        for T_cam_lidar in (reader.T_cam_lidar(sid), calib.T_cam_lidar_static):
            p_cam = transform_points(T_cam_lidar, points[:, :3].astype(np.float64))
            rng = np.linalg.norm(p_cam, axis=1)
            dirs = (p_cam / rng[:, None]) @ T_world_cam[:3, :3].T
            origin = np.broadcast_to(T_world_cam[:3, 3], dirs.shape)
            o, d = torch.tensor(origin, dtype=torch.float32), torch.tensor(dirs, dtype=torch.float32)
            dist = scene.raycast(o, d, 1000.0).dist.numpy()
            errors.append(np.abs(dist[visible] - rng[visible]))
            if not errors[1:]:  # motion-compensated: exact up to float32 ray-casting precision
                assert errors[0].max() < 0.01 + 1e-4 * rng[visible].max()
                assert (dist[~visible] < rng[~visible] - 0.01).all()
        # Uncompensated, the ranges are off by about the distance flown between t_cam and t_lidar.
        flown = np.linalg.norm(poses.T_world_body_lidar[i, :3, 3] - poses.T_world_body_cam[i, :3, 3])
        assert flown > 0.04
        assert (
            np.median(errors[1]) > 10 * np.median(errors[0]) and np.percentile(errors[1], 90) > 0.25 * flown
        )


def test_visibility_on_a_constructed_scene():
    """A wall hides the ground behind it from a low camera but not from a LiDAR 10 m above it."""
    from airfisheye_bench.synth.builder import SceneBuilder
    from airfisheye_bench.synth.scene import Scene

    b = SceneBuilder(size_m=200.0, rng=np.random.default_rng(0))
    b.add_box(0.0, 20.0, 0.0, 10.0, 1.0, 8.0, 0.0, "wall", (0.5, 0.5, 0.5))  # x in [-5, 5], y in [19.5, 20.5]
    scene = Scene(b.finish())
    cam = np.array([0.0, 0.0, 5.0])
    R_north = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # LiDAR x -> north
    T_world_lidar = make_transform(R_north, np.array([0.0, 0.0, 15.0]))
    spec = LidarSpec(
        channels=48, points_per_channel=256, hfov_deg=60.0, vfov_deg=(-40.0, -5.0), max_range=120.0
    )
    points, world, _ = scan_lidar(scene, T_world_lidar, spec)
    assert (
        np.abs(transform_points(T_world_lidar, points[:, :3].astype(np.float64)) - world.numpy()).max() < 1e-3
    )
    visible = lidar_visibility(scene, cam, world)

    p = world.numpy().astype(np.float64)
    on_wall = points[:, 3] == RAW_ID["wall"]
    expected = np.ones(len(p), bool)
    # Wall points: only the front face (y = 19.5) can be seen from the camera, which is below the top (z = 8).
    expected[on_wall] = np.abs(p[on_wall, 1] - 19.5) < 1e-3
    # Ground points behind the wall: hidden iff the segment crosses the wall's slab within |x| <= 5 (the
    # segment stays below z = 5 < 8 there).
    behind = ~on_wall & (p[:, 1] > 20.5)
    x_at = lambda y: cam[0] + (p[behind, 0] - cam[0]) * (y - cam[1]) / (p[behind, 1] - cam[1])  # noqa: E731
    xa, xb = x_at(19.5), x_at(20.5)
    crosses = (np.minimum(xa, xb) <= 5.0) & (np.maximum(xa, xb) >= -5.0)
    expected[behind] = ~crosses
    margin = np.minimum(np.abs(np.minimum(xa, xb) - 5.0), np.abs(np.maximum(xa, xb) + 5.0))
    clear = np.ones(len(p), bool)
    clear[behind] = margin > 0.05  # skip grazing segments
    assert (~expected & behind).sum() > 50 and expected[behind].sum() > 50  # both cases occur
    assert np.array_equal(visible[clear], expected[clear])


def test_cube_faces_agree_across_shared_edges(tiny_dataset):
    """Border pixels of each face, stepped one pixel outward, land on the neighbouring face: labels and depth agree."""
    reader = DatasetReader(tiny_dataset)
    s = get_preset("tiny").face_size
    c = (s - 1) / 2
    k = np.arange(s)
    border = np.concatenate(
        [
            np.stack([np.zeros(s), k], 1),
            np.stack([np.full(s, s - 1), k], 1),
            np.stack([k, np.zeros(s)], 1),
            np.stack([k, np.full(s, s - 1)], 1),
        ]
    )  # (row, col)
    step = np.concatenate(
        [
            np.tile([[-1, 0]], (s, 1)),
            np.tile([[1, 0]], (s, 1)),
            np.tile([[0, -1]], (s, 1)),
            np.tile([[0, 1]], (s, 1)),
        ]
    )
    label_agree, depth_err = [], []
    for sid in reader.split("train")[:4]:
        seg, depth = reader.cubemap(sid, "seg"), reader.cubemap(sid, "depth")
        for f, name in enumerate(FACE_NAMES):
            out = border + step  # one pixel beyond the edge, on the face's extended image plane
            d_face = np.stack([(out[:, 1] - c) / (s / 2), (out[:, 0] - c) / (s / 2), np.ones(len(out))], 1)
            nf, nr, nc, ok = _face_pixel(d_face @ face_rotation(name).T, s)
            ok &= nf != f
            r0, c0 = border[ok, 0].astype(int), border[ok, 1].astype(int)
            label_agree.append(seg[f, r0, c0] == seg[nf[ok], nr[ok], nc[ok]])
            a, b = depth[f, r0, c0], depth[nf[ok], nr[ok], nc[ok]]
            both = (a > 0) & (b > 0)
            depth_err.append(np.abs(a[both] - b[both]) / a[both])
            assert ((a > 0) == (b > 0)).mean() > 0.9  # sky meets sky
    assert np.concatenate(label_agree).mean() > 0.85
    assert np.median(np.concatenate(depth_err)) < 0.05


def test_raycast_fisheye_matches_the_cubemap_remap(tiny_dataset):
    reader = DatasetReader(tiny_dataset)
    for sid in reader.split("val"):
        remap = CubemapToFisheye(reader.calib(sid).fisheye_camera(), get_preset("tiny").face_size)
        seg = remap.remap(reader.cubemap(sid, "seg")[:, None], mode="nearest", fill=255)[0]
        depth = remap.remap(reader.cubemap(sid, "depth")[:, None], mode="nearest", fill=0)[0]
        fseg, fdepth = reader.fisheye(sid, "seg"), reader.fisheye(sid, "depth")
        inside = fseg != 255
        assert np.array_equal(inside, seg != 255)
        assert (seg[inside] == fseg[inside]).mean() > 0.85
        both = (depth > 0) & (fdepth > 0)
        assert np.median(np.abs(depth[both] - fdepth[both]) / fdepth[both]) < 0.02


# ------------------------------------------------------------------------------- determinism / resume
class _Interrupted(Exception):
    pass


@pytest.fixture(scope="module")
def micro_reference(tmp_path_factory) -> Path:
    return writer.generate_dataset(
        MICRO, tmp_path_factory.mktemp("micro") / "ref", seed=3, workers=1, progress=False
    )


@pytest.mark.integration
def test_two_workers_give_identical_bytes(micro_reference, tmp_path):
    other = writer.generate_dataset(MICRO, tmp_path / "two", seed=3, workers=2, progress=False)
    assert _tree_bytes(other) == _tree_bytes(micro_reference)


def test_resume_after_interruption_is_byte_identical(micro_reference, tmp_path, monkeypatch):
    out = tmp_path / "resumed"
    calls = {"n": 0}
    original = writer.Worker.run

    def flaky(self, job):
        calls["n"] += 1
        if calls["n"] > 5:
            raise _Interrupted
        return original(self, job)

    monkeypatch.setattr(writer.Worker, "run", flaky)
    with pytest.raises(_Interrupted):
        writer.generate_dataset(MICRO, out, seed=3, workers=1, progress=False)
    monkeypatch.undo()
    assert (out / writer.JOURNAL_NAME).is_file() and not (out / "manifest.json").exists()
    # Debris of a killed process: a temporary file, and a frame file written but never journaled (corrupted).
    (out / ".000009.png.deadbeef.tmp").write_bytes(b"partial")
    unjournaled = sorted((out).rglob("lidar/*.npy"))[-1]
    unjournaled.write_bytes(b"garbage")
    with pytest.raises(ValueError, match="different settings"):
        writer.generate_dataset(MICRO, out, seed=4, workers=1, progress=False)
    writer.generate_dataset(MICRO, out, seed=3, workers=1, progress=False)
    assert _tree_bytes(out) == _tree_bytes(micro_reference)


def test_verify_detects_corruption_missing_and_extra_files(micro_reference, tmp_path):
    root = tmp_path / "copy"
    shutil.copytree(micro_reference, root)
    assert verify(root).ok and cli_main(["verify", f"root={root}"]) == 0
    target = next(iter(sorted(read_manifest(root))))
    data = bytearray((root / target).read_bytes())
    data[len(data) // 2] ^= 0xFF
    (root / target).write_bytes(bytes(data))
    victim = sorted(root.rglob("*.png"))[0]
    victim.unlink()
    (root / "stray.txt").write_text("x")
    report = verify(root)
    assert report.corrupted == [target]
    assert report.missing == [victim.relative_to(root).as_posix()]
    assert report.unexpected == ["stray.txt"] and not report.ok
    assert cli_main(["verify", f"root={root}"]) == 1


def test_refuses_foreign_or_mismatched_output(micro_reference, tmp_path):
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="not empty"):
        writer.generate_dataset(MICRO, tmp_path / "busy", seed=3, progress=False)
    with pytest.raises(ValueError, match="different settings"):
        writer.generate_dataset(MICRO, micro_reference, seed=4, progress=False)
    assert writer.generate_dataset(MICRO, micro_reference, seed=3, progress=False) == micro_reference  # no-op


def test_ensure_dataset_generates_once_for_concurrent_callers(tmp_path, monkeypatch):
    monkeypatch.setitem(PRESETS, "micro", MICRO)
    calls = []
    original = writer.generate_dataset

    def counting(*args, **kwargs):
        calls.append(args)
        return original(*args, **kwargs)

    monkeypatch.setattr(cache, "generate_dataset", counting)
    results: list[Path] = []
    threads = [
        threading.Thread(
            target=lambda: results.append(
                cache.ensure_dataset("micro", root=tmp_path, workers=1, progress=False)
            )
        )
        for _ in range(2)
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(calls) == 1 and len(results) == 2 and results[0] == results[1]
    assert results[0] == cache.cached_dataset_path("micro", tmp_path) and verify(results[0]).ok
    assert not results[0].with_name(results[0].name + ".partial").exists()


def test_a_cache_written_by_another_generator_is_generated_again(tmp_path, monkeypatch, caplog):
    monkeypatch.setitem(PRESETS, "micro", MICRO)
    monkeypatch.setattr(cache, "_CURRENT", set())
    root = cache.ensure_dataset("micro", root=tmp_path, workers=1, progress=False)
    assert writer.stale_file(root, MICRO) is None  # the sampled frames re-render to the same content
    before = _tree_bytes(root)

    # What an older generator would have left: one LiDAR point 1 mm off in a sampled frame.
    plan = plan_trajectories(MICRO, ENVIRONMENTS)[0]
    rel = f"{plan.key}/lidar/000000.npy"
    points = np.load(root / rel)
    points[0, 0] += 1e-3
    np.save(root / rel, points)
    assert writer.stale_file(root, MICRO) == rel

    probes = []
    monkeypatch.setattr(cache, "stale_file", lambda *a: probes.append(a) or writer.stale_file(*a))
    monkeypatch.setattr(cache, "_CURRENT", set())  # a new process, the same code: the marker answers
    assert cache.ensure_dataset("micro", root=tmp_path, progress=False) == root and not probes

    monkeypatch.setattr(cache, "_CURRENT", set())  # a new process with other code
    monkeypatch.setattr(cache, "_code_fingerprint", lambda: "another version")
    with caplog.at_level("WARNING", logger=cache.log.name):
        again = cache.ensure_dataset("micro", root=tmp_path, workers=1, progress=False)
    assert again == root and verify(root).ok
    assert f"{rel} differs from what this version writes" in caplog.text
    after = _tree_bytes(root)
    assert after.keys() == before.keys() and after[rel] == before[rel]
    assert not list(tmp_path.glob("*.old")) and not list(tmp_path.glob("*.partial"))
    probes.clear()
    monkeypatch.setattr(cache, "_CURRENT", set())
    assert (
        cache.ensure_dataset("micro", root=tmp_path, progress=False) == root and not probes
    )  # marked current

    # Another config under the same name (a preset edited without a version bump) is stale too.
    monkeypatch.setitem(PRESETS, "micro", MICRO.replace(lidar_points_per_channel=48))
    assert writer.stale_file(root, PRESETS["micro"]) == "dataset.yaml"


def test_cli_generates_and_writes_a_contact_sheet(tiny_dataset, tmp_path):
    png = tmp_path / "sheet.png"
    assert cli_main(["contact_sheet", f"root={tiny_dataset}", f"png={png}"]) == 0
    from PIL import Image

    img = np.asarray(Image.open(png))
    assert img.ndim == 3 and img.shape[1] > 1000 and img.std() > 20
    assert exit_status(cli_main, ["preset=tiny", f"out={tmp_path / 'x'}", "bogus=1"]) == 2
    assert exit_status(cli_main, ["preset=tiny", f"out={tmp_path / 'x'}", "flight.bogus=1"]) == 2
    assert exit_status(cli_main, ["preset=tiny", f"out={tmp_path / 'x'}", "verify=maybe"]) == 2
    assert exit_status(cli_main, ["presetz"]) == 2 and not (tmp_path / "x").exists()
    assert cli_main(["presets"]) == 0
    out = tmp_path / "custom"
    assert (
        cli_main(
            [
                "preset=tiny",
                f"out={out}",
                "total_frames=4",
                "face_size=8",
                "fisheye_size=16",
                "lidar_channels=4",
                "lidar_points_per_channel=16",
                "scene_size_m=60",
                "verify=true",
                "contact_sheet=true",
                "progress=false",
            ]
        )
        == 0
    )
    # The contact sheet lands inside the dataset folder, and the dataset still verifies (it is not data).
    assert (out / "contact_sheet.png").is_file() and not list(tmp_path.glob("*contact_sheet*"))
    assert verify(out).ok and "contact_sheet.png" not in read_manifest(out)
    spec = DatasetSpec.load(out)
    assert spec.generator["config"]["face_size"] == 8 and spec.name == "airfisheye-synthetic-tiny-custom"


def test_gimbal_pitch_is_stratified_so_every_split_spans_the_range():
    cfg = get_preset("quickstart")
    plans = plan_trajectories(cfg, ENVIRONMENTS)
    lo, hi = cfg.flight.gimbal_pitch_deg
    for split in ("train", "val", "test"):
        values = [
            recording.stratified_value(p.index, cfg.num_trajectories, lo, hi, phase=0.1, jitter=j)
            for p in plans
            if p.split == split
            for j in (-0.5, 0.5)
        ]
        assert min(values) >= lo and max(values) <= hi
        assert max(values) - min(values) > 0.4 * (hi - lo)


def test_the_cache_generates_with_a_worker_per_core_up_to_eight(tmp_path, monkeypatch):
    monkeypatch.setitem(PRESETS, "micro", MICRO)
    seen: dict = {}

    def generate(*args, **kwargs):
        seen.update(kwargs)
        raise RuntimeError("stop before generating")

    monkeypatch.setattr(cache, "generate_dataset", generate)
    monkeypatch.setattr(cache.os, "cpu_count", lambda: 16)
    with pytest.raises(RuntimeError, match="stop before generating"):
        cache.ensure_dataset("micro", root=tmp_path, progress=False)
    assert seen["workers"] == 8
