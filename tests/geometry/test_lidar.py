"""LiDAR sensor description and scan organisation into I_LiDAR."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.lidar import LidarSpec, organize_scan, spherical_coordinates


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
def test_organize_recovers_the_beam_grid_from_a_shuffled_scan() -> None:
    spec = LidarSpec(channels=16, points_per_channel=90)
    rng = np.random.default_rng(0)
    points = beam_points(spec, rng.uniform(1.0, 100.0, 16 * 90))
    # small angular jitter (well under half a cell) must not move a point to another cell
    points += rng.normal(0.0, 1e-4, points.shape) * np.linalg.norm(points, axis=1, keepdims=True)
    perm = rng.permutation(len(points))
    index = organize_scan(points[perm], spec)
    assert index.shape == (16, 90) and index.dtype == np.int64
    np.testing.assert_array_equal(perm[index.reshape(-1)], np.arange(16 * 90))


def test_dropped_returns_leave_empty_cells() -> None:
    spec = LidarSpec(channels=8, points_per_channel=40)
    rng = np.random.default_rng(1)
    returned = rng.random(8 * 40) < 0.6
    index = organize_scan(beam_points(spec, 20.0)[returned], spec).reshape(-1)
    np.testing.assert_array_equal(index >= 0, returned)
    np.testing.assert_array_equal(index[returned], np.arange(returned.sum()))


def test_collision_goes_to_the_point_nearest_the_cell_centre() -> None:
    spec = LidarSpec(channels=4, points_per_channel=16, hfov_deg=360.0, vfov_deg=(-30.0, 30.0))
    beam = spec.beam_directions(torch.float64)[2, 5].numpy()

    def turned(cells: float) -> np.ndarray:  # the beam rotated about z by a fraction of a column
        a = cells * spec.horizontal_resolution
        Rz = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
        return 7.0 * Rz @ beam

    far_off, near_centre = turned(0.3), turned(-0.1)
    for points, winner in (([far_off, near_centre], 1), ([near_centre, far_off], 0)):
        index = organize_scan(np.array(points), spec)
        assert index[2, 5] == winner and (index >= 0).sum() == 1
    # an exact tie (a duplicated return) goes to the lower point index
    assert organize_scan(np.array([far_off, near_centre, near_centre]), spec)[2, 5] == 1


def test_points_outside_the_fov_are_left_out() -> None:
    spec = LidarSpec(channels=4, points_per_channel=30, hfov_deg=270.0, vfov_deg=(-10.0, 10.0))
    cell = math.radians(270.0) / 30
    pts = np.array(
        [
            [-5.0, 0.0, 0.0],  # behind: azimuth 180 deg, outside the 270 deg FOV
            [5.0, 0.0, 5.0],  # 45 deg up, far above the top channel
            [0.0, 0.0, 0.0],  # no direction at all
            # 0.4 cell past the last column centre is still in the last cell
            [math.cos(math.radians(135.0) - 0.1 * cell), math.sin(math.radians(135.0) - 0.1 * cell), 0.0],
        ]
    )
    index = organize_scan(pts, spec)
    assert set(index[index >= 0].tolist()) == {3}
    assert (index == 3).sum() == 1 and index[:, -1].max() == 3


def test_full_circle_wraps_around() -> None:
    spec = LidarSpec(channels=2, points_per_channel=8, hfov_deg=360.0, vfov_deg=(0.0, 10.0))
    azimuths = np.radians([170.0, -170.0, 180.0, -180.0])
    index = organize_scan(np.stack([np.cos(azimuths), np.sin(azimuths), 0 * azimuths], 1), spec)
    assert index[0, 7] == 0 and index[0, 0] == 1  # column centres at 157.5 and -157.5 deg
    assert (index >= 0).sum() == 2  # the +-180 deg points lost the collisions but were not out of the FOV
    index = organize_scan(np.array([[-1.0, 0.0, 0.0]]), spec)  # exactly 180 deg, the seam between 7 and 0
    assert index[0, 0] == 0 or index[0, 7] == 0


def test_torch_in_torch_out_and_empty_scan() -> None:
    spec = LidarSpec(channels=4, points_per_channel=8)
    pts = torch.from_numpy(beam_points(spec, 5.0)).float()
    index = organize_scan(pts, spec)
    assert isinstance(index, torch.Tensor) and index.dtype == torch.int64
    np.testing.assert_array_equal(index.numpy(), organize_scan(pts.double().numpy(), spec))
    empty = organize_scan(np.zeros((0, 3), dtype=np.float32), spec)
    assert empty.shape == (4, 8) and (empty == -1).all()


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
