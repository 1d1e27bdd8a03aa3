"""``data.format=kitti360``: reading, the transform chain and the curl against the devkit's own formulas, splits,
bad input, the seg refusal, and training end to end on a fixture in the real layout
(:mod:`airfisheye_bench.studies.miniature_datasets.kitti360`).

The devkit's formulas, re-implemented line by line and not through the project's code, are
:mod:`airfisheye_bench.studies.miniature_datasets.kitti360_devkit` (the KITTI-360 benchmark times the curl against
them too).
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import open_dict

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.io import DatasetFormatError, EmptySplitError, load_camera
from airfisheye_bench.io.datasets import DatasetSource, DepthPoints, open_dataset
from airfisheye_bench.io.datasets.kitti360 import Kitti360Source
from airfisheye_bench.studies.miniature_datasets.kitti360 import SEQUENCES, image, write_kitti360
from airfisheye_bench.studies.miniature_datasets.kitti360_devkit import (
    devkit_cam2image,
    devkit_curl,
    devkit_velo_to_cam,
    devkit_velo_to_pose,
)
from airfisheye_bench.training import train
from datamodules.dataset import AirFisheyeDataset, CameraConfig
from tests.helpers import calibration_fixtures
from tests.helpers.commands import TRAIN, assert_one_line_error, run_in_process
from tests.helpers.configs import compose_train
from tests.helpers.runs import tiny_run_overrides

SEQ = SEQUENCES[0]


@pytest.fixture(scope="module")
def root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_kitti360(tmp_path_factory.mktemp("kitti360"))


# ----------------------------------------------------------------------------------------------- reading
@pytest.mark.parametrize("cam", ["image_02", "image_03"])
def test_lidar_to_camera_is_the_devkits_chain(root: Path, cam: str) -> None:
    src = open_dataset(root, "kitti360", {"camera": cam})
    calib = src.calib(f"{SEQ}/0000000000")
    np.testing.assert_allclose(calib.T_cam_lidar_static, devkit_velo_to_cam(root, cam), atol=1e-9)
    np.testing.assert_allclose(calib.T_body_lidar, devkit_velo_to_pose(root), atol=1e-9)
    # The camera stamps equal the scan stamps in this root: no extra motion between the two.
    np.testing.assert_allclose(src.T_cam_lidar(f"{SEQ}/0000000001"), calib.T_cam_lidar_static, atol=1e-12)


def test_velodyne_frame_is_flu_in_the_rig(root: Path) -> None:
    """In the pose frame (x forward, y right, z down) the Velodyne's x is forward, y left, z up: FLU."""
    R = devkit_velo_to_pose(root)[:3, :3]
    np.testing.assert_allclose(np.sign(np.round(R)), np.diag([1.0, -1.0, -1.0]))
    src = open_dataset(root, "kitti360", {"camera": "image_02"})  # the left camera sees +y_velo
    T = src.calib(f"{SEQ}/0000000000").T_cam_lidar_static
    assert (T[:3, :3] @ [0.0, 1.0, 0.0])[2] > 0.99


@pytest.mark.parametrize("size", [96, 48])
def test_a_velodyne_point_lands_where_the_devkit_projects_it(root: Path, tmp_path: Path, size: int) -> None:
    """Points written into a frame's .bin project (curled, through the chain, MEI) to the pixel of the devkit's
    ``cam2image`` (scaled about the corner at a served size of 48), with their range from the camera."""
    local = tmp_path / "k360"
    shutil.copytree(root, local)
    frame = 1
    pcd = np.array([[2.0, 6.0, 0.5], [-1.0, 8.0, -1.2], [3.0, 4.0, 1.5]])  # left of the car, seen by image_02
    bin_path = local / "data_3d_raw" / SEQ / "velodyne_points" / "data" / f"{frame:010d}.bin"
    np.hstack([pcd, np.ones((3, 1))]).astype(np.float32).tofile(bin_path)
    pcd = np.fromfile(bin_path, np.float32).reshape(-1, 4)[:, :3].astype(np.float64)

    cam = devkit_velo_to_cam(local, "image_02") @ np.vstack(
        [devkit_curl(local, SEQ, frame, pcd).T, np.ones(3)]
    )
    u, v, depth = devkit_cam2image(local, "image_02", cam[:3].T)
    assert (depth > 0).all()
    s = size / 96
    u, v = (u + 0.5) * s - 0.5, (v + 0.5) * s - 0.5

    ds = AirFisheyeDataset.from_root(
        local, "train", "depth", source="fisheye", camera=CameraConfig(size=size), format="kitti360",
        format_options={"target_occlusion": "none"}, lidar_min_range=0.0,
    )  # fmt: skip
    target = ds.reader.depth_points(f"{SEQ}/{frame:010d}")
    uv, _ = ds.camera.project(
        torch.from_numpy(target.points @ ds.reader.T_cam_lidar(f"{SEQ}/{frame:010d}")[:3, :3].T)
        + torch.from_numpy(ds.reader.T_cam_lidar(f"{SEQ}/{frame:010d}")[:3, 3])
    )
    np.testing.assert_allclose(uv.numpy(), np.stack([u, v], axis=1), atol=1e-6)
    depth_map = ds[ds.sample_ids.index(f"{SEQ}/{frame:010d}")]["depth"][0]
    for ui, vi, di in zip(u, v, depth, strict=True):
        assert depth_map[round(vi), round(ui)].item() == pytest.approx(di, abs=1e-4)
    assert int((depth_map > 0).sum()) == 3


