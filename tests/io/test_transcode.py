"""``transcode_dataset``: a PNG release rewritten as JPEG + ``.npy`` reads back the same data, all or nothing."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from airfisheye_bench.cli import transcode
from airfisheye_bench.dataset_tools import transcode as transcode_module
from airfisheye_bench.dataset_tools.inspect import inspect_dataset
from airfisheye_bench.dataset_tools.transcode import TranscodeReport, transcode_dataset
from airfisheye_bench.geometry.cubemap import FACE_NAMES
from airfisheye_bench.io import DatasetFormatError, DatasetReader, DatasetSpec, FileEncodings
from airfisheye_bench.io.manifest import read_manifest, verify
from datamodules.dataset import AirFisheyeDataset, CameraConfig
from tests.helpers.commands import exit_status


@pytest.fixture(scope="module")
def jpg_npy(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, TranscodeReport]:
    """The tiny dataset transcoded to RGB JPEG + depth ``.npy`` (one worker, hard links); read-only."""
    dst = tmp_path_factory.mktemp("transcoded") / "jpg-npy"
    return dst, transcode_dataset(tiny_dataset, dst, rgb="jpg", depth="npy")


def _samples(reader: DatasetReader) -> list[str]:
    return [sid for split in reader.split_names for sid in reader.split(split)]


def _no_leftovers(folder: Path) -> None:
    assert not [p.name for p in folder.iterdir() if ".partial-" in p.name]


def test_png_to_jpg_npy_reads_back_the_same_data(tiny_dataset: Path, jpg_npy) -> None:
    dst, report = jpg_npy
    src, out = DatasetReader(tiny_dataset), DatasetReader(dst)
    assert src.spec.files == FileEncodings(rgb="png", depth="png16")
    assert out.spec.files == FileEncodings(rgb="jpg", seg="png", depth="npy", depth_scale=256.0)
    assert out.spec.description.endswith("(transcoded from rgb png / depth png16)")
    assert out.spec.with_updates(files=src.spec.files, description=src.spec.description) == src.spec
    assert inspect_dataset(dst, deep=True).ok
    assert verify(dst).ok

    sids = _samples(src)
    assert sids == _samples(out) and len(sids) == 12
    assert report.transcoded == len(sids) * (len(FACE_NAMES) + 1) * 2  # rgb + depth: 5 faces and the fisheye
    assert report.linked > 0 and report.copied == 0 and report.bytes_before > 0 and report.bytes_after > 0
    assert str(report.transcoded) in report.summary()
    rgb_errors = []  # mean |JPEG - PNG| per file, grey levels
    for sid in sids:
        for face in FACE_NAMES:
            assert out.layout.cubemap(sid, face, "depth").suffix == ".npy"
            assert out.layout.cubemap(sid, face, "rgb").suffix == ".jpg"
            assert np.array_equal(out.cube_face(sid, face, "depth"), src.cube_face(sid, face, "depth"))
            rgb_new, rgb_old = out.cube_face(sid, face, "rgb"), src.cube_face(sid, face, "rgb")
            rgb_errors.append(np.abs(rgb_new.astype(int) - rgb_old.astype(int)).mean())
            label = out.layout.cubemap(sid, face, "seg")
            assert label.read_bytes() == src.layout.cubemap(sid, face, "seg").read_bytes()
        assert np.array_equal(out.fisheye(sid, "depth"), src.fisheye(sid, "depth"))
        rgb_errors.append(
            np.abs(out.fisheye(sid, "rgb").astype(int) - src.fisheye(sid, "rgb").astype(int)).mean()
        )
        for new, old in (
            (out.layout.lidar(sid), src.layout.lidar(sid)),
            (out.layout.lidar_visible(sid), src.layout.lidar_visible(sid)),
        ):
            assert new.read_bytes() == old.read_bytes()
            assert os.path.samefile(new, old)  # hard-linked
    # Quality 95 with 4:4:4 chroma; the tiny faces (48 px) are all texture, the worst for JPEG.
    assert np.mean(rgb_errors) < 3 and max(rgb_errors) < 4
    traj = src.trajectories()[0]
    assert out.layout.calib(traj).read_bytes() == src.layout.calib(traj).read_bytes()
    assert out.layout.poses(traj).read_bytes() == src.layout.poses(traj).read_bytes()
    assert all("/seg/" in p.as_posix() for p in dst.rglob("*.png"))  # only the labels stay PNG


def test_the_training_samples_are_unchanged(tiny_dataset: Path, jpg_npy) -> None:
    dst, _ = jpg_npy
    before = AirFisheyeDataset.from_root(tiny_dataset, "train", "completion", camera=CameraConfig(size=32))[0]
    after = AirFisheyeDataset.from_root(dst, "train", "completion", camera=CameraConfig(size=32))[0]
    assert after["sample_id"] == before["sample_id"]
    assert after["depth"].dtype == before["depth"].dtype and bool((after["depth"] == before["depth"]).all())
    assert bool((after["sparse_depth"] == before["sparse_depth"]).all())
    assert float((after["image"] - before["image"]).abs().mean()) < 0.1


def test_npy_back_to_png16_gives_the_source_values(tiny_dataset: Path, jpg_npy, tmp_path: Path) -> None:
    dst, _ = jpg_npy
    back = tmp_path / "back"
    report = transcode_dataset(dst, back, rgb="jpg", depth="png16")
    src, mid, out = DatasetReader(tiny_dataset), DatasetReader(dst), DatasetReader(back)
    assert out.spec.files == FileEncodings(rgb="jpg", depth="png16", depth_scale=256.0)
    assert report.transcoded == 12 * 6 and report.copied == 0  # JPEG RGB is carried over (linked) as it is
    for sid in _samples(src):
        for face in FACE_NAMES:
            new, old = out.layout.cubemap(sid, face, "depth"), src.layout.cubemap(sid, face, "depth")
            assert new.suffix == ".png"
            assert np.array_equal(np.asarray(Image.open(new)), np.asarray(Image.open(old)))
            rgb = out.layout.cubemap(sid, face, "rgb")
            assert rgb.read_bytes() == mid.layout.cubemap(sid, face, "rgb").read_bytes()
        assert np.array_equal(out.fisheye(sid, "depth"), src.fisheye(sid, "depth"))


@pytest.mark.integration
def test_workers_and_copies_give_the_same_bytes(tiny_dataset: Path, jpg_npy, tmp_path: Path) -> None:
    dst, serial = jpg_npy
    parallel = transcode_dataset(tiny_dataset, tmp_path / "parallel", workers=2, link=False)
    assert read_manifest(tmp_path / "parallel") == read_manifest(dst)
    assert parallel.linked == 0 and parallel.copied == serial.linked
    assert (parallel.transcoded, parallel.bytes_after) == (serial.transcoded, serial.bytes_after)
    sid = DatasetReader(dst).split("train")[0]
    copied = DatasetReader(tmp_path / "parallel").layout.lidar(sid)
    assert not os.path.samefile(copied, DatasetReader(tiny_dataset).layout.lidar(sid))


# In this process, and through the pool of worker processes (a worker's error reaches the caller intact). The pool
# costs seconds of starting interpreters: that case is slow, and the default suite takes the pool's path in
# test_workers_and_copies_give_the_same_bytes.
@pytest.mark.integration
@pytest.mark.parametrize("workers", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_a_corrupt_file_is_named(tiny_dataset: Path, tmp_path: Path, workers: int) -> None:
    src = tmp_path / "src"
    shutil.copytree(tiny_dataset, src, copy_function=os.link)
    bad = DatasetReader(src).layout.cubemap(DatasetReader(src).split("val")[0], "up", "rgb")
    bad.unlink()  # a new file, not the shared one
    bad.write_bytes(b"not a png")
    with pytest.raises(DatasetFormatError, match=re.escape(str(bad))):
        transcode_dataset(src, tmp_path / "out", workers=workers)
    assert not (tmp_path / "out").exists()
    _no_leftovers(tmp_path)


def test_bad_destinations_and_sources(tiny_dataset: Path, tmp_path: Path) -> None:
    taken = tmp_path / "taken"
    taken.mkdir()
    with pytest.raises(FileExistsError, match="taken"):
        transcode_dataset(tiny_dataset, taken)
    with pytest.raises(ValueError, match="is the source root"):
        transcode_dataset(tiny_dataset, tiny_dataset)
    with pytest.raises(ValueError, match="inside the source root"):
        transcode_dataset(tiny_dataset, tiny_dataset / "sub" / "new")
    assert not (tiny_dataset / "sub").exists()
    with pytest.raises(ValueError, match="rgb must be one of"):
        transcode_dataset(tiny_dataset, tmp_path / "x", rgb="webp")
    with pytest.raises(ValueError, match="jpeg_quality"):
        transcode_dataset(tiny_dataset, tmp_path / "x", jpeg_quality=0)

    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "a.txt").write_text("x")
    with pytest.raises(DatasetFormatError, match=r"dataset\.yaml"):
        transcode_dataset(empty, tmp_path / "x")
    assert not (tmp_path / "x").exists()
    _no_leftovers(tmp_path)


def test_a_failure_half_way_leaves_nothing(
    tiny_dataset: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = []
    encode = transcode_module._encode_file

    def flaky(job):
        calls.append(job)
        if len(calls) % 3 == 0:  # the 3rd file of each run
            raise OSError("disk full")
        return encode(job)

    monkeypatch.setattr(transcode_module, "_encode_file", flaky)
    out = tmp_path / "out" / "new"
    with pytest.raises(OSError, match="disk full"):
        transcode_dataset(tiny_dataset, out)
    assert len(calls) == 3 and not out.exists()
    _no_leftovers(out.parent)
    assert transcode([f"src={tiny_dataset}", f"dst={out}"]) == 2  # the command line reports it too
    assert not out.exists()
    _no_leftovers(out.parent)


def test_command_line(tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "cli"
    assert transcode([f"src={tiny_dataset}", f"dst={out}", "depth=pfm", "rgb=png", "link=false"]) == 0
    assert "72 files transcoded" in capsys.readouterr().out  # depth only, PNG RGB is carried over
    assert DatasetSpec.load(out).files == FileEncodings(rgb="png", depth="pfm")
    assert verify(out).ok and inspect_dataset(out).ok
    assert transcode([f"src={tiny_dataset}", f"dst={out}"]) == 2
    assert str(out) in capsys.readouterr().err
    assert exit_status(transcode, [f"src={tiny_dataset}"]) == 2
    assert "dst= is required" in capsys.readouterr().err
    assert exit_status(transcode, [f"src={tiny_dataset}", f"dst={tmp_path / 'y'}", "colour=rgb"]) == 2
    assert "unknown option 'colour'" in capsys.readouterr().err
    assert exit_status(transcode, [f"src={tiny_dataset}", f"dst={tmp_path / 'y'}", "link=maybe"]) == 2
    assert "error: link=maybe: expected a boolean" in capsys.readouterr().err
    assert exit_status(transcode, [f"src={tiny_dataset}", f"dst={tmp_path / 'y'}", "workers=two"]) == 2
    assert "error: workers=two: expected an integer" in capsys.readouterr().err
    _no_leftovers(tmp_path)
