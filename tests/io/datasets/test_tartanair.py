"""``data.format=tartanair``: TartanAir V2 read from fixtures written in the toolkit's exact layout and encodings
(airfisheye_bench/studies/miniature_datasets/tartanair.py; sources: github:castacks/tartanairpy e8535a8b and its
submodules)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest
import torch
from omegaconf import open_dict
from PIL import Image

from airfisheye_bench.geometry import CubemapToFisheye, ideal_camera
from airfisheye_bench.geometry.cube_depth import lidar_from_faces, sample_range
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.transforms import CAM_FROM_FLU
from airfisheye_bench.io.datasets import open_dataset
from airfisheye_bench.io.datasets.tartanair import TartanAirSource, read_depth_png
from airfisheye_bench.io.datasets.tartanair_labels import TARTANAIR_TO_TRAIN, TRAIN_CLASSES, train_id
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.studies.miniature_datasets.tartanair import (
    COLORS,
    NAME_MAPS,
    depth_png_bytes_order,
    scene_hit,
    tartanair_face_ray,
    tartanair_project,
    write_tartanair_fixture,
)

if TYPE_CHECKING:
    from datamodules import AirFisheyeDataset

SIZE = 48
FIRST = "CoalMine/easy_P000/000000"


@pytest.fixture(scope="module")
def fixture_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_tartanair_fixture(tmp_path_factory.mktemp("tartanair") / "root", size=SIZE)


@pytest.fixture(scope="module")
def small_download(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three trajectories (one environment) of 5 frames: fewer than the 10 a split by trajectory needs."""
    root = tmp_path_factory.mktemp("tartanair_small") / "root"
    return write_tartanair_fixture(root, size=SIZE, frames=5, environments=("CoalMine",))


@pytest.fixture
def writable_root(fixture_root: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(fixture_root, tmp_path / "root"))


def source(root: Path, **options) -> TartanAirSource:
    src = open_dataset(root, "tartanair", {"split_period": 3, **options})
    assert isinstance(src, TartanAirSource)
    return src


# ----------------------------------------------------------------------------------------------- encodings
def test_depth_png_golden_bytes(tmp_path: Path) -> None:
    """12.5 is float32 0x41480000, little-endian bytes 00 00 48 41; OpenCV writes channel 0 as blue, so the PNG
    holds R, G, B, A = 0x48, 0x00, 0x00, 0x41 (reader.py write_float_depth: image.view("<u1") -> cv2.imwrite)."""
    path = tmp_path / "000000_lcam_front_depth.png"
    Image.fromarray(np.full((2, 2, 4), (0x48, 0x00, 0x00, 0x41), np.uint8), "RGBA").save(path)
    assert read_depth_png(path).tolist() == [[12.5, 12.5], [12.5, 12.5]]


def test_depth_png_agrees_with_the_toolkit_code_through_opencv(tmp_path: Path) -> None:
    """Live comparison: the toolkit's own writer and reader (tartanair/reader.py, run through OpenCV)."""
    cv2 = pytest.importorskip("cv2")
    depth = np.random.default_rng(0).uniform(0.1, 1e4, (5, 7)).astype(np.float32)
    toolkit_file = tmp_path / "toolkit_depth.png"
    cv2.imwrite(str(toolkit_file), depth[..., None].view("<u1"))  # write_float_depth
    assert np.array_equal(read_depth_png(toolkit_file), depth)
    ours = tmp_path / "fixture_depth.png"
    Image.fromarray(depth_png_bytes_order(depth), "RGBA").save(ours)
    decoded = np.squeeze(cv2.imread(str(ours), cv2.IMREAD_UNCHANGED).view("<f4"), axis=-1)  # read_depth
    assert np.array_equal(decoded, depth)