@pytest.mark.parametrize(("cam", "most"), [("image_02", 0.62), ("image_03", 1.23)])
def test_the_devkit_leaves_out_the_tangential_terms(tmp_path: Path, cam: str, most: float) -> None:
    """docs/design.md, "Camera models": on KITTI-360's own calibrations ``cam2image`` (k1, k2 only) and ``unified``
    (p1, p2 kept, as ``cv2.omnidir``) put a ray up to 0.62 px (image_02) and 1.23 px (image_03) apart in the image."""
    (tmp_path / "calibration").mkdir()
    camera = load_camera(calibration_fixtures.write_kitti360(tmp_path / "calibration" / f"{cam}.yaml", cam))
    theta, phi = np.meshgrid(
        np.radians(np.arange(0.0, 180.0, 0.25)), np.radians(np.arange(-180.0, 180.0, 0.5))
    )
    rays = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1).reshape(
        -1, 3
    )
    u, v, _ = devkit_cam2image(tmp_path, cam, rays)
    ours, valid = camera.project(rays)
    theirs = np.stack([u, v], 1)
    inside = valid & camera.in_image(ours) & camera.in_image(theirs)
    shift = np.linalg.norm(ours[inside] - theirs[inside], axis=1)
    assert shift.max() == pytest.approx(most, abs=0.01)
    assert shift[np.degrees(theta.reshape(-1))[inside] <= 45.0].max() < most / 3


@pytest.mark.parametrize("frame", [0, 1, 3])
def test_deskew_is_the_devkits_curl(root: Path, frame: int) -> None:
    """Frame 0 takes the next frame's motion, 1 the previous one's, 3 none (frame 2 has no pose: standing)."""
    src = open_dataset(root, "kitti360", {})
    pcd = np.fromfile(root / "data_3d_raw" / SEQ / "velodyne_points/data" / f"{frame:010d}.bin", np.float32)
    pcd = pcd.reshape(-1, 4)[::997, :3].astype(np.float64)
    moved = src.deskew(f"{SEQ}/{frame:010d}", pcd)
    np.testing.assert_allclose(moved, devkit_curl(root, SEQ, frame, pcd), atol=1e-9)
    assert (np.abs(moved - pcd).max() > 0.1) == (frame != 3)


def test_without_scan_time_stamps_the_curl_is_still_the_devkits(root: Path, tmp_path: Path) -> None:
    local = tmp_path / "k360"
    shutil.copytree(root, local, ignore=shutil.ignore_patterns("*.png"))
    (local / "data_3d_raw" / SEQ / "velodyne_points" / "timestamps.txt").unlink()
    src = open_dataset(local, "kitti360", {})
    pcd = load_bin(local, 1)[::997]
    np.testing.assert_allclose(
        src.deskew(f"{SEQ}/0000000001", pcd), devkit_curl(local, SEQ, 1, pcd), atol=1e-9
    )
    T = src.T_cam_lidar(f"{SEQ}/0000000001")  # no scan time: the camera is taken as simultaneous
    np.testing.assert_allclose(T, src.calib(f"{SEQ}/0000000001").T_cam_lidar_static)


