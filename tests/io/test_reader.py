"""DatasetReader on a generated dataset, and on a release whose dataset.yaml changes the path layout."""

from __future__ import annotations

import pathlib
import pickle
import shutil

import numpy as np
import pytest
import yaml

from airfisheye_bench.geometry.transforms import invert_rigid
from airfisheye_bench.io import DatasetFormatError, DatasetReader, DatasetSpec
from airfisheye_bench.io.layout import DatasetLayout


def test_reader_samples_and_motion_compensation(tiny_dataset):
    reader = DatasetReader(tiny_dataset)
    sid = reader.split("train")[1]
    poses, calib = reader.poses(sid), reader.calib(sid)
    i = poses.index(sid.rsplit("/", 1)[1])
    expected = (
        invert_rigid(poses.T_world_body_cam[i] @ calib.T_body_cam)
        @ poses.T_world_body_lidar[i]
        @ calib.T_body_lidar
    )
    assert np.allclose(reader.T_cam_lidar(sid), expected, atol=1e-12)
    # The drone moved between t_cam and t_lidar: the compensated transform differs from the static one.
    assert np.linalg.norm(reader.T_cam_lidar(sid)[:3, 3] - calib.T_cam_lidar_static[:3, 3]) > 0.01
    lut = reader.spec.label_lut()
    train = lut[reader.fisheye(sid, "seg")]
    assert train.max() == 255 and train[train != 255].max() < reader.spec.num_train_classes
    clone = pickle.loads(pickle.dumps(reader))  # DataLoader workers receive a pickled reader
    assert np.array_equal(clone.lidar(sid), reader.lidar(sid))
    with pytest.raises(ValueError, match="split must be one of"):
        reader.split("holdout")


def test_layout_templates_come_from_dataset_yaml(tiny_dataset, tmp_path):
    """A release with another folder structure is read by changing dataset.yaml only."""
    root = tmp_path / "release"
    shutil.copytree(tiny_dataset, root)
    spec = DatasetSpec.load(root)
    old = DatasetLayout(root, spec.layout, spec.files)
    data = yaml.safe_load((root / "dataset.yaml").read_text())
    data["layout"]["lidar"] = "scans/{env}-{traj}/{frame}.npy"
    (root / "dataset.yaml").write_text(yaml.safe_dump(data))
    reader = DatasetReader(root)
    sid = reader.split("test")[0]
    new_path = reader.layout.lidar(sid)
    assert new_path.parent.parent.name == "scans"
    new_path.parent.mkdir(parents=True)
    shutil.move(old.lidar(sid), new_path)
    assert reader.lidar(sid).shape[1] == 4
    with pytest.raises(DatasetFormatError, match="does not exist"):
        reader.lidar(reader.split("train")[0])  # not moved


def test_format_errors_cross_process_boundaries() -> None:
    """Worker pools pickle exceptions: the path, key and message must survive."""
    err = pickle.loads(
        pickle.dumps(DatasetFormatError("/data/a/calib.yaml", "must be a mapping", key="camera"))
    )
    assert (err.path, err.key, err.message) == (
        pathlib.Path("/data/a/calib.yaml"),
        "camera",
        "must be a mapping",
    )
    assert str(err) == "/data/a/calib.yaml: key 'camera': must be a mapping"