def test_depth_is_range_along_each_texel_ray(fixture_root: Path) -> None:
    """The PNGs hold planar depth; the source serves range: at each texel, the analytic scene's distance along the
    texel's ray (reader.py depth_to_dist: planar * sqrt(u^2 + v^2 + f^2) / f, f = S/2, centres at i + 0.5)."""
    src = source(fixture_root)
    rows, cols = np.meshgrid(np.arange(SIZE), np.arange(SIZE), indexing="ij")
    for ours, theirs in (("front", "front"), ("up", "top"), ("down", "bottom"), ("left", "left")):
        expected, _ = scene_hit(tartanair_face_ray(theirs, cols, rows, SIZE), 0)
        got = src.face(FIRST, ours, "depth")
        hit = np.isfinite(expected)
        np.testing.assert_allclose(got[hit], expected[hit], rtol=1e-5)
    # Front centre-right texel (24, 24): ray (1/48, 1/48, 1) meets the building wall z = 8.
    assert src.face(FIRST, "front", "depth")[24, 24] == pytest.approx(8.0 * np.sqrt(1 + 2 / 48**2), rel=1e-6)


# ------------------------------------------------------------------------------------ face orientation
POINTS = {  # camera frame (x right, y down, z forward); off-centre so that a rotated face would misplace them
    "front": (1.0, 0.7, 5.0),
    "left": (-5.0, 0.8, 1.5),
    "right": (4.0, -1.0, 0.6),
    "top": (1.2, -4.0, 2.0),
    "bottom": (-1.5, 3.0, 0.9),
}
AXIS = {"front": (2, 1), "left": (0, -1), "right": (0, 1), "top": (1, -1), "bottom": (1, 1)}
MARKER = 77  # 'car' in the edited name map -> vehicle


def _place_markers(root: Path) -> None:
    """Put a 3x3 'car' patch, at the point's planar depth, where TartanAir's sampler puts each point."""
    env = root / "CoalMine"
    name_map = json.loads((env / "seg_label_map.json").read_text())
    name_map["name_map"]["car"] = MARKER
    (env / "seg_label_map.json").write_text(json.dumps(name_map))
    traj = env / "Data_easy" / "P000"
    for expected_face, point in POINTS.items():
        face, col, row = tartanair_project(np.array(point), SIZE)
        assert face == expected_face
        cam = f"lcam_{face}"
        seg_file, depth_file = (
            traj / f"seg_{cam}" / f"000000_{cam}_seg.png",
            traj / f"depth_{cam}" / f"000000_{cam}_depth.png",
        )
        seg = np.array(Image.open(seg_file))
        depth = read_depth_png(depth_file)
        r, c = slice(round(row) - 1, round(row) + 2), slice(round(col) - 1, round(col) + 2)
        axis, sign = AXIS[face]
        seg[r, c] = MARKER
        depth[r, c] = sign * point[axis]  # a patch of the plane through the point, facing the camera
        Image.fromarray(seg, "L").save(seg_file)
        Image.fromarray(depth_png_bytes_order(depth), "RGBA").save(depth_file)


def test_a_point_placed_by_tartanairs_sampler_lands_at_its_fisheye_pixel_with_its_range(
    writable_root: Path,
) -> None:
    _place_markers(writable_root)
    src = source(writable_root)
    camera = ideal_camera(256, 256, fov_deg=190.0, model="equidistant")
    remap = CubemapToFisheye(camera, SIZE)
    seg = remap(src.cubemap(FIRST, "seg")[:, None], "nearest", fill=255)[0]
    depth = remap(src.cubemap(FIRST, "depth")[:, None], "nearest", fill=0)[0]
    vehicle = [name for name, _ in TRAIN_CLASSES].index("vehicle")
    for face, point in POINTS.items():
        uv, valid = camera.project(np.array(point, dtype=np.float64))
        assert valid, face
        col, row = (round(float(c)) for c in uv)
        assert seg[row, col] == vehicle, face
        assert depth[row, col] == pytest.approx(np.linalg.norm(point), rel=0.03), face
    # The check is sensitive to the in-plane rotation of top/bottom: turned by 90 degrees they miss.
    faces = src.cubemap(FIRST, "seg")
    faces[3:] = np.rot90(faces[3:], axes=(1, 2))
    turned = remap(faces[:, None], "nearest", fill=255)[0]
    for face in ("top", "bottom"):
        uv, _ = camera.project(np.array(POINTS[face], dtype=np.float64))
        col, row = (round(float(c)) for c in uv)
        assert turned[row, col] != vehicle, face


