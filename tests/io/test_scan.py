"""LiDAR scan files: every reader against files written in the format's own layout, and one error per bad file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from airfisheye_bench import io
from airfisheye_bench.cli.commands import inspect
from airfisheye_bench.dataset_tools.inspect_scans import inspect_scans
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.scan import Scan, load_scan, write_pcd, write_ply
from tests.helpers.commands import run_command
from tests.helpers.pcl_files import write_pcd_binary_compressed

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


# A colour + normals + intensity + ring cloud as PCL's point types lay it out: rgb packed in a float, normals and
# curvature, a COUNT 3 field and a padding field between them.
EXTRA_FIELDS = [
    ("x", "<f4", POINTS[:, 0]),
    ("y", "<f4", POINTS[:, 1]),
    ("z", "<f4", POINTS[:, 2]),
    ("_", "<u1", np.zeros((50, 4))),
    ("rgb", "<u4", RNG.integers(0, 2**24, 50)),
    ("normal_x", "<f4", RNG.normal(size=50)),
    ("normal_y", "<f4", RNG.normal(size=50)),
    ("normal_z", "<f4", RNG.normal(size=50)),
    ("curvature", "<f4", RNG.uniform(size=50)),
    ("principal", "<f8", RNG.normal(size=(50, 3))),
    ("intensity", "<f4", INTENSITY),
    ("ring", "<u2", RINGS),
    ("time", "<f4", np.linspace(0.0, 0.1, 50)),
]


def _pcd_with_fields(path: Path, fields: list[tuple[str, str, np.ndarray]], data: str) -> None:
    """A PCD file with any fields (``(name, numpy dtype, values [N] or [N, COUNT])``), ``ascii`` or ``binary``."""
    n = len(fields[0][2])
    cols = [np.asarray(v).astype(t).reshape(n, -1) for _, t, v in fields]
    header = (
        f"VERSION 0.7\nFIELDS {' '.join(f[0] for f in fields)}\n"
        f"SIZE {' '.join(str(c.dtype.itemsize) for c in cols)}\n"
        f"TYPE {' '.join({'f': 'F', 'i': 'I', 'u': 'U'}[c.dtype.kind] for c in cols)}\n"
        f"COUNT {' '.join(str(c.shape[1]) for c in cols)}\nWIDTH {n}\nHEIGHT 1\nPOINTS {n}\nDATA {data}\n"
    )
    if data == "binary":
        rec = np.empty(
            n, dtype=[(f"f{k}", c.dtype, c.shape[1:] if c.shape[1] > 1 else ()) for k, c in enumerate(cols)]
        )
        for k, c in enumerate(cols):
            rec[f"f{k}"] = c if c.shape[1] > 1 else c[:, 0]
        body = rec.tobytes()
    else:
        body = "".join(
            " ".join(repr(v) for c in cols for v in c[i].tolist()) + "\n" for i in range(n)
        ).encode()
    path.write_bytes(header.encode() + body)


@pytest.mark.parametrize("data", ["ascii", "binary", "binary_compressed"])
def test_pcd_with_colour_normals_and_other_fields(tmp_path: Path, data: str) -> None:
    """Fields the reader does not use are skipped by their SIZE x COUNT (and left out of the compressed data
    when they are ``_`` padding, as PCL does); x y z, intensity and ring come out exact."""
    path = tmp_path / "coloured.pcd"
    if data == "binary_compressed":
        write_pcd_binary_compressed(path, EXTRA_FIELDS)
    else:
        _pcd_with_fields(path, EXTRA_FIELDS, data)
    scan = load_scan(path)
    np.testing.assert_array_equal(scan.points, POINTS)
    np.testing.assert_array_equal(scan.intensity, INTENSITY)
    np.testing.assert_array_equal(scan.rings, RINGS)


def test_pcd_binary_compressed_as_pcl_writes_it(tmp_path: Path) -> None:
    """An organised 130k-point cloud in PCL's binary_compressed layout (``pcl::PCDWriter::writeBinaryCompressed``,
    io/src/pcd_io.cpp: uint32 packed and unpacked sizes, then LZF of all x, all y, ...; the compressor is
    tests/helpers/pcl_files.py): the NaN cells are dropped and counted, the rest read back exactly."""
    rng = np.random.default_rng(1)
    n, rings = 130_048, 64
    points = rng.uniform(-50.0, 50.0, (n, 3)).astype(np.float32)
    points[rng.random(n) < 0.1] = np.nan
    ring = np.repeat(np.arange(rings), n // rings)
    intensity = rng.integers(0, 256, n).astype(np.float32)
    fields = [("x", "<f4", points[:, 0]), ("y", "<f4", points[:, 1]), ("z", "<f4", points[:, 2])]
    fields += [("intensity", "<f4", intensity), ("ring", "<u2", ring), ("t", "<f4", np.zeros(n))]
    path = tmp_path / "organised.pcd"
    write_pcd_binary_compressed(path, fields, height=rings)
    scan = load_scan(path)
    valid = ~np.isnan(points).any(axis=1)
    assert scan.no_returns == int((~valid).sum()) > 0
    np.testing.assert_array_equal(scan.points, points[valid])
    np.testing.assert_array_equal(scan.intensity, intensity[valid])
    np.testing.assert_array_equal(scan.rings, ring[valid])


@pytest.mark.parametrize("binary", [True, False])
def test_ply_with_colour_normals_and_other_properties(tmp_path: Path, binary: bool) -> None:
    """Properties of every PLY type around x y z (double here), intensity and ring; their bytes are skipped."""
    props = [
        ("double", "x", POINTS[:, 0]),
        ("uchar", "red", RNG.integers(0, 256, 50)),
        ("double", "y", POINTS[:, 1]),
        ("double", "z", POINTS[:, 2]),
        ("uint8", "green", RNG.integers(0, 256, 50)),
        ("short", "label", RNG.integers(-5, 5, 50)),
        ("float", "nx", RNG.normal(size=50)),
        ("float32", "curvature", RNG.uniform(size=50)),
        ("float", "intensity", INTENSITY),
        ("int", "segment", RNG.integers(0, 1000, 50)),
        ("ushort", "ring", RINGS),
        ("float64", "timestamp", np.linspace(0.0, 0.1, 50)),
    ]
    types = {"double": "<f8", "float64": "<f8", "float": "<f4", "float32": "<f4", "uchar": "u1"}
    types.update({"uint8": "u1", "short": "<i2", "int": "<i4", "ushort": "<u2"})
    fmt = "binary_little_endian" if binary else "ascii"
    header = f"ply\nformat {fmt} 1.0\ncomment a coloured scan\nelement vertex 50\n"
    header += "".join(f"property {t} {name}\n" for t, name, _ in props) + "end_header\n"
    if binary:
        rec = np.empty(50, dtype=[(name, types[t]) for t, name, _ in props])
        for _, name, values in props:
            rec[name] = values
        body = rec.tobytes()
    else:
        rows = zip(*(np.asarray(v).astype(types[t]).tolist() for t, _, v in props), strict=True)
        body = "".join(" ".join(repr(v) for v in row) + "\n" for row in rows).encode()
    path = tmp_path / "coloured.ply"
    path.write_bytes(header.encode() + body)
    scan = load_scan(path)
    np.testing.assert_array_equal(scan.points, POINTS)
    np.testing.assert_array_equal(scan.intensity, INTENSITY)
    np.testing.assert_array_equal(scan.rings, RINGS)


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
    out["no z field"] = (p, "no field z: a scan needs x, y and z")
    p = tmp / "packed.pcd"
    write_pcd_binary_compressed(p, EXTRA_FIELDS)
    good = p.read_bytes()
    p.write_bytes(good[:-10])
    out["pcd compressed size"] = (p, "binary_compressed sizes")
    p = tmp / "corrupt.pcd"
    data_at = good.index(b"DATA binary_compressed\n") + len(b"DATA binary_compressed\n") + 8
    p.write_bytes(
        good[:data_at] + b"\xff" + good[data_at + 1 :]
    )  # the first token: a copy from before the start
    out["pcd compressed data"] = (p, "binary_compressed data is corrupt")
    p = tmp / "cut.pcd"
    write_pcd(p, POINTS, INTENSITY)
    p.write_bytes(p.read_bytes()[:-7])
    out["pcd size"] = (p, "bytes of binary data for 50 points")
    p = tmp / "keys.npz"
    np.savez(p, points=POINTS, colour=np.zeros((50, 3)), intensity=INTENSITY[:10])
    out["npz field"] = (p, "array 'intensity' has shape (10,)")
    p = tmp / "scan.las"
    p.write_bytes(b"LASF")
    out["suffix"] = (p, "not a LiDAR scan file")
    return out


def test_a_bad_file_is_one_error_naming_it(tmp_path: Path) -> None:
    for name, (path, message) in _bad_files(tmp_path).items():
        with pytest.raises(DatasetFormatError) as info:
            load_scan(path)
        assert str(path) in str(info.value) and message in str(info.value), name


@pytest.mark.integration  # a fresh interpreter
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
    from airfisheye_bench.studies.miniature_datasets.spinning_scans import simulate

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
    kitti = AirFisheyeDataset.from_root(root, "test", "completion", source="fisheye", augment=None)
    own = AirFisheyeDataset.from_root(tiny_dataset, "test", "completion", source="fisheye", augment=None)
    sid = kitti.sample_ids[0]
    assert kitti.reader.lidar_scan(sid).format == "kitti_bin" and original.spec.has("lidar")
    assert np.array_equal(kitti[0]["sparse_depth"].numpy(), own[0]["sparse_depth"].numpy())
    assert kitti.lidar_counts["rings from firing_order"] == 1
    for path in root.rglob("velodyne/*.bin"):  # the generator's own order: lasers bottom first, from -135 deg
        npy = path.parent.parent / "lidar" / (path.stem + ".npy")
        data = np.load(npy)
        np.column_stack([data[:, :3], np.zeros(len(data))]).astype(np.float32).tofile(path)
    other = AirFisheyeDataset.from_root(root, "test", "completion", source="fisheye", augment=None)
    assert np.array_equal(other[0]["sparse_depth"].numpy(), own[0]["sparse_depth"].numpy())
    assert sum(v for k, v in other.lidar_counts.items() if k.startswith("rings from ")) == 1