def test_the_camera_time_stamp_moves_the_lidar_frame(tmp_path: Path) -> None:
    """A camera 20 ms after the scan, the car at ~10 m/s: a point 10 m ahead is ~0.2 m closer to it."""
    late = write_kitti360(
        tmp_path / "late", sequences=SEQUENCES[:1], frames=2, unposed=(), camera_delay_s=0.02
    )
    src = open_dataset(late, "kitti360", {})
    sid = f"{SEQ}/0000000001"
    T_static = src.calib(sid).T_cam_lidar_static
    ahead = np.linalg.inv(T_static) @ src.T_cam_lidar(sid) @ np.array([10.0, 0.0, 0.0, 1.0])
    assert ahead[0] == pytest.approx(10.0 - 0.2, abs=0.02)


def test_accumulated_targets_are_moved_through_the_poses(root: Path) -> None:
    """accumulate=1: the posed frames either side of frame 1 in poses.txt are 0 and 3 (2 has no pose)."""
    src = open_dataset(root, "kitti360", {"accumulate": 1})
    target = src.depth_points(f"{SEQ}/0000000001", min_range=1.0)
    scans = {g: load_bin(root, g) for g in (0, 1, 3)}
    scans = {g: p[np.linalg.norm(p, axis=1) >= 1.0] for g, p in scans.items()}
    assert len(target.points) == sum(len(p) for p in scans.values())
    assert target.occlusion == "zbuffer"
    poses = np.loadtxt(root / "data_poses" / SEQ / "poses.txt")
    world = {int(row[0]): np.vstack([row[1:].reshape(3, 4), [0, 0, 0, 1]]) for row in poses}
    velo_pose = devkit_velo_to_pose(root)
    some = slice(0, None, 5000)
    start = 0
    for g, scan in scans.items():  # the clouds follow the frame order, each in frame 1's Velodyne frame
        # accumulation.cpp AddVelodynePoints: the scan's world points are Tr_pose_world * Tr_velo_pose * curled.
        T = np.linalg.inv(world[1] @ velo_pose) @ world[g] @ velo_pose
        expected = devkit_curl(root, SEQ, g, scan[some]) @ T[:3, :3].T + T[:3, 3]
        np.testing.assert_allclose(target.points[start : start + len(scan)][some], expected, atol=1e-6)
        start += len(scan)


def load_bin(root: Path, frame: int, seq: str = SEQ) -> np.ndarray:
    path = root / "data_3d_raw" / seq / "velodyne_points/data" / f"{frame:010d}.bin"
    return np.fromfile(path, np.float32).reshape(-1, 4)[:, :3].astype(np.float64)


def test_images_and_completion_samples(root: Path) -> None:
    ds = AirFisheyeDataset.from_root(
        root, "val", "completion", source="fisheye", camera=CameraConfig(size=48), format="kitti360"
    )
    sample = ds[0]
    assert sample["sample_id"] == f"{SEQUENCES[1]}/0000000000"
    assert sample["image"].shape == (3, 48, 48) and sample["depth"].shape == sample["sparse_depth"].shape
    assert (sample["sparse_depth"] > 0).sum() > 50 and (sample["depth"] > 0).sum() > 50
    assert not (sample["depth"][0] > 0)[~sample["valid_mask"]].any()
    rgb = ds.reader.fisheye(ds.sample_ids[0], "rgb")
    np.testing.assert_array_equal(rgb, image(10))
    assert ds.lidar_counts["rings from firing_order"] == 1
    assert isinstance(ds.reader, DatasetSource)


def test_augmented_point_depth_is_the_flipped_projection(root: Path) -> None:
    """A horizontal flip mirrors the projected target about the principal point's column: u -> 2 cx - u."""
    from datamodules.augment import AugmentParams

    ds = AirFisheyeDataset.from_root(
        root, "train", "depth", source="fisheye", camera=CameraConfig(size=96), format="kitti360",
        format_options={"target_occlusion": "none"},
    )  # fmt: skip
    sid = ds.sample_ids[0]
    plain = ds._point_depth(sid, None)[0]
    flipped = ds._point_depth(sid, AugmentParams(True, 0.0, None))[0]
    v, u = torch.nonzero(plain > 0, as_tuple=True)
    mirrored = torch.round(2 * ds.camera.cx - u).long()
    inside = (mirrored >= 0) & (mirrored < 96)
    assert inside.sum() > 100
    hit = flipped[v[inside], mirrored[inside]] > 0
    assert hit.float().mean() > 0.95  # a few pixels hold two points and keep the nearer one