# ------------------------------------------------------------------------------------------------ labels
def test_labels_map_through_each_environments_names(fixture_root: Path) -> None:
    src = source(fixture_root)
    names = [name for name, _ in TRAIN_CLASSES]
    # Front texel (24, 24) sees the building in both environments, whose maps give it 59 and 3 (59 is sky in the
    # second): both come out as the training class 'building'.
    for sid in (FIRST, "OldTownFall/easy_P000/000000"):
        env = sid.split("/")[0]
        raw = np.array(
            Image.open(fixture_root / env / "Data_easy/P000/seg_lcam_front/000000_lcam_front_seg.png")
        )
        assert raw[24, 24] == NAME_MAPS[env]["building"]
        assert src.face(sid, "front", "seg")[24, 24] == names.index("building")
    # The top face's centre is sky; the back face's centre is the chair wall, which the table leaves unmapped.
    assert src.face(FIRST, "up", "seg")[24, 24] == names.index("sky")
    assert src.face(FIRST, "back", "seg")[24, 24] == 255
    rgb = src.face(FIRST, "front", "rgb")
    assert rgb.dtype == np.uint8 and tuple(rgb[24, 24]) == COLORS["building"]


def test_the_label_table_targets_the_synthetic_training_classes() -> None:
    from airfisheye_bench.synth.classes import TRAIN_CLASSES as SYNTH

    assert [(c.name, tuple(c.color)) for c in SYNTH] == [(n, tuple(c)) for n, c in TRAIN_CLASSES]
    assert set(TARTANAIR_TO_TRAIN.values()) <= {n for n, _ in TRAIN_CLASSES}
    assert train_id("Road") == 1 and train_id("treetrunk") == 8 and train_id("chair") == 255


# ------------------------------------------------------------------------------------------------ splits
def test_splits_by_trajectory(fixture_root: Path) -> None:
    src = source(fixture_root)
    assert src.trajectories("train") == ["CoalMine/easy_P000", "OldTownFall/easy_P000"]
    assert src.trajectories("val") == ["CoalMine/easy_P001", "OldTownFall/easy_P001"]
    assert src.trajectories("test") == ["CoalMine/hard_P000", "OldTownFall/hard_P000"]
    assert src.split("train")[:2] == [FIRST, "CoalMine/easy_P000/000001"]
    every = [s for name in src.split_names for s in src.split(name)]
    assert len(every) == len(set(every)) == 18
    assert src.spec.splits.by == "trajectory"
    only = source(fixture_root, environments=["OldTownFall"], frame_stride=2)
    assert only.split("train") == ["OldTownFall/easy_P000/000000", "OldTownFall/easy_P000/000002"]
    assert only.split("val") == ["OldTownFall/easy_P001/000000", "OldTownFall/easy_P001/000002"]


def test_fewer_trajectories_than_the_period_split_by_frame_blocks(
    small_download: Path, fixture_root: Path
) -> None:
    """A 3-trajectory download with split_period 10: each trajectory's frames in three contiguous blocks."""
    src = open_dataset(small_download, "tartanair")
    assert src.spec.splits.by == "frame_blocks"
    trajs = ["CoalMine/easy_P000", "CoalMine/easy_P001", "CoalMine/hard_P000"]
    blocks = {"train": ["000000", "000001", "000002"], "val": ["000003"], "test": ["000004"]}
    for name, frames in blocks.items():
        assert src.split(name) == [f"{t}/{f}" for t in trajs for f in frames], name
        assert src.trajectories(name) == trajs
    again = open_dataset(small_download, "tartanair")
    assert all(again.split(name) == src.split(name) for name in blocks)  # deterministic
    six = open_dataset(fixture_root, "tartanair")  # 6 trajectories of 3 frames: one frame per split in each
    assert [len(six.split(name)) for name in blocks] == [6, 6, 6]
    assert six.split("test")[:2] == ["CoalMine/easy_P000/000002", "CoalMine/easy_P001/000002"]
    strided = open_dataset(
        small_download, "tartanair", {"frame_stride": 3}
    )  # 2 frames a trajectory: all train
    assert len(strided.split("train")) == 6 and strided.split("val") == strided.split("test") == []
    assert "at least 3 frames" in strided.split_rule("val")


