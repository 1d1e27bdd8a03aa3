"""Round trips and error messages of the per-frame file codecs."""

from __future__ import annotations

import numpy as np
import pytest

from airfisheye_bench.atomic import atomic_write_bytes, remove_stale_temporaries
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


# -------------------- fast decoding (torchvision.io) == PIL
def pil_pixels(path, rgb: bool = False) -> np.ndarray:
    """What the readers returned before the fast path: PIL's pixels (converted to RGB if ``rgb``)."""
    from PIL import Image

    with Image.open(path) as img:
        return np.asarray(img.convert("RGB") if rgb else img)


def test_fast_decoders_are_used_and_bit_exact(tmp_path, rng):
    from airfisheye_bench.io import codecs

    assert codecs._torchvision_io() is not None  # the fast path is what these checks exercise
    smooth = np.linspace(0, 255, 64 * 48 * 3).reshape(64, 48, 3).astype(np.uint8)
    img = np.where(rng.random((64, 48, 1)) < 0.2, rng.integers(0, 256, (64, 48, 3)), smooth).astype(np.uint8)
    write_rgb(tmp_path / "a.png", img)
    write_rgb(tmp_path / "a.jpg", img)
    for name in ("a.png", "a.jpg"):
        out = read_rgb(tmp_path / name)
        assert out.dtype == np.uint8 and out.shape == (64, 48, 3) and out.flags.writeable
        np.testing.assert_array_equal(out, pil_pixels(tmp_path / name, rgb=True), err_msg=name)
    from PIL import Image

    for subsampling in (1, 2):  # 4:2:2 and 4:2:0 JPEGs: the same chroma upsampling as PIL
        Image.fromarray(img).save(tmp_path / f"s{subsampling}.jpg", quality=90, subsampling=subsampling)
        np.testing.assert_array_equal(
            read_rgb(tmp_path / f"s{subsampling}.jpg"), pil_pixels(tmp_path / f"s{subsampling}.jpg", rgb=True)
        )
    label = rng.integers(0, 23, (31, 17), dtype=np.uint8)
    write_label(tmp_path / "l.png", label)
    np.testing.assert_array_equal(read_label(tmp_path / "l.png"), label)
    depth = rng.uniform(0.0, 300.0, (31, 17)).astype(np.float32)
    for scale in (256.0, 100.0):
        write_depth(tmp_path / "d.png", depth, scale=scale)
        expected = (pil_pixels(tmp_path / "d.png").astype(np.float32) / np.float32(scale)).astype(np.float32)
        back = read_depth(tmp_path / "d.png", scale=scale)
        assert back.dtype == np.float32
        np.testing.assert_array_equal(back, expected)


def test_other_layouts_fall_back_to_pil(tmp_path, rng):
    """Grey, RGBA, palette and transparent-colour PNGs, grey and CMYK JPEGs: converted (or refused) as by PIL."""
    from PIL import Image

    rgb = rng.integers(0, 256, (12, 10, 3), dtype=np.uint8)
    rgb[0, 0] = 0
    files = {  # name: (image, save options)
        "grey.png": (Image.fromarray(rgb[..., 0]), {}),
        "rgba.png": (Image.fromarray(np.dstack([rgb, rgb[..., :1]]), mode="RGBA"), {}),
        "palette.png": (Image.fromarray(rgb).convert("P"), {}),
        "trns.png": (Image.fromarray(rgb), {"transparency": (0, 0, 0)}),  # an RGB PNG with a tRNS chunk
        "grey.jpg": (Image.fromarray(rgb[..., 0]), {}),
        "cmyk.jpg": (Image.fromarray(rgb).convert("CMYK"), {}),
    }
    for name, (img, options) in files.items():
        img.save(tmp_path / name, **options)
        out = read_rgb(tmp_path / name)
        assert out.dtype == np.uint8 and out.shape == (12, 10, 3)
        np.testing.assert_array_equal(out, pil_pixels(tmp_path / name, rgb=True), err_msg=name)
    np.testing.assert_array_equal(read_label(tmp_path / "palette.png"), pil_pixels(tmp_path / "palette.png"))
    with pytest.raises(DatasetFormatError, match=r"grey\.png.*16-bit"):  # an 8-bit depth PNG
        read_depth(tmp_path / "grey.png")
    Image.fromarray(rgb[..., 0].astype(np.uint16) * 200).save(tmp_path / "d16.png")
    with pytest.raises(DatasetFormatError, match=r"d16\.png.*single-channel 8-bit"):  # a 16-bit label
        read_label(tmp_path / "d16.png")


def test_corrupt_images_name_the_file(tmp_path):
    write_rgb(tmp_path / "ok.png", np.zeros((16, 16, 3), np.uint8))
    write_rgb(tmp_path / "ok.jpg", np.full((16, 16, 3), 128, np.uint8))
    for name in ("ok.png", "ok.jpg"):
        data = (tmp_path / name).read_bytes()
        (tmp_path / f"cut-{name}").write_bytes(data[: len(data) // 2])  # a valid header, truncated data
        with pytest.raises(DatasetFormatError, match=rf"cut-ok\.{name[-3:]}.*cannot decode"):
            read_rgb(tmp_path / f"cut-{name}")
    with pytest.raises(DatasetFormatError, match=r"missing\.jpg.*does not exist"):
        read_rgb(tmp_path / "missing.jpg")
    with pytest.raises(DatasetFormatError, match=r"missing\.png.*does not exist"):
        read_label(tmp_path / "missing.png")