@pytest.mark.parametrize(("flip", "angle"), [(False, 0.3), (True, 0.3), (True, -0.5)])
def test_augmented_point_depth_is_the_moved_projection(root: Path, flip: bool, angle: float) -> None:
    """Rotated (and mirrored) targets are the points projected through the turned camera: where the moved plain
    map (nearest resampling, which shifts some points by a pixel) has a point, the projection mostly has the same
    one; turned the wrong way round, almost none."""
    from datamodules.augment import AugmentParams, apply_geometry

    ds = AirFisheyeDataset.from_root(
        root, "train", "depth", source="fisheye", camera=CameraConfig(size=96), format="kitti360",
        format_options={"target_occlusion": "none"},
    )  # fmt: skip
    sid = ds.sample_ids[0]
    full = ds.reader.depth_points(sid, 1.0).points
    few = full[
        np.random.default_rng(0).choice(len(full), 300, replace=False)
    ]  # few points: few share a pixel
    ds.reader.depth_points = lambda sample_id, min_range: DepthPoints(few, "none")
    plain = ds._point_depth(sid, None)
    turned = ds._point_depth(sid, AugmentParams(flip, angle, None))[0]
    n = int((turned > 0).sum())
    for sign in (1.0, -1.0):
        moved = apply_geometry(
            plain, AugmentParams(flip, sign * angle, None), ds.camera.cx, ds.camera.cy, "nearest"
        )
        both = (turned > 0) & (moved[0] > 0)
        if sign > 0:
            assert both.sum() > 0.4 * n
            assert ((turned - moved[0]).abs()[both] < 1e-4).float().mean() > 0.8
        else:
            assert both.sum() < 0.1 * n


# ------------------------------------------------------------------------------------------------- splits
def test_default_splits_by_sequence(root: Path, tmp_path: Path) -> None:
    src = open_dataset(root, "kitti360", {})
    assert src.split("train") == [f"{SEQ}/{f:010d}" for f in (0, 1, 3)]  # frame 2 has no pose
    assert src.split("val") == src.split("test") == [f"{SEQUENCES[1]}/{f:010d}" for f in (0, 1, 3)]
    assert open_dataset(root, "kitti360", {"frame_step": 2}).split("train") == [
        f"{SEQ}/0000000000",
        f"{SEQ}/0000000003",
    ]
    many = tmp_path / "many"
    names = [f"2013_05_28_drive_{i:04d}_sync" for i in (10, 0, 3, 2)]
    for name in names:
        (many / "data_2d_raw" / name / "image_02" / "data_rgb").mkdir(parents=True)
        (many / "data_3d_raw" / name / "velodyne_points" / "data").mkdir(parents=True)
        (many / "data_poses" / name).mkdir(parents=True)
        (many / "data_poses" / name / "poses.txt").write_text("0 1 0 0 0 0 1 0 0 0 0 1 0\n")
    test_only = "2013_05_28_drive_0018_sync"  # images but no poses (a held-out sequence): not used
    (many / "data_2d_raw" / test_only / "image_02" / "data_rgb").mkdir(parents=True)
    locations = open_dataset(many, "kitti360", {}).spec.splits.locations
    assert locations == {names[1]: "train", names[3]: "train", names[2]: "val", names[0]: "test"}


def test_sequences_option_sets_the_splits(root: Path) -> None:
    src = open_dataset(
        root, "kitti360", {"sequences": {"train": [SEQUENCES[1]], "val": [SEQ], "test": [SEQ]}}
    )
    assert src.split("train")[0].startswith(SEQUENCES[1]) and src.split("test")[0].startswith(SEQ)
    with pytest.raises(ConfigError, match=r"data\.format_options\.sequences\.val: .*nope is not a folder"):
        open_dataset(root, "kitti360", {"sequences": {"val": ["nope"]}})
    with pytest.raises(EmptySplitError, match=r"split 'val' is empty .*split's sequences: none"):
        AirFisheyeDataset.from_root(
            root, "val", "depth", source="fisheye", format="kitti360",
            format_options={"sequences": {"train": [SEQ], "test": [SEQ]}},
        )  # fmt: skip


