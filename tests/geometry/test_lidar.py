"""LiDAR sensor description and scan organisation into I_LiDAR."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.lidar_layout import organize_scan


def beam_points(spec: LidarSpec, ranges: np.ndarray | float = 10.0) -> np.ndarray:
    """One point per beam, listed row-major (channel, column), at the given ranges."""
    dirs = spec.beam_directions(torch.float64).reshape(-1, 3).numpy()
    return dirs * np.broadcast_to(np.asarray(ranges, dtype=np.float64), (len(dirs),))[:, None]


# ---------------------------------------------------------------------------------------------- LidarSpec
def test_defaults_are_the_paper_sensor() -> None:
    spec = LidarSpec()
    assert (spec.channels, spec.points_per_channel, spec.hfov_deg, spec.max_range) == (64, 2048, 270.0, 120.0)
    assert spec.vfov_deg == (-45.0, 15.0)
    assert spec.vertical_resolution == pytest.approx(math.radians(60.0) / 63)  # VFOV / (N_C - 1)
    assert spec.horizontal_resolution == pytest.approx(math.radians(270.0) / 2048)


def test_beam_pattern() -> None:
    spec = LidarSpec(channels=5, points_per_channel=12, hfov_deg=90.0, vfov_deg=(-20.0, 10.0))
    d = spec.beam_directions(torch.float64)
    assert d.shape == (5, 12, 3) and d.dtype == torch.float64
    torch.testing.assert_close(d.norm(dim=-1), torch.ones(5, 12, dtype=torch.float64))
    _, az, el = spherical_coordinates(d.reshape(-1, 3).numpy())
    az, el = np.degrees(az.reshape(5, 12)), np.degrees(el.reshape(5, 12))
    # channel 0 is the lowest; the channels span exactly the vertical FOV
    np.testing.assert_allclose(el[:, 0], [-20.0, -12.5, -5.0, 2.5, 10.0], atol=1e-9)
    assert np.all(np.diff(el, axis=0) > 0) and np.allclose(el, el[:, :1])
    # columns: ascending azimuth (towards +y, the LiDAR's left), cell centres of a FOV centred on +x
    np.testing.assert_allclose(az[0], -45.0 + 7.5 * (np.arange(12) + 0.5), atol=1e-9)
    assert spec.beam_directions(torch.float32).dtype == torch.float32


def test_full_circle_has_no_duplicate_column() -> None:
    spec = LidarSpec(channels=2, points_per_channel=8, hfov_deg=360.0, vfov_deg=(0.0, 10.0))
    _, az, _ = spherical_coordinates(beam_points(spec)[:8])
    assert len(np.unique(np.round(np.mod(az, 2 * np.pi), 9))) == 8


def test_spec_round_trip_and_yaml_friendly() -> None:
    spec = LidarSpec(channels=32, points_per_channel=1024, hfov_deg=360.0, vfov_deg=(-30, 10), max_range=80)
    d = spec.to_dict()
    assert d == {
        "channels": 32,
        "points_per_channel": 1024,
        "hfov_deg": 360.0,
        "vfov_deg": [-30.0, 10.0],
        "max_range": 80.0,
    }
    assert LidarSpec.from_dict(d) == spec
    with pytest.raises(ValueError, match="unknown LiDAR spec keys"):
        LidarSpec.from_dict({**d, "rings": 3})


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"channels": 1}, "channels"),
        ({"channels": 2.5}, "channels"),
        ({"channels": True}, "channels"),
        ({"points_per_channel": 0}, "points_per_channel"),
        ({"hfov_deg": 0.0}, "hfov_deg"),
        ({"hfov_deg": 400.0}, "hfov_deg"),
        ({"hfov_deg": float("nan")}, "hfov_deg"),
        ({"vfov_deg": (10.0, -10.0)}, "vfov_deg"),
        ({"vfov_deg": (-95.0, 0.0)}, "vfov_deg"),
        ({"vfov_deg": (0.0,)}, "vfov_deg"),
        ({"max_range": -1.0}, "max_range"),
    ],
)
def test_spec_validation(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        LidarSpec(**kwargs)


def test_spec_is_frozen() -> None:
    with pytest.raises(AttributeError):
        LidarSpec().channels = 3  # type: ignore[misc]


# ---------------------------------------------------------------------------------------------- organize_scan
def turned(points: np.ndarray, radians: np.ndarray | float) -> np.ndarray:
    """Points rotated about the LiDAR's z axis (a change of azimuth phase)."""
    a = np.broadcast_to(np.asarray(radians, dtype=np.float64), (len(points),))
    x, y, z = points.T
    return np.stack([np.cos(a) * x - np.sin(a) * y, np.sin(a) * x + np.cos(a) * y, z], axis=1)


@pytest.mark.parametrize("phase", [0.0, 0.5, -0.49])
def test_organize_recovers_the_beam_grid_from_a_shuffled_scan(phase: float) -> None:
    """Whatever the azimuth phase (beams on the sector centres, on their edges, anywhere), every return keeps
    its own place: ring = channel, position = beam index along the ring."""
    spec = LidarSpec(channels=16, points_per_channel=90, hfov_deg=360.0)
    rng = np.random.default_rng(0)
    points = beam_points(spec, rng.uniform(1.0, 100.0, 16 * 90))
    ring_phase = np.repeat(rng.uniform(-0.5, 0.5, 16), 90) if phase == -0.49 else phase
    points = turned(points, ring_phase * spec.horizontal_resolution)
    perm = rng.permutation(len(points))
    ring, position, column = organize_scan(points[perm], spec)
    assert ring.dtype == position.dtype == column.dtype == np.int64
    channel, beam = np.divmod(perm, 90)
    np.testing.assert_array_equal(ring, channel)
    if phase == 0.0:  # beams on the sector centres: the sector is the beam's column
        np.testing.assert_array_equal(column, beam)
    # a beam past +180 deg wraps to the ring's start: positions are the beams' order in azimuth
    _, az, _ = spherical_coordinates(points[perm])
    for i in range(16):
        np.testing.assert_array_equal(np.argsort(position[ring == i]), np.argsort(az[ring == i]))