# ------------------------------------------------------------------------------------- calibration, poses
def test_calibration_and_frames(fixture_root: Path) -> None:
    src = source(fixture_root)
    calib = src.calib(FIRST)
    assert calib.face_size == SIZE and src.spec.face_size == SIZE
    camera = calib.fisheye_camera()
    assert (camera.width, camera.model, camera.fov_deg) == (2 * SIZE, "equidistant", 190.0)
    # Camera forward (z) is body forward (FLU x); the LiDAR is the body frame; same instant, no motion.
    assert np.allclose(calib.T_body_cam[:3, :3] @ [0, 0, 1], [1, 0, 0])
    assert np.allclose(src.T_cam_lidar(FIRST), calib.T_cam_lidar_static)
    assert calib.lidar_spec().channels == 16 and calib.lidar_spec().points_per_channel == 3600


def test_pose_file_is_ned_with_xyzw_quaternions(fixture_root: Path) -> None:
    """Frame 1 of the fixture: 1 m north, 2 m up (z = -2), yawed 10 degrees (quaternion 0 0 sin5 cos5)."""
    T = source(fixture_root).T_world_cam("CoalMine/easy_P000/000001")
    yaw = np.radians(10.0)
    assert np.allclose(T[:3, 3], [1.0, 0.0, -2.0])
    assert np.allclose(T[:3, 2], [np.cos(yaw), np.sin(yaw), 0.0], atol=1e-6)  # looks north-east of north
    assert np.allclose(T[:3, 1], [0.0, 0.0, 1.0], atol=1e-6)  # image down is world down


# ------------------------------------------------------------------------------------------------ LiDAR
@pytest.mark.parametrize("frame", ["flu", "ned", "camera"])
def test_the_dataset_lidar_is_turned_to_flu_whatever_axes_the_file_uses(tmp_path: Path, frame: str) -> None:
    root = write_tartanair_fixture(tmp_path / "root", size=SIZE, frames=1, lidar_frame=frame)
    src = source(root)
    agreement = src.lidar_agreement(FIRST)
    assert max(agreement, key=agreement.get) == frame and agreement[frame] > 0.9
    points = src.lidar_scan(FIRST).points
    # The beam at azimuth 0, elevation +1 deg meets the building wall 8 m ahead: FLU (8, 0, 8 tan 1deg).
    assert np.min(np.linalg.norm(points - [8.0, 0.0, 8.0 * np.tan(np.radians(1.0))], axis=1)) < 1e-3
    elevations = np.degrees(np.arcsin(points[:, 2] / np.linalg.norm(points, axis=1)))
    assert np.allclose(np.unique(np.round(elevations, 3)), np.arange(-15, 16, 2), atol=1e-3)


def test_a_preset_lidar_is_cast_into_the_six_depth_faces(fixture_root: Path) -> None:
    """``data.lidar.preset``: the dataset asks for ``cast_scan`` with that sensor instead of the recorded scan."""
    src = source(fixture_root)
    scan = src.cast_scan(FIRST, LidarSpec.from_preset("vlp16"))
    assert src.calib(FIRST).lidar_spec().name == "tartanair-vlp16" and scan.rings is not None
    expected, _ = scene_hit(
        scan.points @ CAM_FROM_FLU.T, 0
    )  # the analytic scene along each point's direction
    close = np.abs(np.linalg.norm(scan.points, axis=1) - expected) <= 0.05 * expected
    assert close.mean() > 0.9
    wall = np.abs(scan.points[:, 0] + 5.0) < 0.05  # the back face is used too: the chair wall 5 m behind
    assert wall.sum() > 100 and scan.points[:, 0].min() > -5.3


