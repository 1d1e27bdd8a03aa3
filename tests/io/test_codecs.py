"""Round trips and error messages of the per-frame file codecs."""

from __future__ import annotations

import numpy as np
import pytest

from airfisheye_bench.io import (
    DatasetFormatError,
    read_depth,
    read_label,
    read_lidar,
    read_pfm,
    read_rgb,
    read_visibility,
    write_depth,
    write_label,
    write_lidar,
    write_pfm,
    write_rgb,
    write_visibility,
)
from airfisheye_bench.io.atomic import atomic_write_bytes, remove_stale_temporaries


@pytest.fixture
def rng():
    return np.random.default_rng(0)


def test_rgb_png_round_trip_is_exact_and_deterministic(tmp_path, rng):
    img = rng.integers(0, 256, (17, 23, 3), dtype=np.uint8)
    write_rgb(tmp_path / "a.png", img)
    write_rgb(tmp_path / "b.png", img)
    assert np.array_equal(read_rgb(tmp_path / "a.png"), img)
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()


def test_rgb_jpeg_round_trip_is_close(tmp_path):
    img = np.zeros((32, 32, 3), np.uint8)
    img[:, :16] = (200, 50, 20)
    write_rgb(tmp_path / "a.jpg", img)
    back = read_rgb(tmp_path / "a.jpg")
    assert back.shape == img.shape and np.abs(back.astype(int) - img).mean() < 3


def test_label_round_trip_keeps_ignore(tmp_path, rng):
    lab = rng.integers(0, 23, (9, 11), dtype=np.uint8)
    lab[0, :] = 255
    write_label(tmp_path / "l.png", lab)
    assert np.array_equal(read_label(tmp_path / "l.png"), lab)


@pytest.mark.parametrize("suffix", [".png", ".npy", ".pfm"])
def test_depth_round_trip(tmp_path, rng, suffix):
    d = rng.uniform(0.5, 200.0, (13, 7)).astype(np.float32)
    d[0, 0], d[1, 1], d[2, 2] = 0.0, np.inf, np.nan  # all invalid -> 0
    write_depth(tmp_path / f"d{suffix}", d)
    back = read_depth(tmp_path / f"d{suffix}")
    assert back.dtype == np.float32 and back.shape == d.shape
    assert back[0, 0] == 0 and back[1, 1] == 0 and back[2, 2] == 0
    valid = np.isfinite(d) & (d > 0)
    tol = 0.5 / 256 + 1e-6 if suffix == ".png" else 0.0
    assert np.abs(back[valid] - d[valid]).max() <= tol


def test_depth_png_quantisation_and_saturation(tmp_path):
    d = np.array([[1.0, 1.0 + 1 / 256], [300.0, 255.99]], np.float32)
    write_depth(tmp_path / "d.png", d)
    back = read_depth(tmp_path / "d.png")
    assert back[0, 0] == 1.0 and back[0, 1] == np.float32(1 + 1 / 256)
    assert back[1, 0] == np.float32(65535 / 256)  # saturated, not wrapped around
    assert abs(back[1, 1] - 255.99) < 1 / 256


def test_pfm_is_bottom_to_top(tmp_path):
    img = np.arange(6, dtype=np.float32).reshape(2, 3)
    write_pfm(tmp_path / "x.pfm", img)
    raw = (tmp_path / "x.pfm").read_bytes()
    first_row_on_disk = np.frombuffer(raw[-24:-12], "<f4")
    assert first_row_on_disk.tolist() == [3.0, 4.0, 5.0]  # the bottom image row comes first
    assert np.array_equal(read_pfm(tmp_path / "x.pfm"), img)


def test_lidar_and_visibility_round_trip(tmp_path, rng):
    pts = np.concatenate([rng.normal(size=(50, 3)), rng.integers(0, 23, (50, 1))], 1).astype(np.float32)
    vis = rng.random(50) > 0.5
    write_lidar(tmp_path / "l.npy", pts)
    write_visibility(tmp_path / "v.npy", vis)
    assert np.array_equal(read_lidar(tmp_path / "l.npy"), pts)
    assert np.array_equal(read_visibility(tmp_path / "v.npy", num_points=50), vis)
    with pytest.raises(DatasetFormatError, match="scan has 49"):
        read_visibility(tmp_path / "v.npy", num_points=49)


def test_readers_name_the_file_on_bad_contents(tmp_path):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png")
    with pytest.raises(DatasetFormatError, match=r"bad\.png"):
        read_rgb(bad)
    np.save(tmp_path / "pts.npy", np.zeros((5, 3), np.float32))
    with pytest.raises(DatasetFormatError, match=r"pts\.npy.*\[N, 4\]"):
        read_lidar(tmp_path / "pts.npy")
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(DatasetFormatError, match=r"obj\.npy"):  # pickled content is refused
        read_lidar(tmp_path / "obj.npy")
    with pytest.raises(DatasetFormatError, match="does not exist"):
        read_depth(tmp_path / "missing.png")
    write_rgb(tmp_path / "rgb.png", np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(DatasetFormatError, match="single-channel"):
        read_label(tmp_path / "rgb.png")


def test_writers_validate_arguments(tmp_path):
    with pytest.raises(ValueError, match="rgb must have dtype uint8"):
        write_rgb(tmp_path / "x.png", np.zeros((4, 4, 3), np.float32))
    with pytest.raises(ValueError, match="unsupported RGB suffix"):
        write_rgb(tmp_path / "x.bmp", np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError, match="depth must be a float array"):
        write_depth(tmp_path / "x.png", np.zeros((4, 4), np.uint16))
    with pytest.raises(ValueError, match=r"points must be a numpy array \[N, 4\]"):
        write_lidar(tmp_path / "x.npy", np.zeros((4, 3), np.float32))


def test_atomic_write_leaves_no_partial_file(tmp_path, monkeypatch):
    target = tmp_path / "f.bin"
    atomic_write_bytes(target, b"old")

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("os.replace", boom)
    with pytest.raises(OSError):
        atomic_write_bytes(target, b"new")
    monkeypatch.undo()
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.bin"]  # the temporary was cleaned up
    (tmp_path / ".g.bin.abc.tmp").write_bytes(b"x")  # as left by a killed process
    assert remove_stale_temporaries(tmp_path) == 1