def test_dropped_returns_shorten_the_rings() -> None:
    spec = LidarSpec(channels=8, points_per_channel=40)
    rng = np.random.default_rng(1)
    returned = rng.random(8 * 40) < 0.6
    ring, position, column = organize_scan(beam_points(spec, 20.0)[returned], spec)
    channel, beam = np.divmod(np.flatnonzero(returned), 40)
    np.testing.assert_array_equal(ring, channel)
    np.testing.assert_array_equal(column, beam)
    for i in range(8):  # ranks 0, 1, ... of the returned beams in azimuth order
        np.testing.assert_array_equal(position[ring == i], np.arange((channel == i).sum()))


def test_points_sharing_a_sector_keep_their_own_places() -> None:
    """Two returns in one sector (beams near its edges, jitter): both are organised, by azimuth."""
    spec = LidarSpec(channels=4, points_per_channel=16, hfov_deg=360.0, vfov_deg=(-30.0, 30.0))
    beam = spec.beam_directions(torch.float64)[2, 5].numpy()[None] * 7.0
    cells = np.array([0.3, -0.45, 0.3, 1.2])  # offsets from the sector centre, in sectors; a duplicate
    points = turned(np.repeat(beam, 4, axis=0), cells * spec.horizontal_resolution)
    ring, position, column = organize_scan(points, spec)
    np.testing.assert_array_equal(ring, [2, 2, 2, 2])
    np.testing.assert_array_equal(column, [5, 5, 5, 6])
    np.testing.assert_array_equal(position, [1, 0, 2, 3])  # equal azimuths: the lower index first


def test_points_outside_the_fov() -> None:
    spec = LidarSpec(channels=4, points_per_channel=30, hfov_deg=270.0, vfov_deg=(-10.0, 10.0))
    pts = np.array(
        [
            [-5.0, 0.0, -0.3],  # behind: azimuth 180 deg, outside the 270 deg HFOV; -3.4 deg: channel 1
            [5.0, 0.0, 5.0],  # 45 deg up, far above the top channel: no beam returns it
            [0.0, 0.0, 0.0],  # no direction at all
            [5.0, 0.0, math.tan(math.radians(11.6)) * 5.0],  # 11.6 deg: within half a spacing (3.3 deg) of 10
        ]
    )
    ring, position, column = organize_scan(pts, spec)
    np.testing.assert_array_equal(ring, [1, -1, -1, 3])  # channels at -10, -3.3, 3.3, 10 deg
    np.testing.assert_array_equal(position, [0, -1, -1, 0])
    assert column[0] == math.floor(315.0 / 9.0) and column[3] == 15  # the sector beyond the HFOV; the centre


def test_full_circle_wraps_around() -> None:
    spec = LidarSpec(channels=2, points_per_channel=8, hfov_deg=360.0, vfov_deg=(0.0, 10.0))
    azimuths = np.radians([170.0, -170.0, 180.0, -180.0])
    ring, position, column = organize_scan(
        np.stack([np.cos(azimuths), np.sin(azimuths), 0 * azimuths], 1), spec
    )
    np.testing.assert_array_equal(ring, 0)
    np.testing.assert_array_equal(column, [7, 0, 7, 0])  # 45 deg sectors from -180 deg
    _, az, _ = spherical_coordinates(np.stack([np.cos(azimuths), np.sin(azimuths), 0 * azimuths], 1))
    np.testing.assert_array_equal(position, np.argsort(np.argsort(az, kind="stable"), kind="stable"))


def test_torch_in_torch_out_and_empty_scan() -> None:
    spec = LidarSpec(channels=4, points_per_channel=8)
    pts = torch.from_numpy(beam_points(spec, 5.0)).float()
    layout = organize_scan(pts, spec)
    expected = organize_scan(pts.double().numpy(), spec)
    for got, want in zip(layout, expected, strict=True):
        assert isinstance(got, torch.Tensor) and got.dtype == torch.int64
        np.testing.assert_array_equal(got.numpy(), want)
    empty = organize_scan(np.zeros((0, 3), dtype=np.float32), spec)
    assert all(v.shape == (0,) for v in empty)


@pytest.mark.parametrize(
    "points",
    [
        np.zeros((5, 4)),
        np.zeros(3),
        np.zeros((5, 3), dtype=np.int64),
        np.array([[1.0, np.nan, 0.0]]),
        [[1.0, 2.0, 3.0]],
    ],
)
def test_organize_rejects_bad_points(points) -> None:
    with pytest.raises(ValueError, match="points_lidar"):
        organize_scan(points, LidarSpec())


def test_organize_rejects_bad_spec() -> None:
    with pytest.raises(ValueError, match="spec"):
        organize_scan(np.zeros((1, 3)), {"channels": 64})  # type: ignore[arg-type]