# ---------------------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("damage", "name", "message"),
    [
        (
            lambda r: (r / "calibration/calib_cam_to_velo.txt").unlink(),
            "calib_cam_to_velo.txt",
            "no such file",
        ),
        (
            lambda r: (r / "calibration/calib_cam_to_pose.txt").write_text(
                "image_00: 1 0 0 0 0 1 0 0 0 0 1 0\n"
            ),
            "calib_cam_to_pose.txt",
            "no line for image_01, image_02, image_03",
        ),
        (lambda r: (r / "data_poses" / SEQ / "poses.txt").write_text("0 1 0 0\n"), "poses.txt", "line 1"),
        (
            lambda r: (r / "data_3d_raw" / SEQ / "velodyne_points/timestamps.txt").write_text("yesterday\n"),
            "timestamps.txt",
            "'yesterday' is not 'YYYY-MM-DD HH:MM:SS.nnnnnnnnn'",
        ),
        (lambda r: (r / "calibration/image_02.yaml").unlink(), "image_02.yaml", "no such file"),
    ],
)
def test_bad_files_name_the_file(root: Path, tmp_path: Path, damage, name: str, message: str) -> None:
    local = tmp_path / "k360"
    shutil.copytree(root, local)
    damage(local)
    with pytest.raises(DatasetFormatError) as caught:
        src = open_dataset(local, "kitti360", {})
        sid = src.split("train")[0]
        src.calib(sid)
        src.deskew(sid, np.ones((1, 3)))
    assert name in str(caught.value) and message in str(caught.value)


def test_a_missing_scan_names_the_file(root: Path) -> None:
    src = open_dataset(root, "kitti360", {})
    with pytest.raises(DatasetFormatError, match=r"0000000009\.bin"):
        src.lidar_scan(f"{SEQ}/0000000009")


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"camera": "image_00"}, "data.format_options.camera='image_00': expected image_02 or image_03"),
        ({"accumulate": -1}, "data.format_options.accumulate=-1: expected an integer >= 0"),
        ({"target_occlusion": "ordering"}, "data.format_options.target_occlusion='ordering'"),
        ({"camra": "image_03"}, "data.format_options: unknown keys ['camra'] for data.format=kitti360"),
    ],
)
def test_bad_options_are_config_errors(root: Path, options: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(message)):
        open_dataset(root, "kitti360", options)


def test_cube_faces_and_labels_are_refused_with_the_reason(root: Path) -> None:
    with pytest.raises(
        ConfigError, match=r"KITTI-360 has recorded fisheye images, no cube faces; use data\.source"
    ):
        AirFisheyeDataset.from_root(root, "train", "depth", source="cubemap", format="kitti360")
    with pytest.raises(
        ConfigError, match=r"no semantic labels for its fisheye images .*issue #1\); task=seg"
    ):
        AirFisheyeDataset.from_root(root, "train", "seg", source="fisheye", format="kitti360")


def test_the_config_lists_every_option_with_its_default() -> None:
    cfg = compose_train(["task=depth", "data=kitti360"])
    assert cfg.data.format == "kitti360" and cfg.data.root is None and cfg.data.source == "fisheye"
    assert dict(cfg.data.format_options) == Kitti360Source.OPTIONS


# --------------------------------------------------------------------------------------------- end to end
@pytest.mark.integration
def test_seg_is_refused_in_one_line(root: Path, tmp_path: Path) -> None:
    outcome = run_in_process(
        TRAIN,
        ["task=seg", "data=kitti360", f"data.root={root}", "trainer=debug", f"hydra.run.dir={tmp_path}"],
    )
    assert_one_line_error(
        outcome, "KITTI-360 has no semantic labels for its fisheye images", "issue #1", "task=seg"
    )
    assert not (tmp_path / "results.json").exists()


# depth reads what completion reads (the image, the dense depth) and trains AdaBins, which the tiny runs cover: slow
@pytest.mark.integration
@pytest.mark.parametrize("task", [pytest.param("depth", marks=pytest.mark.slow), "completion"])
def test_training_end_to_end(root: Path, tmp_path: Path, task: str) -> None:
    overrides = [
        *tiny_run_overrides(task, root, size=64),
        "data=kitti360",
        "logger=csv",
        "data.format_options.accumulate=1",
    ]
    cfg = compose_train(overrides)
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    results = train(cfg)
    record = json.loads((tmp_path / "results.json").read_text())
    primary = cfg.task.primary_metric
    assert record["task"] == task and record["dataset"]["name"] == "kitti360"
    assert math.isfinite(record["metrics"][primary]) and record["metrics"][primary] == pytest.approx(
        results["metrics"][primary]
    )
