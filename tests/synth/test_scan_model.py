"""Realistic LiDAR scans from the generator: per-frame phase, beam jitter and dropout, recorded in the dataset."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.dataset_tools.inspect import inspect_dataset
from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.io import DatasetReader
from airfisheye_bench.io.dataset_spec import DatasetSpec
from airfisheye_bench.synth import writer
from airfisheye_bench.synth.presets import PRESETS, SynthConfig, get_preset
from airfisheye_bench.synth.sensors import ScanModel

SPEC = LidarSpec(channels=16, points_per_channel=512, hfov_deg=270.0, vfov_deg=(-45.0, 15.0))

#: A small dataset with every realistic-scan option on.
REALISTIC = get_preset("tiny").replace(
    name="micro-realistic",
    total_frames=6,
    face_size=0,
    fisheye_size=24,
    lidar_channels=16,
    lidar_points_per_channel=128,
    lidar_phase="random",
    lidar_jitter_cells=(0.1, 0.1),
    lidar_dropout=0.1,
    scene_size_m=100.0,
)


def _cells(dirs: np.ndarray, spec: LidarSpec, phase: float) -> tuple[np.ndarray, np.ndarray]:
    """Offsets (in cells) of directions from the nominal beam grid shifted by ``phase``: (azimuth, elevation)."""
    _, az, el = spherical_coordinates(dirs)
    fj = (az - phase - spec.column_azimuths()[0]) / spec.horizontal_resolution
    fi = (el - spec.channel_elevations()[0]) / spec.vertical_resolution
    return fj, fi


# ----------------------------------------------------------------------------------------------- the model
def test_the_ideal_model_fires_exactly_the_spec_beams() -> None:
    dirs, beam = ScanModel().beams(SPEC, 0.0, rng=None)
    assert torch.equal(dirs, SPEC.beam_directions(torch.float64).reshape(-1, 3))
    assert np.array_equal(beam, np.arange(SPEC.channels * SPEC.points_per_channel))


def test_random_phase_jitter_and_dropout_follow_their_parameters() -> None:
    scan = ScanModel(phase="random", jitter_cells=(0.1, 0.2), dropout=0.1)
    rng = np.random.default_rng(0)
    phases = np.array([scan.frame_phase(SPEC, 0.0, rng) for _ in range(2000)])
    h = SPEC.horizontal_resolution
    assert np.all(np.abs(phases) <= h / 2) and np.std(phases / h) == pytest.approx(1 / math.sqrt(12), rel=0.1)

    phase = 0.3 * h
    dirs, beam = scan.beams(SPEC, phase, np.random.default_rng(1))
    n = SPEC.channels * SPEC.points_per_channel
    assert len(beam) / n == pytest.approx(0.9, abs=0.02)  # dropout
    assert np.all(np.diff(beam) > 0) and beam.min() >= 0 and beam.max() < n
    fj, fi = _cells(dirs.numpy(), SPEC, phase)
    row, col = np.divmod(beam, SPEC.points_per_channel)
    assert np.std(fj - col) == pytest.approx(0.1, rel=0.1)  # jitter about the phase-shifted beam, in cells
    assert np.std(fi - row) == pytest.approx(0.2, rel=0.1)
    assert abs(np.mean(fj - col)) < 0.01 and abs(np.mean(fi - row)) < 0.01

    again, beam2 = scan.beams(SPEC, phase, np.random.default_rng(1))  # seeded: reproducible
    assert torch.equal(again, dirs) and np.array_equal(beam2, beam)


def test_spin_phase_is_the_rotation_angle_modulo_one_column() -> None:
    scan = ScanModel(phase="spin", rotation_hz=10.0)
    h = SPEC.horizontal_resolution
    t = np.array([0.0, 0.0123, 0.05, 1.0371])
    phases = np.array([scan.frame_phase(SPEC, ti, rng=None) for ti in t])
    assert np.all((phases >= -h / 2) & (phases < h / 2))
    turns = (2 * np.pi * 10.0 * t - phases) / h  # the angle and its phase differ by whole columns
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-6)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"lidar_phase": "wobble"}, "lidar_phase"),
        ({"lidar_dropout": 1.0}, "lidar_dropout"),
        ({"lidar_jitter_cells": (-0.1, 0.0)}, "lidar_jitter_cells"),
        ({"lidar_rotation_hz": 0.0}, "lidar_rotation_hz"),
    ],
)
def test_bad_scan_settings_name_the_field(changes: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        get_preset("tiny").replace(**changes)


# ----------------------------------------------------------------------------------------------- presets
def test_existing_presets_keep_their_identity_and_the_occlusion_preset_round_trips() -> None:
    for name, cfg in PRESETS.items():
        d = cfg.to_dict()
        assert SynthConfig.from_dict(d) == cfg, name
        if not name.startswith(
            "occlusion"
        ):  # ideal scans: the scan fields are not recorded (identity unchanged)
            assert cfg.scan_model().ideal and not any(k.startswith("lidar_phase") for k in d), name
    occ = get_preset("occlusion")
    assert not occ.scan_model().ideal and occ.lidar_points_per_channel == 2048 and occ.fisheye_size == 512
    offset = np.asarray(occ.flight.rig.lidar_offset_in_gimbal_m)  # LiDAR relative to the camera (FLU)
    assert 0.5 <= abs(offset[1]) <= 1.0 and 0.5 <= offset[2] <= 1.0  # beside, and above: the camera is below
    ablation = get_preset("occlusion_ablation")  # the same rig, more and shorter flights
    assert ablation.replace(name="occlusion", num_trajectories=24, split_ratios=occ.split_ratios) == occ


# ----------------------------------------------------------------------------------------------- dataset
@pytest.fixture(scope="module")
def realistic_dataset(tmp_path_factory) -> Path:
    return writer.generate_dataset(
        REALISTIC, tmp_path_factory.mktemp("realistic") / "ds", seed=5, workers=1, progress=False
    )


def test_the_dataset_records_phase_and_beams_and_they_explain_every_point(realistic_dataset: Path) -> None:
    spec = DatasetSpec.load(realistic_dataset)
    assert spec.has("lidar_beam") and spec.has("lidar_scan")
    assert spec.sensors["lidar"]["scan"]["phase"] == "random"
    assert inspect_dataset(realistic_dataset, deep=True).ok
    reader = DatasetReader(realistic_dataset)
    ids = [sid for split in reader.split_names for sid in reader.split(split)]
    phases = []
    for sid in ids:
        lidar_spec = reader.calib(sid).lidar_spec()
        points, beam, visible = reader.lidar(sid), reader.lidar_beam(sid), reader.lidar_visible(sid)
        phase = reader.lidar_phase(sid)
        phases.append(phase)
        assert len(beam) == len(points) == len(visible) > 0
        fj, fi = _cells(points[:, :3].astype(np.float64), lidar_spec, phase)
        row, col = np.divmod(beam, lidar_spec.points_per_channel)
        # Each point lies where its recorded beam fired: within the jitter (0.1 cell, 6 sigma) of the grid
        # shifted by the recorded phase.
        assert np.abs(fj - col).max() < 0.6 and np.abs(fi - row).max() < 0.6
    assert len(set(phases)) == len(phases)  # a new phase every frame


def test_realistic_scans_are_deterministic(realistic_dataset: Path, tmp_path: Path) -> None:
    """Phase, jitter and dropout depend on (seed, trajectory, frame) only: two workers give the same bytes."""
    other = writer.generate_dataset(REALISTIC, tmp_path / "two", seed=5, workers=2, progress=False)
    for path in realistic_dataset.rglob("*"):
        if path.is_file():
            assert (other / path.relative_to(realistic_dataset)).read_bytes() == path.read_bytes(), path