def test_the_deprecated_lidar_option_casts_its_preset_as_before_and_says_so(fixture_root: Path) -> None:
    """``format_options.lidar=<preset>`` keeps working for one release: the source's own sensor becomes that preset
    (the scan ``data.lidar.preset`` casts), with a warning naming the new key; ``dataset`` is the default."""
    with pytest.warns(
        DeprecationWarning, match=r"format_options\.lidar=vlp16 .*use data\.lidar\.preset=vlp16"
    ):
        legacy = source(fixture_root, lidar="vlp16")
    cast = source(fixture_root).cast_scan(FIRST, LidarSpec.from_preset("vlp16"))
    np.testing.assert_array_equal(legacy.lidar_scan(FIRST).points, cast.points)
    assert legacy.calib(FIRST).lidar_spec().name == "vlp16"
    with pytest.warns(DeprecationWarning, match=r"use data\.lidar\.preset=null"):
        own = source(fixture_root, lidar="dataset")
    np.testing.assert_array_equal(own.lidar_scan(FIRST).points, source(fixture_root).lidar_scan(FIRST).points)


def test_the_deprecated_lidar_option_beside_another_preset_is_refused_naming_both_keys(
    fixture_root: Path,
) -> None:
    from airfisheye_bench.errors import ConfigError
    from datamodules import AirFisheyeDataModule

    def datamodule(lidar: str, preset: str | None) -> AirFisheyeDataModule:
        options = {"split_period": 3, "lidar": lidar}
        return AirFisheyeDataModule(
            "completion",
            root=fixture_root,
            format="tartanair",
            format_options=options,
            lidar={"preset": preset},
        )

    for lidar, preset in (("hdl64e", "vlp16"), ("dataset", "vlp16")):
        with pytest.raises(
            ConfigError, match=r"data\.format_options\.lidar=.* and data\.lidar\.preset='vlp16'"
        ):
            datamodule(lidar, preset)
    # The same LiDAR twice, or the option alone, is the deprecated spelling of data.lidar.preset.
    assert datamodule("vlp16", "vlp16").lidar.spec.name == "vlp16"
    assert datamodule("hdl64e", None).lidar.spec is None


def test_cast_lidar_helpers_hand_values() -> None:
    faces = np.full((6, 8, 8), 4.0, np.float32)  # a cube room, walls 4 m from the centre
    assert sample_range(np.array([[1.0, 1.0, 0.0]]), faces)[0] == pytest.approx(4 * np.sqrt(2))
    spec = LidarSpec(channels=2, points_per_channel=4, hfov_deg=360.0, vfov_deg=(0.0, 45.0))
    points, rings = lidar_from_faces(faces, spec)
    assert np.allclose(np.abs(points).max(axis=1), 4.0) and rings.tolist() == [0] * 4 + [1] * 4


# ------------------------------------------------------------------------------------------------ errors
def test_missing_files_name_the_file(writable_root: Path) -> None:
    traj = writable_root / "CoalMine" / "Data_easy" / "P000"
    (traj / "seg_lcam_bottom" / "000000_lcam_bottom_seg.png").unlink()
    (traj / "lidar" / "000001_lcam_front_lidar.ply").unlink()
    (writable_root / "OldTownFall" / "seg_label_map.json").unlink()
    src = source(writable_root)
    with pytest.raises(DatasetFormatError, match=r"000000_lcam_bottom_seg.png: missing"):
        src.cubemap(FIRST, "seg")
    with pytest.raises(DatasetFormatError, match=r"000001_lcam_front_lidar.ply: missing"):
        src.lidar_scan("CoalMine/easy_P000/000001")
    with pytest.raises(DatasetFormatError, match=r"seg_label_map.json: missing"):
        src.cubemap("OldTownFall/easy_P000/000000", "seg")


