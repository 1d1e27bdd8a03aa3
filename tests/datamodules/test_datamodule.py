"""AirFisheyeDataModule / AirFisheyeDataset on the synthetic ``tiny`` preset."""

from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry import transform_points
from airfisheye_bench.geometry.cubemap import direction_to_face
from airfisheye_bench.geometry.occlusion import project_lidar
from airfisheye_bench.io import DatasetFormatError, DatasetReader, EmptySplitError
from datamodules import AirFisheyeDataModule, AirFisheyeDataset, CameraConfig, FisheyeAugment, collate


def _fine_dataset(root: Path, face_size: int) -> Path:
    """Three frames (one per split) whose cube faces are much finer than the ray-cast 48^2 fisheye."""
    from airfisheye_bench.synth.presets import get_preset
    from airfisheye_bench.synth.writer import generate_dataset

    config = dataclasses.replace(
        get_preset("tiny"),
        name=f"fine{face_size}",
        num_trajectories=3,
        total_frames=3,
        face_size=face_size,
        fisheye_size=48,
    )
    return generate_dataset(config, root / f"fine{face_size}", seed=1, workers=1, progress=False)


@pytest.fixture(scope="module")
def fine_datasets(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    root = tmp_path_factory.mktemp("fine")
    return {s: _fine_dataset(root, s) for s in (160, 320)}


def remap_vs_render(root: Path) -> tuple[float, float]:
    """(label disagreement over all valid pixels, median relative depth error) of cubemap remap vs direct render."""
    disagree, total, rel = 0, 0, []
    for split in ("train", "val", "test"):
        seg = [
            AirFisheyeDataset.from_root(root, split, "seg", source=src)[0] for src in ("cubemap", "fisheye")
        ]
        depth = [
            AirFisheyeDataset.from_root(root, split, "depth", source=src)[0]["depth"][0]
            for src in ("cubemap", "fisheye")
        ]
        mask = seg[0]["valid_mask"] & seg[1]["valid_mask"]
        disagree += int((seg[0]["label"] != seg[1]["label"])[mask].sum())
        total += int(mask.sum())
        both = mask & (depth[0] > 0) & (depth[1] > 0)
        rel.append(((depth[0] - depth[1]).abs() / depth[1])[both])
    return disagree / total, float(torch.cat(rel).median())


@pytest.mark.parametrize("task", ["seg", "depth", "completion"])
def test_batches_have_the_documented_shapes_and_ranges(tiny_dataset: Path, task: str) -> None:
    dm = AirFisheyeDataModule(task, root=tiny_dataset, camera={"size": 48}, batch_size=2, augment={})
    dm.setup("fit")
    batch = next(iter(dm.train_dataloader()))
    assert batch["image"].shape == (2, 3, 48, 48) and batch["image"].dtype == torch.float32
    assert batch["valid_mask"].shape == (2, 48, 48) and batch["valid_mask"].dtype == torch.bool
    assert len(batch["sample_id"]) == 2 and batch["num_skipped"] == 0
    assert batch["sample_id"][0].count("/") == 2
    valid = batch["valid_mask"]
    if task == "seg":
        label = batch["label"]
        assert label.dtype == torch.int64 and label.shape == (2, 48, 48)
        assert (label[~valid] == 255).all()
        classes = set(label[valid].unique().tolist()) - {255}
        assert classes and max(classes) < dm.num_classes == len(dm.class_names)
    else:
        depth = batch["depth"]
        assert depth.shape == (2, 1, 48, 48)
        assert (depth >= 0).all() and depth.max() <= 120.0 and (depth > 0).any()
        assert (depth[:, 0][~valid] == 0).all()
    if task == "completion":
        sparse = batch["sparse_depth"]
        assert sparse.shape == (2, 1, 48, 48) and (sparse > 0).any() and sparse.max() <= 120.0
        assert (sparse[:, 0][~valid] == 0).all()


def test_label_mapping_follows_dataset_yaml(tiny_dataset: Path) -> None:
    ds = AirFisheyeDataset.from_root(tiny_dataset, "val", "seg", source="fisheye")
    reader = DatasetReader(tiny_dataset)
    sid = ds.sample_ids[0]
    raw = reader.fisheye(sid, "seg")
    expected = np.full(raw.shape, 255, np.int64)
    for raw_id, train_id in reader.spec.raw_to_train.items():
        expected[raw == raw_id] = train_id
    np.testing.assert_array_equal(ds[0]["label"].numpy(), expected)


def test_cubemap_remap_agrees_with_the_direct_fisheye_render(fine_datasets: dict[int, Path]) -> None:
    """The remap reproduces the ray-cast fisheye up to face sampling, and the residue shrinks with the texel size.

    Labels can only disagree where a class boundary passes within half a texel of a pixel's ray, so the
    disagreement is proportional to the texel size; a geometric error would leave a floor.
    """
    coarse, _ = remap_vs_render(fine_datasets[160])
    fine, depth_error = remap_vs_render(fine_datasets[320])
    assert fine <= 0.02
    assert fine <= 0.65 * coarse
    assert depth_error < 0.01


@pytest.mark.slow
def test_remap_label_agreement_at_fine_faces(tmp_path: Path) -> None:
    disagreement, depth_error = remap_vs_render(_fine_dataset(tmp_path, 640))
    assert disagreement <= 0.01 and depth_error < 0.005


def test_a_pinhole_at_90_degrees_serves_the_front_face(tiny_dataset: Path) -> None:
    """``data.camera.model=pinhole data.camera.fov_deg=90`` at the faces' size: each pixel centre's ray is a front
    texel's, so the whole frame is valid and depth (range, as every served depth) and labels are the face's own."""
    reader = DatasetReader(tiny_dataset)
    size = reader.cube_face(reader.split("test")[0], "front", "depth").shape[0]
    camera = CameraConfig(size=size, model="pinhole", fov_deg=90.0)
    depth = AirFisheyeDataset.from_root(tiny_dataset, "test", "depth", camera=camera)[0]
    seg = AirFisheyeDataset.from_root(tiny_dataset, "test", "seg", camera=camera)[0]
    assert depth["valid_mask"].all() and seg["valid_mask"].all()
    face = torch.from_numpy(reader.cube_face(depth["sample_id"], "front", "depth"))
    kept = depth["depth"][0] > 0
    assert kept.float().mean() > 0.2  # the rest is sky
    torch.testing.assert_close(depth["depth"][0][kept], face[kept], rtol=0, atol=0)
    assert (seg["label"] != 255).float().mean() > 0.2


def test_sparse_depth_holds_visible_points(tiny_dataset: Path) -> None:
    """Points kept by the occlusion correction are visible per the exact ground truth (precision >= 0.98)."""
    ds = AirFisheyeDataset.from_root(tiny_dataset, "train", "completion", camera=CameraConfig(size=64))
    reader = ds.reader
    kept = visible = 0
    for sid in ds.sample_ids:
        points = reader.lidar(sid)[:, :3].astype(np.float64)
        calib = reader.calib(sid)
        mask = project_lidar(points, reader.T_cam_lidar(sid), ds.camera, calib.lidar_spec(), "ordering").mask
        kept += mask.sum()
        visible += (mask & reader.lidar_visible(sid)).sum()
    assert kept > 0 and visible / kept >= 0.98
    # ... and they are where the dense ground truth puts them.
    sample = ds[0]
    sparse, dense = sample["sparse_depth"][0], sample["depth"][0]
    both = (sparse > 0) & (dense > 0)
    assert ((sparse[both] - dense[both]).abs() / dense[both]).median() < 0.03


def test_motion_compensation_matters(fine_datasets: dict[int, Path]) -> None:
    """With compensation, visible LiDAR points sit on the rendered surfaces along their exact rays."""
    root = fine_datasets[320]
    reader = DatasetReader(root)
    for split in ("train", "val", "test"):
        errors = {}
        for compensate in (True, False):
            ds = AirFisheyeDataset.from_root(root, split, "completion", motion_compensation=compensate)
            sid = ds.sample_ids[0]
            points = transform_points(ds.T_cam_lidar(sid), reader.lidar(sid)[:, :3].astype(np.float64))
            rng = np.linalg.norm(points, axis=1)
            faces = reader.cubemap(sid, "depth")
            face, u, v = direction_to_face(torch.from_numpy(points / rng[:, None]), faces.shape[1])
            ok = (face >= 0).numpy() & reader.lidar_visible(sid)
            s = faces.shape[1]
            surface = faces[
                face[ok], v[ok].round().clamp(0, s - 1).long(), u[ok].round().clamp(0, s - 1).long()
            ]
            errors[compensate] = np.median(np.abs(surface - rng[ok]) / rng[ok])
        assert errors[True] < 0.002
        assert errors[True] < errors[False]


def test_augmentation_keeps_every_target_aligned(tiny_dataset: Path) -> None:
    augment = FisheyeAugment(hflip=1.0, rotate_deg=60.0, color_jitter=None)
    plain = AirFisheyeDataset.from_root(tiny_dataset, "train", "completion", camera=CameraConfig(size=64))
    aug = AirFisheyeDataset.from_root(
        tiny_dataset, "train", "completion", camera=CameraConfig(size=64), augment=augment
    )
    torch.manual_seed(0)
    s = aug[1]
    base = plain[1]
    # The sparse LiDAR map (rotated as points) still matches the dense depth (rotated as an image) ...
    both = (s["sparse_depth"] > 0) & (s["depth"] > 0)
    rel = ((s["sparse_depth"][both] - s["depth"][both]).abs() / s["depth"][both]).median()
    both0 = (base["sparse_depth"] > 0) & (base["depth"] > 0)
    rel0 = ((base["sparse_depth"][both0] - base["depth"][both0]).abs() / base["depth"][both0]).median()
    assert rel < max(2 * rel0, 0.03)
    # ... and the flip with a zero rotation is an exact mirror of every map.
    flip_only = AirFisheyeDataset.from_root(
        tiny_dataset,
        "train",
        "completion",
        camera=CameraConfig(size=64),
        augment=FisheyeAugment(1.0, 0.0, None),
    )[1]
    for key in ("image", "depth", "sparse_depth", "valid_mask"):
        torch.testing.assert_close(flip_only[key], base[key].flip(-1))


def test_rotation_moves_pixels_about_the_principal_point(tiny_dataset: Path) -> None:
    """A 90-degree rotation of the camera frame is a 90-degree rotation of a square centred image."""
    plain = AirFisheyeDataset.from_root(tiny_dataset, "val", "depth", camera=CameraConfig(size=64))
    rot = AirFisheyeDataset.from_root(
        tiny_dataset, "val", "depth", camera=CameraConfig(size=64), augment=FisheyeAugment(0.0, 90.0, None)
    )
    rot.augment = dataclasses.replace(rot.augment)  # same settings; the draw below is forced to +90 deg
    from datamodules.augment import AugmentParams

    rot.augment = type(
        "Fixed", (), {"sample": staticmethod(lambda generator=None: AugmentParams(False, math.pi / 2, None))}
    )()
    a, b = plain[0]["depth"][0], rot[0]["depth"][0]
    # x (right) turns towards y (down): the new image at (row, col) shows the old one at (W-1-col, row).
    torch.testing.assert_close(b, torch.rot90(a, k=-1, dims=(0, 1)))


def test_draws_follow_the_epoch_whatever_the_workers(tiny_dataset: Path) -> None:
    """A batch depends on (seed, epoch, index) only, not on the global RNG: no workers, workers, and persistent
    workers (which must see the epoch the main process sets) give the same batches, epoch after epoch."""

    def epochs(workers: int, persistent: bool) -> list[list[dict]]:
        dm = AirFisheyeDataModule(
            "completion",
            root=tiny_dataset,
            camera={"size": 32},
            batch_size=2,
            augment={"rotate_deg": 30},
            num_workers=workers,
            persistent_workers=persistent,
            seed=7,
        )
        dm.setup("fit")
        loader = dm.train_dataloader()
        out = []
        for epoch in range(2):  # what Lightning and BenchmarkTask do at every epoch start
            loader.sampler.set_epoch(epoch)
            dm.set_epoch(epoch)
            out.append(list(loader))
        return out

    reference = epochs(0, False)
    by_id = [
        {sid: b["image"][i] for b in batches for i, sid in enumerate(b["sample_id"])} for batches in reference
    ]
    shared = by_id[0].keys() & by_id[1].keys()
    assert shared and all(not torch.equal(by_id[0][s], by_id[1][s]) for s in shared)  # a new draw per epoch
    for other in (epochs(2, False), epochs(2, True)):
        for ours, theirs in zip(reference, other, strict=True):
            for x, y in zip(ours, theirs, strict=True):
                assert x["sample_id"] == y["sample_id"]
                for key in ("image", "depth", "sparse_depth", "valid_mask"):
                    torch.testing.assert_close(x[key], y[key], rtol=0, atol=0)


def test_fisheye_source_resizes_and_rejects_lens_changes(tiny_dataset: Path) -> None:
    ds = AirFisheyeDataset.from_root(
        tiny_dataset, "val", "depth", source="fisheye", camera=CameraConfig(size=32)
    )
    assert ds[0]["depth"].shape == (1, 32, 32)
    with pytest.raises(ValueError, match="source=cubemap"):
        AirFisheyeDataset.from_root(
            tiny_dataset, "val", "depth", source="fisheye", camera=CameraConfig(fov_deg=180.0)
        )
    other_lens = AirFisheyeDataset.from_root(
        tiny_dataset, "val", "seg", camera=CameraConfig(size=40, model="equisolid", fov_deg=170.0)
    )
    assert other_lens.camera.model == "equisolid" and other_lens[0]["label"].shape == (40, 40)


# ------------------------------------------------------------------------------------------------ robustness
@pytest.fixture
def broken_copy(tiny_dataset: Path, tmp_path: Path) -> Path:
    root = tmp_path / "copy"
    shutil.copytree(tiny_dataset, root)
    return root


def _first(root: Path, split: str = "train") -> str:
    return (root / "splits" / f"{split}.txt").read_text().split()[0]


def test_missing_root_and_split_are_clear_errors(tmp_path: Path, broken_copy: Path) -> None:
    with pytest.raises(ValueError, match=r"data\.root"):
        AirFisheyeDataModule("seg", root=tmp_path / "nowhere")
    (broken_copy / "splits" / "val.txt").unlink()
    with pytest.raises((ValueError, OSError), match=r"val\.txt"):
        AirFisheyeDataset.from_root(broken_copy, "val", "seg")
    (broken_copy / "splits" / "val.txt").write_text("# no frames\n")
    with pytest.raises(EmptySplitError, match=r"split 'val' is empty .*splits/val\.txt"):
        AirFisheyeDataset.from_root(broken_copy, "val", "seg")


def test_corrupt_files_name_the_file(broken_copy: Path) -> None:
    reader = DatasetReader(broken_copy)
    sid = _first(broken_copy)
    face = reader.layout.cubemap(sid, "left", "rgb")
    face.write_bytes(b"not an image")
    ds = AirFisheyeDataset.from_root(broken_copy, "train", "seg")
    with pytest.raises(DatasetFormatError, match=face.name):
        ds[0]


def test_bad_values_are_reported(broken_copy: Path) -> None:
    reader = DatasetReader(broken_copy)
    sid = _first(broken_copy)
    # Unknown raw label ids.
    seg_path = reader.layout.fisheye(sid, "seg")
    from airfisheye_bench.io import write_label, write_lidar

    label = reader.fisheye(sid, "seg")
    label[0, 0] = 200
    write_label(seg_path, label)
    with pytest.raises(DatasetFormatError, match=r"\[200\]"):
        AirFisheyeDataset.from_root(broken_copy, "train", "seg", source="fisheye")[0]
    # An empty LiDAR scan.
    write_lidar(reader.layout.lidar(sid), np.zeros((0, 4), np.float32))
    with pytest.raises(DatasetFormatError, match="empty"):
        AirFisheyeDataset.from_root(broken_copy, "train", "completion")[0]


def test_skip_bad_frames_drops_and_counts(broken_copy: Path) -> None:
    reader = DatasetReader(broken_copy)
    sid = _first(broken_copy)
    reader.layout.cubemap(sid, "front", "rgb").unlink()
    ds = AirFisheyeDataset.from_root(
        broken_copy, "train", "seg", camera=CameraConfig(size=32), skip_bad_frames=True
    )
    samples = [ds[0], ds[1]]
    assert samples[0] is None and samples[1] is not None
    batch = collate(samples)
    assert batch["num_skipped"] == 1 and batch["image"].shape[0] == 1
