"""Drone flights: IMU consistent with the poses, collision-free, within the paper's ranges, yaw along velocity."""

from __future__ import annotations

import numpy as np
import pytest

from airfisheye_bench.synth.trajectory import GRAVITY, Flight, FlightConfig, UniformBSpline


class _Block:
    """Flat ground with one 30 m tall block across x in [-20, 20] (any y): flights must climb over it."""

    bounds = (-150.0, -150.0, 150.0, 150.0)

    def ground_height(self, xy):
        return np.zeros(len(xy))

    def obstacle_height(self, xy, radius):
        x = np.asarray(xy, np.float64)[:, 0]
        return np.where(np.abs(x) <= 20.0 + radius, 30.0, 0.0)


@pytest.fixture(scope="module")
def flights() -> list[Flight]:
    return [Flight.generate(_Block(), FlightConfig(), 400, np.random.default_rng(s)) for s in range(6)]


def _vee_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector of rotation matrices ``[N, 3, 3]`` (small angles)."""
    cos = np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1)
    angle = np.arccos(cos)
    w = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], 1)
    scale = np.where(angle < 1e-8, 0.5, angle / (2 * np.sin(np.maximum(angle, 1e-8))))
    return w * scale[:, None]


def test_bspline_derivatives_match_finite_differences():
    rng = np.random.default_rng(0)
    spline = UniformBSpline(rng.normal(size=(12, 2)), t0=-1.0, dt=0.7, degree=5)
    t = np.linspace(spline.t0 + 0.01, spline.t_end - 0.01, 50)
    h = 1e-5
    for r in range(1, 4):
        fd = (spline(t + h, r - 1) - spline(t - h, r - 1)) / (2 * h)
        assert np.allclose(spline(t, r), fd, atol=1e-4 * max(1.0, np.abs(fd).max()))


def test_imu_matches_finite_differences_of_the_poses(flights):
    for flight in flights:
        t = np.linspace(0.0, flight.duration_s, 300)
        h = 1e-3
        accel, gyro = flight.imu(t)
        # Specific force from the second difference of the positions, rotated into the body frame.
        p = flight.body_pose
        a_fd = (p(t + h)[:, :3, 3] - 2 * p(t)[:, :3, 3] + p(t - h)[:, :3, 3]) / h**2
        R = p(t)[:, :3, :3]
        f_fd = np.einsum("nji,nj->ni", R, a_fd + np.array([0.0, 0.0, GRAVITY]))
        assert np.abs(f_fd - accel).max() < 1e-3
        # Angular rate from the relative rotation over +-h.
        rel = np.einsum("nji,njk->nik", p(t - h)[:, :3, :3], p(t + h)[:, :3, :3])
        assert np.abs(_vee_log(rel) / (2 * h) - gyro).max() < 1e-4


def test_integrating_the_imu_file_samples_reproduces_the_attitude(flights):
    flight = flights[0]
    t = flight.imu_times()
    _, gyro = flight.imu(t)
    R = flight.body_pose(t[:1])[0, :3, :3]
    for k in range(len(t) - 1):  # trapezoidal rate, exact exponential map per step
        w = 0.5 * (gyro[k] + gyro[k + 1]) * (t[k + 1] - t[k])
        angle = np.linalg.norm(w)
        K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        step = (
            np.eye(3) + (np.sin(angle) / angle) * K + ((1 - np.cos(angle)) / angle**2) * (K @ K)
            if angle > 0
            else np.eye(3)
        )
        R = R @ step
    truth = flight.body_pose(t[-1:])[0, :3, :3]
    assert np.degrees(np.linalg.norm(_vee_log((R.T @ truth)[None]))) < 0.05


def test_flights_are_collision_free_and_within_ranges(flights):
    cfg = FlightConfig()
    scene = _Block()
    for flight in flights:
        t = np.linspace(0.0, flight.duration_s, 4000)
        pos = flight.position(t)
        floor = scene.obstacle_height(pos[:, :2], cfg.obstacle_radius_m) + cfg.clearance_m
        assert (pos[:, 2] >= floor - 1e-6).all()
        assert (
            pos[:, 2] <= cfg.altitude_m[1] + 30.0 + cfg.clearance_m
        ).all()  # only obstacles push it higher
        lo, hi = scene.bounds[0], scene.bounds[2]
        assert (pos[:, :2] > lo).all() and (pos[:, :2] < hi).all()
        assert cfg.gimbal_pitch_deg[0] <= flight.gimbal_pitch_deg <= cfg.gimbal_pitch_deg[1]
        assert cfg.lidar_delay_s[0] <= flight.lidar_delay_s <= cfg.lidar_delay_s[1]
        assert np.allclose(np.diff(flight.t_cam), 0.1) and np.allclose(
            flight.t_lidar - flight.t_cam, flight.lidar_delay_s
        )


def test_attitude_follows_the_motion(flights):
    for flight in flights:
        t = np.linspace(0.0, flight.duration_s, 500)
        R = flight.body_pose(t)[:, :3, :3]
        tilt = np.degrees(np.arccos(np.clip(R[:, 2, 2], -1, 1)))
        assert tilt.max() < 25.0 and tilt.mean() < 10.0  # small roll/pitch from the accelerations
        v = flight.position(t, 1)[:, :2]
        heading = np.arctan2(R[:, 1, 0], R[:, 0, 0])
        course = np.arctan2(v[:, 1], v[:, 0])
        diff = np.degrees(np.abs((heading - course + np.pi) % (2 * np.pi) - np.pi))
        assert np.median(diff) < 10.0 and diff.max() < 45.0  # yaw along the velocity
        # Thrust along body z: the specific force has no horizontal body component (ideal multirotor).
        accel, _ = flight.imu(t)
        assert np.abs(accel[:, :2]).max() < 1e-9 and (accel[:, 2] > 0).all()


def test_sensor_rig_offsets_and_gimbal(flights):
    for flight in flights:
        offset = np.linalg.norm(flight.T_body_lidar[:3, 3] - flight.T_body_cam[:3, 3])
        assert 0.1 < offset < 0.5  # tens of centimetres between camera and LiDAR
        optical_axis = flight.T_body_cam[:3, :3] @ np.array([0.0, 0.0, 1.0])  # camera z in the body frame
        pitch_down = np.degrees(np.arcsin(-optical_axis[2]))
        assert pitch_down == pytest.approx(flight.gimbal_pitch_deg, abs=1e-9)
        assert np.allclose(flight.T_body_lidar[:3, :3] @ np.array([1.0, 0, 0]), optical_axis)


def test_generation_is_deterministic():
    a = Flight.generate(_Block(), FlightConfig(), 50, np.random.default_rng(7))
    b = Flight.generate(_Block(), FlightConfig(), 50, np.random.default_rng(7))
    assert np.array_equal(a.body_pose(a.t_lidar), b.body_pose(b.t_lidar))


def test_flight_clears_a_generated_downtown():
    import torch

    from airfisheye_bench.synth.scene import Scene

    scene = Scene.generate("downtown", seed=1, size_m=200.0)
    cfg = FlightConfig(altitude_m=(1.5, 20.0))  # low flights: the buildings must push the path up
    for s in range(3):
        flight = Flight.generate(scene, cfg, 150, np.random.default_rng(s))
        t = np.linspace(0.0, flight.duration_s, 3000)
        pos = flight.position(t)
        floor = scene.obstacle_height(
            torch.tensor(pos[:, :2], dtype=torch.float32), cfg.obstacle_radius_m
        ).numpy()
        assert (pos[:, 2] >= floor + cfg.clearance_m - 1e-4).all()


def test_gimbal_and_start_altitude_can_be_fixed():
    class Flat(_Block):
        def obstacle_height(self, xy, radius):
            return np.zeros(len(xy))

    flight = Flight.generate(
        Flat(), FlightConfig(), 30, np.random.default_rng(0), gimbal_pitch_deg=30.0, start_altitude_m=50.0
    )
    assert flight.gimbal_pitch_deg == 30.0
    assert abs(flight.position(np.array([0.0]))[0, 2] - 50.0) < 5.0  # the altitude walk moves slowly