def test_bad_files_and_options(writable_root: Path, tmp_path: Path) -> None:
    traj = writable_root / "CoalMine" / "Data_easy" / "P000"
    Image.fromarray(np.zeros((SIZE, SIZE, 3), np.uint8)).save(
        traj / "depth_lcam_left" / "000001_lcam_left_depth.png"
    )
    src = source(writable_root)
    with pytest.raises(DatasetFormatError, match=r"000001_lcam_left_depth.png: expected an 8-bit RGBA PNG"):
        src.cubemap("CoalMine/easy_P000/000001", "depth")
    # A scan that matches the depth in no frame is refused, naming the file and the shares.
    ply = traj / "lidar" / "000000_lcam_front_lidar.ply"
    body = np.random.default_rng(1).uniform(-50, 50, (100, 3)).astype("<f4")
    header = b"ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\nproperty float y\n"
    ply.write_bytes(header + b"property float z\nend_header\n" + body.tobytes())
    with pytest.raises(
        DatasetFormatError, match=r"000000_lcam_front_lidar.ply: the points match the depth faces"
    ):
        src.lidar_scan(FIRST)
    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetFormatError, match="no TartanAir V2 trajectory"):
        source(tmp_path / "empty")
    with pytest.raises(DatasetFormatError, match="environments: no folder"):
        source(writable_root, environments=["Atlantis"])
    with pytest.raises(ValueError, match="lidar: expected dataset or one of"):
        source(writable_root, lidar="vlp17")
    with pytest.raises(ValueError, match="unknown keys"):
        source(writable_root, camera="rcam")
    with pytest.raises(DatasetFormatError, match="TartanAir V2 is read from its cube faces"):
        src.fisheye(FIRST, "rgb")


# ------------------------------------------------------------------------------------------- end to end
# depth reads what completion reads (the image, the dense depth) and trains AdaBins, which the tiny runs cover: slow
@pytest.mark.integration
@pytest.mark.parametrize("task", ["seg", pytest.param("depth", marks=pytest.mark.slow), "completion"])
def test_train_runs_every_task_on_tartanair(task: str, fixture_root: Path, tmp_path: Path) -> None:
    """``python train.py task=<task> data=tartanair data.root=<fixture> trainer=debug ...`` writes its metrics."""
    from airfisheye_bench.training import train
    from tests.helpers.configs import compose_train
    from tests.helpers.runs import tiny_run_overrides

    overrides = tiny_run_overrides(task, fixture_root, size=64 if task == "depth" else 32)  # AdaBins needs 64
    cfg = compose_train([*overrides, "data=tartanair", "data.format_options.split_period=3", "logger=csv"])
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    results = train(cfg)
    record = json.loads((tmp_path / "results.json").read_text())
    primary = cfg.task.primary_metric
    assert record["task"] == task and record["split"] == "test"
    assert np.isfinite(record["metrics"][primary])
    assert record["metrics"][primary] == pytest.approx(results["metrics"][primary])


@pytest.mark.integration
def test_train_seg_on_a_three_trajectory_download(small_download: Path, tmp_path: Path) -> None:
    """``python train.py task=seg data=tartanair data.root=<3 trajectories>`` with the default split_period."""
    from airfisheye_bench.training import train
    from tests.helpers.configs import compose_train
    from tests.helpers.runs import tiny_run_overrides

    cfg = compose_train([*tiny_run_overrides("seg", small_download, size=32), "data=tartanair", "logger=csv"])
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    results = train(cfg)
    record = json.loads((tmp_path / "results.json").read_text())
    assert record["split"] == "test" and np.isfinite(record["metrics"]["mIoU"])
    assert record["metrics"]["mIoU"] == pytest.approx(results["metrics"]["mIoU"])


