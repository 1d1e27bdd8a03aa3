"""dataset.yaml, calib.yaml, poses.csv, imu.csv and split files: round trips, motion compensation, clear errors."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from airfisheye_bench.geometry.transforms import (
    euler_to_matrix,
    invert_rigid,
    make_transform,
    transform_points,
)
from airfisheye_bench.io import (
    Calibration,
    ClassDef,
    DatasetFormatError,
    DatasetSpec,
    ImuTable,
    PoseTable,
    SplitsSpec,
    camera_from_lidar,
    read_split,
    write_split,
)


def _spec(**kw) -> DatasetSpec:
    base = dict(
        name="toy",
        raw_classes=(
            ClassDef(0, "sky", (70, 130, 180)),
            ClassDef(1, "road", (128, 64, 128)),
            ClassDef(2, "car", (0, 0, 142)),
        ),
        train_classes=(ClassDef(0, "sky", (70, 130, 180)), ClassDef(1, "ground", (128, 64, 128))),
        raw_to_train={0: 0, 1: 1},
        splits=SplitsSpec(
            files={"train": "splits/train.txt", "val": "splits/val.txt"}, locations={"a/t0": "train"}
        ),
        sensors={"cubemap": {"face_size": 32}},
        contents=("cubemap", "lidar"),
    )
    base.update(kw)
    return DatasetSpec(**base)


def test_spec_round_trip_and_lut(tmp_path):
    spec = _spec()
    spec.save(tmp_path)
    back = DatasetSpec.load(tmp_path / "dataset.yaml")
    assert back == spec
    lut = back.label_lut()
    assert lut[[0, 1, 2, 255]].tolist() == [0, 1, 255, 255]  # unmapped raw class -> ignore
    assert back.face_size == 32 and back.has("lidar") and not back.has("fisheye")


@pytest.mark.parametrize(
    ("mutate", "key"),
    [
        (lambda d: d["classes"]["raw"][1].update(color=[1, 2]), "classes.raw[1].color"),
        (lambda d: d["classes"]["raw"][1].pop("name"), "classes.raw[1].name"),
        (lambda d: d["classes"]["train"][1].update(id=5), "classes.train"),
        (lambda d: d["classes"]["raw_to_train"].update({7: 0}), "classes.raw_to_train.7"),
        (lambda d: d["classes"]["raw_to_train"].update({2: 9}), "classes.raw_to_train.2"),
        (lambda d: d["files"].update(depth="exr"), "files.depth"),
        (lambda d: d["layout"].update(lidar="{env}/{traj}/{bogus}.npy"), "layout.lidar"),
        (lambda d: d["splits"]["locations"].update({"a/t1": "holdout"}), "splits.locations.a/t1"),
        (lambda d: d.pop("name"), "name"),
        (lambda d: d["contents"].append("radar"), "contents[2]"),
        (lambda d: d.update(format_version=99), "format_version"),
    ],
)
def test_spec_errors_name_file_and_key(tmp_path, mutate, key):
    data = _spec().to_dict()
    mutate(data)
    path = tmp_path / "dataset.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(DatasetFormatError) as err:
        DatasetSpec.load(tmp_path)
    assert err.value.key == key
    assert str(path) in str(err.value) and key in str(err.value)


def test_spec_rejects_non_mapping_yaml(tmp_path):
    (tmp_path / "dataset.yaml").write_text("- just\n- a list\n")
    with pytest.raises(DatasetFormatError, match="top level must be a mapping"):
        DatasetSpec.load(tmp_path)


def _calib() -> Calibration:
    T_bc = make_transform(euler_to_matrix(0.0, 0.3, 0.0), np.array([0.1, 0.0, -0.1]))
    T_bl = make_transform(euler_to_matrix(0.0, 0.3, 0.0), np.array([0.0, 0.1, 0.2]))
    cam = {"model": "equidistant", "width": 64, "height": 64, "fov_deg": 190.0}
    return Calibration(
        cam, 32, T_bc, T_bl, {"channels": 16, "points_per_channel": 64}, {"gimbal_pitch_deg": 17.2}
    )


def test_calib_round_trip(tmp_path):
    calib = _calib()
    calib.save(tmp_path / "calib.yaml")
    back = Calibration.load(tmp_path / "calib.yaml")
    assert back.face_size == 32 and back.camera == calib.camera and back.extras == {"gimbal_pitch_deg": 17.2}
    assert np.allclose(back.T_body_cam, calib.T_body_cam, atol=0, rtol=0)
    assert back.fisheye_camera().width == 64 and back.lidar_spec().channels == 16


def test_calib_rejects_non_rigid_extrinsics(tmp_path):
    data = _calib().to_dict()
    data["T_body_lidar"][0][0] = 2.0
    (tmp_path / "calib.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(DatasetFormatError, match=r"calib\.yaml: key 'T_body_lidar'.*not rigid"):
        Calibration.load(tmp_path / "calib.yaml")


def test_calib_rejects_bad_sensor_models(tmp_path):
    data = _calib().to_dict()
    data["camera"]["fov_deg"] = -5.0
    (tmp_path / "calib.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(DatasetFormatError, match=r"key 'camera': invalid description"):
        Calibration.load(tmp_path / "calib.yaml")
    data = _calib().to_dict()
    data["lidar"]["beams"] = 3
    (tmp_path / "calib.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(DatasetFormatError, match=r"key 'lidar': invalid description.*beams"):
        Calibration.load(tmp_path / "calib.yaml")


def _random_pose(rng) -> np.ndarray:
    return make_transform(euler_to_matrix(*rng.uniform(-np.pi, np.pi, 3)), rng.uniform(-50, 50, 3))


def test_poses_round_trip_and_motion_compensation(tmp_path):
    rng = np.random.default_rng(3)
    n = 4
    T_cam = np.stack([_random_pose(rng) for _ in range(n)])
    T_lid = np.stack([_random_pose(rng) for _ in range(n)])
    table = PoseTable(
        [f"{i:06d}" for i in range(n)], np.arange(n) * 0.1, T_cam, np.arange(n) * 0.1 + 0.03, T_lid
    )
    table.save(tmp_path / "poses.csv")
    back = PoseTable.load(tmp_path / "poses.csv")
    assert back.frames == table.frames and np.allclose(back.t_lidar, table.t_lidar)
    assert np.abs(back.T_world_body_cam - T_cam).max() < 1e-8
    calib = _calib()
    T_cam_lidar = camera_from_lidar(back, calib.T_body_cam, calib.T_body_lidar)
    # Independent check: a LiDAR point goes to the world through the LiDAR-time pose, then into the camera
    # through the camera-time pose.
    p_lidar = rng.normal(size=(10, 3)) * 20
    for i in range(n):
        world = transform_points(T_lid[i] @ calib.T_body_lidar, p_lidar)
        expected = transform_points(invert_rigid(T_cam[i] @ calib.T_body_cam), world)
        assert np.abs(transform_points(T_cam_lidar[i], p_lidar) - expected).max() < 1e-6


def test_poses_errors_name_line(tmp_path):
    path = tmp_path / "poses.csv"
    rng = np.random.default_rng(0)
    T = np.stack([_random_pose(rng)])
    PoseTable(["000000"], np.zeros(1), T, np.zeros(1), T).save(path)
    path.write_text(path.read_text() + "000001,0.1,1,2\n")
    with pytest.raises(DatasetFormatError, match=r"poses\.csv: key 'line 3': expected 17 columns"):
        PoseTable.load(path)
    path.write_text("frame,t\n")
    with pytest.raises(DatasetFormatError, match="header"):
        PoseTable.load(path)


def test_imu_round_trip(tmp_path):
    t = np.arange(5) * 0.01
    imu = ImuTable(t, np.tile([0.1, -0.2, 9.81], (5, 1)), np.tile([0.01, 0.02, -0.03], (5, 1)))
    imu.save(tmp_path / "imu.csv")
    back = ImuTable.load(tmp_path / "imu.csv")
    assert back.rate_hz == 100.0 and np.allclose(back.accel, imu.accel) and np.allclose(back.gyro, imu.gyro)
    with pytest.raises(ValueError, match="strictly increasing"):
        ImuTable(t[::-1], imu.accel, imu.gyro)


def test_split_round_trip_and_errors(tmp_path):
    ids = ["a/t0/000000", "a/t0/000001", "b/t3/000010"]
    write_split(tmp_path / "train.txt", ids)
    assert read_split(tmp_path / "train.txt") == ids
    (tmp_path / "bad.txt").write_text("a/t0/000000\na/t0\n")
    with pytest.raises(DatasetFormatError, match=r"bad\.txt: key 'line 2'"):
        read_split(tmp_path / "bad.txt")
    (tmp_path / "dup.txt").write_text("a/t0/000000\na/t0/000000\n")
    with pytest.raises(DatasetFormatError, match="duplicate"):
        read_split(tmp_path / "dup.txt")
