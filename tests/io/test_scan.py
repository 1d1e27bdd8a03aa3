"""LiDAR scan files: every reader against files written in the format's own layout, and one error per bad file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from airfisheye_bench import io
from airfisheye_bench.cli.commands import inspect
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.inspect_scans import inspect_scans
from airfisheye_bench.io.scan import Scan, load_scan, write_pcd, write_ply
from tests.helpers.commands import run_command

RNG = np.random.default_rng(0)
POINTS = RNG.uniform(-20.0, 20.0, (50, 3)).astype(np.float32).astype(np.float64)
INTENSITY = RNG.uniform(0.0, 1.0, 50).astype(np.float32)
RINGS = RNG.integers(0, 32, 50)


def test_kitti_bin(tmp_path: Path) -> None:
    path = tmp_path / "000000.bin"
    np.column_stack([POINTS, INTENSITY]).astype(np.float32).tofile(path)
    scan = load_scan(path)
    np.testing.assert_array_equal(scan.points, POINTS)
    np.testing.assert_array_equal(scan.intensity, INTENSITY)
    assert scan.rings is None and scan.firing_order and scan.format == "kitti_bin"


def test_nuscenes_pcd_bin_turns_the_frame_and_keeps_the_rings(tmp_path: Path) -> None:
    path = tmp_path / "n008__LIDAR_TOP__1533151603547590.pcd.bin"
    x_right, y_forward = -POINTS[:, 1], POINTS[:, 0]  # nuScenes LIDAR_TOP: x right, y forward, z up
    np.column_stack([x_right, y_forward, POINTS[:, 2], INTENSITY, RINGS]).astype(np.float32).tofile(path)
    scan = load_scan(path)
    np.testing.assert_allclose(scan.points, POINTS, atol=1e-6)
    assert np.array_equal(scan.rings, RINGS) and not scan.firing_order


@pytest.mark.parametrize("binary", [True, False])
@pytest.mark.parametrize("with_ring", [True, False])
def test_pcd(tmp_path: Path, binary: bool, with_ring: bool) -> None:
    path = tmp_path / "cloud.pcd"
    write_pcd(path, POINTS, INTENSITY, RINGS if with_ring else None, binary=binary)
    scan = load_scan(path)
    np.testing.assert_allclose(scan.points, POINTS, atol=1e-5)
    np.testing.assert_allclose(scan.intensity, INTENSITY, atol=1e-6)
    assert (scan.rings is not None) == with_ring and (not with_ring or np.array_equal(scan.rings, RINGS))


def test_pcd_as_a_driver_writes_it(tmp_path: Path) -> None:
    """A ROS Velodyne driver's PointXYZIR with padding, a time field and a VIEWPOINT: the padding and time are
    ignored, the viewpoint (the sensor at (1, 2, 0), turned 90 deg about z) is undone."""
    n = len(POINTS)
    rec = np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("_", "<f4"), ("intensity", "<f4"),
                             ("ring", "<u2"), ("time", "<f4")])  # fmt: skip
    turned = np.column_stack([-POINTS[:, 1], POINTS[:, 0], POINTS[:, 2]]) + np.array([1.0, 2.0, 0.0])
    rec["x"], rec["y"], rec["z"] = turned.T
    rec["intensity"], rec["ring"] = INTENSITY, RINGS
    c = np.sqrt(0.5)
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z _ intensity ring time\n"
        "SIZE 4 4 4 4 4 2 4\nTYPE F F F F F U F\nCOUNT 1 1 1 1 1 1 1\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 1 2 0 {c} 0 0 {c}\nPOINTS {n}\nDATA binary\n"
    )
    path = tmp_path / "driver.pcd"
    path.write_bytes(header.encode() + rec.tobytes())
    scan = load_scan(path)
    np.testing.assert_allclose(scan.points, POINTS, atol=1e-4)
    assert np.array_equal(scan.rings, RINGS)


def test_an_organised_pcd_drops_and_counts_its_empty_cells(tmp_path: Path) -> None:
    grid = POINTS.copy()
    grid[::5] = np.nan
    grid[1::7] = 0.0
    path = tmp_path / "ouster.pcd"
    write_pcd(path, grid, height=5)
    scan = load_scan(path)
    empty = np.isnan(grid).any(axis=1) | ~grid.any(axis=1)
    assert scan.no_returns == int(empty.sum()) > 0 and len(scan.points) == int((~empty).sum())


@pytest.mark.parametrize("binary", [True, False])
def test_ply(tmp_path: Path, binary: bool) -> None:
    path = tmp_path / "scan.ply"
    write_ply(path, POINTS, INTENSITY, RINGS, binary=binary)
    scan = load_scan(path)
    np.testing.assert_allclose(scan.points, POINTS, atol=1e-5)
    assert np.array_equal(scan.rings, RINGS) and scan.format == "ply"


def test_npy_and_npz(tmp_path: Path) -> None:
    np.save(tmp_path / "a.npy", np.column_stack([POINTS, INTENSITY, RINGS]))
    scan = load_scan(tmp_path / "a.npy")
    assert np.array_equal(scan.rings, RINGS) and np.allclose(scan.intensity, INTENSITY)
    np.save(tmp_path / "grid.npy", np.full((4, 8, 3), np.nan))
    assert load_scan(tmp_path / "grid.npy").no_returns == 32
    np.savez(tmp_path / "b.npz", points=POINTS, intensity=INTENSITY, ring=RINGS)
    scan = load_scan(tmp_path / "b.npz")
    assert np.array_equal(scan.points, POINTS) and np.array_equal(scan.rings, RINGS)


def _bad_files(tmp: Path) -> dict[str, tuple[Path, str]]:
    out = {}
    p = tmp / "short.bin"
    p.write_bytes(b"\0" * 20)  # 20 bytes: not float32 x 4
    out["size"] = (p, "not a whole number of KITTI")
    p = tmp / "nan.bin"
    np.array([[1.0, np.nan, 0.0, 0.0]], dtype=np.float32).tofile(p)
    out["nan"] = (p, "NaN or infinite")
    p = tmp / "field.pcd"
    write_pcd(p, POINTS)
    p.write_bytes(p.read_bytes().replace(b"FIELDS x y z", b"FIELDS x y w"))
    out["unknown field"] = (p, "unknown field 'w'")
    p = tmp / "cut.pcd"
    write_pcd(p, POINTS, INTENSITY)
    p.write_bytes(p.read_bytes()[:-7])
    out["pcd size"] = (p, "bytes of binary data for 50 points")
    p = tmp / "keys.npz"
    np.savez(p, points=POINTS, colour=INTENSITY)
    out["npz field"] = (p, "unknown field 'colour'")
    p = tmp / "scan.las"
    p.write_bytes(b"LASF")
    out["suffix"] = (p, "not a LiDAR scan file")
    return out


def test_a_bad_file_is_one_error_naming_it(tmp_path: Path) -> None:
    for name, (path, message) in _bad_files(tmp_path).items():
        with pytest.raises(DatasetFormatError) as info:
            load_scan(path)
        assert str(path) in str(info.value) and message in str(info.value), name


def test_load_scan_is_exported_by_the_io_package(tmp_path: Path) -> None:
    """``from airfisheye_bench.io import load_scan`` in a fresh interpreter (an import cycle would show only there)."""
    path = tmp_path / "000000.bin"
    np.column_stack([POINTS, INTENSITY]).astype(np.float32).tofile(path)
    code = f"from airfisheye_bench.io import Scan, load_scan; print(len(load_scan({str(path)!r}).points))"
    done = run_command("-c", [code])
    assert done.returncode == 0 and done.stdout.split() == ["50"], done.stderr[-2000:]
    assert io.load_scan is load_scan and io.Scan is Scan


def test_inspect_a_folder_of_kitti_scans(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from airfisheye_bench.geometry.lidar import LidarSpec
    from tests.geometry.real_scans import simulate

    spec = LidarSpec.from_preset("hdl64e", points_per_channel=512)
    for seed in range(2):
        points, _ = simulate(spec, seed, order="kitti", self_hits=300)
        np.column_stack([points, np.zeros(len(points))]).astype(np.float32).tofile(
            tmp_path / f"{seed:06d}.bin"
        )
    report = inspect_scans(tmp_path, lidar="hdl64e")
    assert report.ok and len(report.scans) == 2
    assert all(s.ring_source == "firing_order" and s.near_origin > 200 for s in report.scans)
    assert all((s.per_ring > 0).sum() >= 60 for s in report.scans)
    assert inspect([f"root={tmp_path}", "lidar=hdl64e"]) == 0
    out = capsys.readouterr().out
    assert "rings from firing_order" in out and "within min_range" in out
    (tmp_path / "000009.bin").write_bytes(b"\0" * 20)
    assert inspect([f"root={tmp_path}", "lidar=hdl64e"]) == 1
    assert "000009.bin" in capsys.readouterr().out
    assert json.dumps(report.scans[0].line())  # a plain one-line summary


def test_a_release_whose_lidar_files_are_kitti_scans(tiny_dataset: Path, tmp_path: Path) -> None:
    """``layout.lidar`` may name real scan files: the same points as KITTI ``.bin`` (re-stored in KITTI's firing
    order, no ring field) serve the same sparse depth as the layout's own ``.npy``, and so do they in the
    generator's own order."""
    import shutil

    import yaml

    from airfisheye_bench.geometry.lidar import spherical_coordinates
    from airfisheye_bench.geometry.lidar_layout import rings_from_elevation
    from airfisheye_bench.io import DatasetReader
    from datamodules.dataset import AirFisheyeDataset

    root = tmp_path / "kitti_style"
    shutil.copytree(tiny_dataset, root)
    meta = yaml.safe_load((root / "dataset.yaml").read_text())
    meta.setdefault("layout", {})["lidar"] = "{env}/{traj}/velodyne/{frame}.bin"
    (root / "dataset.yaml").write_text(yaml.safe_dump(meta))
    original = DatasetReader(tiny_dataset)
    for npy in sorted(root.rglob("lidar/*.npy")):
        data = np.load(npy)
        r, _, el = spherical_coordinates(data[:, :3].astype(np.float64))
        channel = rings_from_elevation(
            r, el, original.calib("suburban/traj00").lidar_spec()
        )  # uniform: exact
        az = np.remainder(np.arctan2(data[:, 1], data[:, 0]), 2 * np.pi)  # from azimuth 0, round once
        kitti_order = np.lexsort((az, -channel))  # top laser first
        out = npy.parent.parent / "velodyne" / (npy.stem + ".bin")
        out.parent.mkdir(exist_ok=True)
        np.column_stack([data[kitti_order, :3], np.zeros(len(data))]).astype(np.float32).tofile(out)
    kitti = AirFisheyeDataset(root, "test", "completion", source="fisheye", augment=None)
    own = AirFisheyeDataset(tiny_dataset, "test", "completion", source="fisheye", augment=None)
    sid = kitti.sample_ids[0]
    assert kitti.reader.lidar_scan(sid).format == "kitti_bin" and original.spec.has("lidar")
    assert np.array_equal(kitti[0]["sparse_depth"].numpy(), own[0]["sparse_depth"].numpy())
    assert kitti.lidar_counts["rings from firing_order"] == 1
    for path in root.rglob("velodyne/*.bin"):  # the generator's own order: lasers bottom first, from -135 deg
        npy = path.parent.parent / "lidar" / (path.stem + ".npy")
        data = np.load(npy)
        np.column_stack([data[:, :3], np.zeros(len(data))]).astype(np.float32).tofile(path)
    other = AirFisheyeDataset(root, "test", "completion", source="fisheye", augment=None)
    assert np.array_equal(other[0]["sparse_depth"].numpy(), own[0]["sparse_depth"].numpy())
    assert sum(v for k, v in other.lidar_counts.items() if k.startswith("rings from ")) == 1