@pytest.mark.integration
def test_an_empty_split_is_one_line(small_download: Path, tmp_path: Path) -> None:
    """Trajectories of 2 frames (every 3rd of 5) leave val empty: one line naming the root, the split, the rule."""
    from tests.helpers.commands import TRAIN, assert_one_line_error, run_in_process

    args = [
        "task=seg",
        "data=tartanair",
        f"data.root={small_download}",
        "data.format_options.frame_stride=3",
        "trainer=debug",
        f"hydra.run.dir={tmp_path}",
    ]
    outcome = run_in_process(TRAIN, args)
    assert_one_line_error(outcome, str(small_download), "split 'val' is empty", "at least 3 frames")
    assert not (tmp_path / "results.json").exists()


@pytest.mark.integration
def test_the_command_line_names_a_root_without_trajectories(tmp_path: Path) -> None:
    from tests.helpers.commands import TRAIN, run_in_process

    (tmp_path / "empty").mkdir()
    args = [
        "task=seg",
        "data=tartanair",
        f"data.root={tmp_path / 'empty'}",
        f"hydra.run.dir={tmp_path / 'run'}",
    ]
    done = run_in_process(TRAIN, args)
    assert done.returncode == 2, done.stderr
    assert "no TartanAir V2 trajectory" in done.stderr and "Traceback" not in done.stderr


def test_the_config_lists_every_option_with_its_default() -> None:
    from tests.helpers.configs import compose_train

    cfg = compose_train(["task=seg", "data=tartanair"])
    assert cfg.data.format == "tartanair" and cfg.data.root is None
    assert dict(cfg.data.format_options) == TartanAirSource.OPTIONS


def test_design_md_prints_the_label_table_of_the_code() -> None:
    text = (Path(__file__).resolve().parents[3] / "docs" / "design.md").read_text(encoding="utf-8")
    section = text.split("### TartanAir V2", 1)[1].split("\n## ", 1)[0]
    for i, (name, _) in enumerate(TRAIN_CLASSES):
        names = ", ".join(f"`{n}`" for n, t in TARTANAIR_TO_TRAIN.items() if t == name)
        assert f"| {i} | {name} | {names} |" in section, name


def _completion(root: Path, preset: str | None = None, **options) -> AirFisheyeDataset:
    """The ``train`` split for completion at 128^2, its LiDAR ``data.lidar.preset=preset``."""
    from datamodules import AirFisheyeDataset, CameraConfig

    return AirFisheyeDataset.from_root(
        root,
        "train",
        "completion",
        camera=CameraConfig(size=128),
        format="tartanair",
        format_options={"split_period": 3, **options},
        lidar_spec=None if preset is None else LidarSpec.from_preset(preset),
    )


@pytest.mark.parametrize("preset", [None, "hdl64e"])
def test_sparse_depth_lands_on_the_dense_depth(fixture_root: Path, preset: str | None) -> None:
    """The whole chain (PLY axes or the cast beams of data.lidar.preset, T_cam_lidar, projection, occlusion): LiDAR
    ranges agree with the remapped depth at the pixels they land on."""
    sample = _completion(fixture_root, preset)[0]
    sparse, dense = sample["sparse_depth"][0], sample["depth"][0]
    hit = (sparse > 0) & (dense > 0)
    assert hit.sum() > 200
    rel = ((sparse[hit] - dense[hit]).abs() / dense[hit]).numpy()
    assert np.median(rel) < 0.02 and np.mean(rel < 0.1) > 0.9


def test_the_deprecated_lidar_option_serves_what_data_lidar_preset_serves(fixture_root: Path) -> None:
    """``format_options.lidar=hdl64e`` (deprecated) and ``data.lidar.preset=hdl64e`` serve the same sparse input."""
    with pytest.warns(DeprecationWarning):
        legacy = _completion(fixture_root, lidar="hdl64e")[0]["sparse_depth"]
    served = _completion(fixture_root, "hdl64e")[0]["sparse_depth"]
    assert (served > 0).sum() > 200 and torch.equal(legacy, served)
