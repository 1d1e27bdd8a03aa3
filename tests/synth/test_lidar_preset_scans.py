"""The generator simulates a real sensor's layout (``lidar.preset=hdl64e``): its table, offsets and beam origins."""

from __future__ import annotations

import numpy as np
import pytest

from airfisheye_bench.geometry import make_transform, transform_points
from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.lidar_layout import rings_from_elevation
from airfisheye_bench.synth.builder import SceneBuilder
from airfisheye_bench.synth.cli import build_config
from airfisheye_bench.synth.dataset_yaml import dataset_spec
from airfisheye_bench.synth.presets import SynthConfig, get_preset, plan_trajectories
from airfisheye_bench.synth.scene import Scene
from airfisheye_bench.synth.sensors import lidar_visibility, scan_lidar

HDL64E = LidarSpec.from_preset("hdl64e", points_per_channel=256)


@pytest.fixture(scope="module")
def walled_scene() -> Scene:
    b = SceneBuilder(size_m=200.0, rng=np.random.default_rng(0))
    b.add_box(0.0, 12.0, 0.0, 10.0, 1.0, 8.0, 0.0, "wall", (0.5, 0.5, 0.5))
    b.add_box(3.0, -2.5, 0.0, 1.0, 1.0, 3.0, 0.0, "wall", (0.5, 0.5, 0.5))  # a near box, 2-3 m away
    return Scene(b.finish())


def test_beams_start_at_their_lasers_origins(walled_scene: Scene) -> None:
    T_world_lidar = make_transform(np.eye(3), np.array([0.0, 0.0, 1.73]))
    points, world, beam = scan_lidar(walled_scene, T_world_lidar, HDL64E)
    assert len(points) > 5000
    # world positions are where the beams hit: the stored points are them in the LiDAR frame
    assert (
        np.abs(transform_points(T_world_lidar, points[:, :3].astype(np.float64)) - world.numpy()).max() < 1e-3
    )
    channel = beam // HDL64E.points_per_channel
    xyz = points[:, :3].astype(np.float64)
    # seen from its own laser's origin, every return lies on its channel's elevation (exactly, up to float32)
    direction = xyz - HDL64E.beam_origins(np.arctan2(xyz[:, 1], xyz[:, 0]), channel)
    _, _, el = spherical_coordinates(direction)
    assert np.abs(el - HDL64E.channel_elevations()[channel]).max() < 1e-4
    # seen from the centre the near returns are biased (the upper block starts ~0.2 m up) ...
    r, _, el_centre = spherical_coordinates(xyz)
    near = r < 4.0
    assert near.sum() > 100 and np.abs(el_centre - HDL64E.channel_elevations()[channel])[near].max() > 0.02
    # ... and the channel table with the beam origins still finds every ring
    assert (rings_from_elevation(r, el_centre, HDL64E) == channel)[r > 2.0].mean() >= 0.999
    assert lidar_visibility(walled_scene, np.array([0.3, 0.0, 1.8]), world).any()


def test_lidar_preset_in_the_generator_config() -> None:
    config = build_config("tiny", {"lidar.preset": "hdl64e"})
    assert config.lidar_preset == "hdl64e" and config.lidar_spec() == LidarSpec.from_preset("hdl64e")
    assert SynthConfig.from_dict(config.to_dict()) == config
    assert "lidar_preset" not in get_preset("tiny").to_dict()  # the existing presets keep their identity
    spec = dataset_spec(config, 0, plan_trajectories(config, ["suburban"]))
    assert "lidar_beam" in spec.contents and "lidar_scan" not in spec.contents
    assert spec.sensors["lidar"]["elevations_deg"][0] == pytest.approx(-24.999201)
    with pytest.raises(ValueError, match="lidar_preset must be one of"):
        get_preset("tiny").replace(lidar_preset="hdl65e")
