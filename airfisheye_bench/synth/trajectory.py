"""Smooth drone flights through a scene: body poses, sensor timestamps and IMU readings.

A flight is a uniform quintic B-spline in time (``C^4``), so velocity, acceleration and jerk are analytic and the
IMU follows the poses exactly. Construction:

1. **Horizontal path.** Control points come from a random walk with slowly varying heading and speed that turns
   back towards the centre near the scene border; the spline stays inside the convex hull of its control points, so
   inside the scene.
2. **Altitude.** Each control point gets a target height above ground (a slow random walk in ``altitude_m``,
   0-65 m in the paper), raised to the highest obstacle (plus ``clearance_m``) found along the stretch of path
   that control point influences. A B-spline segment lies in the convex hull of its ``degree + 1`` control points,
   so the flight clears every obstacle sampled along it (collision-free up to the sampling density, which is
   covered by widening the obstacle query radius by half the sample spacing).
3. **Attitude.** Like a real multirotor, the thrust axis (body z) is aligned with ``a - g`` (a = acceleration,
   g = gravity), which gives small roll/pitch from acceleration, and the heading (body x) follows a spline through the
   direction of travel, so yaw follows the velocity. This is the differential-flatness attitude of a quadrotor.
4. **IMU.** Specific force ``f = R^T (a - g)`` and angular rate ``omega = vee(R^T dR/dt)``, both in the body frame
   (FLU), sampled at ``imu_rate_hz``; ``dR/dt`` is differentiated analytically (it needs the jerk).
5. **Sensors.** The camera and the LiDAR sit on a gimbal with a fixed downward pitch per flight (0-45 deg), the
   LiDAR a few tens of centimetres from the camera; the LiDAR scan is taken ``lidar_delay_s`` (20-50 ms) after the
   camera exposure, so the body moves between the two and ``T_cam_lidar`` must be motion-compensated.

Example:
    >>> import numpy as np
    >>> class Flat:  # any object with ground_height / obstacle_height / bounds works
    ...     bounds = (-100.0, -100.0, 100.0, 100.0)
    ...     def ground_height(self, xy): return np.zeros(len(xy))
    ...     def obstacle_height(self, xy, radius): return np.zeros(len(xy))
    >>> flight = Flight.generate(Flat(), FlightConfig(), num_frames=20, rng=np.random.default_rng(0))
    >>> flight.body_pose(flight.t_cam).shape
    (20, 4, 4)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import torch

from airfisheye_bench.geometry import portable
from airfisheye_bench.geometry.transforms import CAM_FROM_FLU, euler_to_matrix, make_transform

GRAVITY = 9.81
_E_Z = np.array([0.0, 0.0, 1.0])


class TerrainQuery(Protocol):
    """What a flight needs from a scene (``synth.scene.Scene`` satisfies it)."""

    bounds: tuple  # (xmin, ymin, xmax, ymax) in metres, or anything with those four numbers

    def ground_height(self, xy): ...

    def obstacle_height(self, xy, radius): ...


# ----------------------------------------------------------------------------------------- B-spline
class UniformBSpline:
    """Uniform B-spline of any degree in time with analytic derivatives.

    Segment ``j`` covers ``[t0 + j dt, t0 + (j + 1) dt]`` and blends control points ``j .. j + degree`` with the
    cardinal B-spline weights, so the curve is defined on ``[t0, t0 + (M - degree) dt]`` for ``M`` control points.

    Args:
        control: ``[M, D]`` control points.
        t0: Start time of the domain.
        dt: Knot spacing (seconds).
        degree: Polynomial degree (the curve is ``C^(degree-1)``).

    Example:
        >>> import numpy as np
        >>> spline = UniformBSpline(np.arange(8.0)[:, None], t0=0.0, dt=1.0, degree=3)  # a straight line
        >>> spline(np.array([0.5]), derivative=1).round(9).tolist()
        [[1.0]]
    """

    def __init__(self, control: np.ndarray, t0: float, dt: float, degree: int = 5) -> None:
        control = np.asarray(control, np.float64)
        if control.ndim != 2 or control.shape[0] <= degree:
            raise ValueError(
                f"control must have shape [M > degree, D], got {control.shape} for degree {degree}"
            )
        if dt <= 0:
            raise ValueError(f"dt must be positive, got {dt}")
        self.control, self.t0, self.dt, self.degree = control, float(t0), float(dt), int(degree)

    @property
    def t_end(self) -> float:
        return self.t0 + (self.control.shape[0] - self.degree) * self.dt

    def __call__(self, t: np.ndarray, derivative: int = 0) -> np.ndarray:
        """Value (or ``derivative``-th time derivative, ``< degree``) at times ``t [N]`` -> ``[N, D]``."""
        k = self.degree
        if not 0 <= derivative < k:
            raise ValueError(f"derivative must be in [0, {k - 1}], got {derivative}")
        x = (np.asarray(t, np.float64) - self.t0) / self.dt
        j = np.clip(np.floor(x), 0, self.control.shape[0] - k - 1).astype(np.int64)
        u = x - j
        out = np.zeros((x.shape[0], self.control.shape[1]))
        for m in range(k + 1):
            w = _cardinal_bspline(u + k - m, k, derivative)
            out += w[:, None] * self.control[j + m]
        return out / self.dt**derivative

    def support(self, index: int) -> tuple[float, float]:
        """Time interval in which control point ``index`` influences the curve (clipped to the domain)."""
        lo = self.t0 + (index - self.degree) * self.dt
        hi = self.t0 + (index + 1) * self.dt
        return max(lo, self.t0), min(hi, self.t_end)


def _cardinal_bspline(x: np.ndarray, k: int, r: int) -> np.ndarray:
    """``r``-th derivative of the cardinal B-spline of degree ``k`` (support ``[0, k + 1]``) at ``x``."""
    out = np.zeros_like(x)
    for l in range(k + 2):  # noqa: E741 - the usual name in the truncated-power formula
        coef = (-1) ** l * math.comb(k + 1, l) / math.factorial(k - r)
        out += coef * _integer_power(np.clip(x - l, 0.0, None), k - r)
    return out


def _integer_power(x: np.ndarray, n: int) -> np.ndarray:
    """``x ** n`` by repeated multiplication: numpy's ``power`` takes SVML on AVX-512 CPUs and its own kernel
    elsewhere, which differ in the last bit, and the poses written from these splines must be the same on every
    CPU (``docs/design.md``, "The same data on every CPU")."""
    out = np.ones_like(x)
    for _ in range(n):
        out = out * x
    return out


# ----------------------------------------------------------------------------------------- configs
@dataclass(frozen=True)
class SensorRig:
    """Mounting of the sensors on the drone body (FLU).

    Attributes:
        camera_offset_m: Camera centre (gimbal centre) in the body frame.
        lidar_offset_in_gimbal_m: LiDAR origin relative to the camera, in the gimbal's FLU axes (tens of cm).
    """

    camera_offset_m: tuple[float, float, float] = (0.15, 0.0, -0.12)
    lidar_offset_in_gimbal_m: tuple[float, float, float] = (-0.05, 0.10, 0.25)

    def T_body_cam(self, gimbal_pitch_deg: float) -> np.ndarray:
        """Camera (OpenCV axes) -> body, for a gimbal pitched ``gimbal_pitch_deg`` down."""
        R_gimbal = euler_to_matrix(0.0, math.radians(gimbal_pitch_deg), 0.0)
        return make_transform(R_gimbal @ CAM_FROM_FLU.T, np.asarray(self.camera_offset_m))

    def T_body_lidar(self, gimbal_pitch_deg: float) -> np.ndarray:
        """LiDAR (FLU axes, looking along the camera's optical axis) -> body."""
        R_gimbal = euler_to_matrix(0.0, math.radians(gimbal_pitch_deg), 0.0)
        t = np.asarray(self.camera_offset_m) + R_gimbal @ np.asarray(self.lidar_offset_in_gimbal_m)
        return make_transform(R_gimbal, t)


@dataclass(frozen=True)
class FlightConfig:
    """Random flight parameters (ranges are sampled once per flight unless noted).

    Attributes:
        frame_rate_hz: Camera/LiDAR frame rate (10 Hz in the paper).
        imu_rate_hz: IMU sample rate.
        altitude_m: Range of the target height above ground (paper: 0-65 m), varied along the flight.
        speed_mps: Range of the cruise speed, varied along the flight.
        gimbal_pitch_deg: Range of the (per-flight) gimbal pitch below the horizon (paper: 0-45 deg).
        lidar_delay_s: Range of the LiDAR timestamp offset after the camera (per flight).
        clearance_m: Minimum distance kept above obstacles (and the ground).
        obstacle_radius_m: Horizontal radius searched for obstacles around the path.
        knot_interval_s: Spacing of the spline's control points in time.
        degree: Spline degree (5: continuous jerk, so continuous angular rates).
        border_margin_m: Distance kept from the scene border.
        turn_rate_deg: Standard deviation of the heading change per knot.
        climb_rate_mps: Largest climb/descent rate between control points (obstacles are cleared by climbing
            early rather than steeply).
        rig: Sensor mounting.
    """

    frame_rate_hz: float = 10.0
    imu_rate_hz: float = 100.0
    altitude_m: tuple[float, float] = (1.5, 65.0)
    speed_mps: tuple[float, float] = (2.0, 8.0)
    gimbal_pitch_deg: tuple[float, float] = (0.0, 45.0)
    lidar_delay_s: tuple[float, float] = (0.02, 0.05)
    clearance_m: float = 2.0
    obstacle_radius_m: float = 3.0
    knot_interval_s: float = 2.0
    degree: int = 5
    border_margin_m: float = 30.0
    turn_rate_deg: float = 12.0
    climb_rate_mps: float = 2.5
    rig: SensorRig = field(default_factory=SensorRig)

    def __post_init__(self) -> None:
        for name in ("altitude_m", "speed_mps", "gimbal_pitch_deg", "lidar_delay_s"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise ValueError(f"FlightConfig.{name} must be (low, high) with low <= high, got {(lo, hi)}")
        if self.altitude_m[0] < 0 or self.speed_mps[0] <= 0 or self.lidar_delay_s[0] < 0:
            raise ValueError("FlightConfig: altitude_m, lidar_delay_s must be >= 0 and speed_mps > 0")
        if not self.gimbal_pitch_deg[0] >= 0 and self.gimbal_pitch_deg[1] <= 90:
            raise ValueError(
                f"FlightConfig.gimbal_pitch_deg must lie in [0, 90], got {self.gimbal_pitch_deg}"
            )
        if self.frame_rate_hz <= 0 or self.imu_rate_hz <= 0:
            raise ValueError("FlightConfig.frame_rate_hz and imu_rate_hz must be positive")


# ----------------------------------------------------------------------------------------- flight
@dataclass
class Flight:
    """One recorded flight: continuous body trajectory plus the sampled sensor timestamps.

    Attributes:
        position: Spline of the body position (world, metres).
        yaw: Spline of the heading (radians, unwrapped).
        t_cam: ``[N]`` camera timestamps (s); the first frame is at ``t = 0``.
        t_lidar: ``[N]`` LiDAR timestamps, ``t_cam + lidar_delay_s``.
        gimbal_pitch_deg: Gimbal pitch of this flight.
        lidar_delay_s: LiDAR delay of this flight.
        T_body_cam: ``[4, 4]`` camera -> body.
        T_body_lidar: ``[4, 4]`` LiDAR -> body.
        imu_rate_hz: IMU sample rate.
    """

    position: UniformBSpline
    yaw: UniformBSpline
    t_cam: np.ndarray
    t_lidar: np.ndarray
    gimbal_pitch_deg: float
    lidar_delay_s: float
    T_body_cam: np.ndarray
    T_body_lidar: np.ndarray
    imu_rate_hz: float

    # ------------------------------------------------------------------------------ generation
    @classmethod
    def generate(
        cls,
        scene: TerrainQuery,
        config: FlightConfig,
        num_frames: int,
        rng: np.random.Generator,
        gimbal_pitch_deg: float | None = None,
        start_altitude_m: float | None = None,
    ) -> Flight:
        """Sample a collision-free flight of ``num_frames`` frames over ``scene``.

        Args:
            scene: Ground and obstacle heights, bounds.
            config: Flight parameter ranges.
            num_frames: Frames to record (at ``config.frame_rate_hz``).
            rng: Source of randomness.
            gimbal_pitch_deg: Fixed gimbal pitch instead of a draw from ``config.gimbal_pitch_deg`` (the writer
                stratifies it over the trajectories so that every split sees the whole range).
            start_altitude_m: Initial target height above ground instead of a draw from ``config.altitude_m``.
        """
        if num_frames < 1:
            raise ValueError(f"num_frames must be >= 1, got {num_frames}")
        cfg = config
        k, dt = cfg.degree, cfg.knot_interval_s
        drawn = float(rng.uniform(*cfg.gimbal_pitch_deg))  # drawn anyway: the rng stream stays the same
        gimbal = drawn if gimbal_pitch_deg is None else float(gimbal_pitch_deg)
        delay = float(rng.uniform(*cfg.lidar_delay_s))
        duration = (num_frames - 1) / cfg.frame_rate_hz + delay
        num_ctrl = math.ceil(duration / dt) + k + 1
        xmin, ymin, xmax, ymax = (float(v) for v in _bounds(scene))
        margin = min(cfg.border_margin_m, 0.25 * (xmax - xmin), 0.25 * (ymax - ymin))
        lo, hi = np.array([xmin + margin, ymin + margin]), np.array([xmax - margin, ymax - margin])

        xy = _random_walk(rng, num_ctrl, lo, hi, cfg, dt)
        # The domain starts at t0 so that the first frame (t = 0) sits one knot into the curve.
        t0 = -dt
        xy_spline = UniformBSpline(np.concatenate([xy, np.zeros((num_ctrl, 1))], 1), t0, dt, k)

        # Heading: direction of the control polygon, unwrapped so the yaw spline never jumps by 2 pi.
        d = np.gradient(xy, axis=0)
        yaw_ctrl = np.unwrap(portable.arctan2(d[:, 1], d[:, 0]))

        # Altitude: target height above ground, raised to clear everything under the control point's support.
        alt_step = 0.02 * (cfg.altitude_m[1] - cfg.altitude_m[0])
        alt = _smooth_walk(rng, num_ctrl, *cfg.altitude_m, step=alt_step, start=start_altitude_m)
        ground_ctrl = _heights(scene.ground_height, xy)
        samples_per_knot = 8
        ts = np.linspace(t0, xy_spline.t_end, (num_ctrl - k) * samples_per_knot + 1)
        pts = xy_spline(ts)[:, :2]
        spacing = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).max()) if len(pts) > 1 else 0.0
        floor = np.maximum(
            _heights(lambda q: scene.obstacle_height(q, cfg.obstacle_radius_m + 0.5 * spacing), pts),
            _heights(scene.ground_height, pts),
        )
        floor = floor + cfg.clearance_m
        z = ground_ctrl + alt
        for i in range(num_ctrl):
            a, b = xy_spline.support(i)
            inside = (ts >= a - 1e-9) & (ts <= b + 1e-9)
            z[i] = max(z[i], floor[inside].max())
        z = _limit_slope(z, cfg.climb_rate_mps * dt)
        position = UniformBSpline(np.concatenate([xy, z[:, None]], 1), t0, dt, k)
        yaw = UniformBSpline(yaw_ctrl[:, None], t0, dt, k)

        t_cam = np.arange(num_frames) / cfg.frame_rate_hz
        return cls(
            position=position,
            yaw=yaw,
            t_cam=t_cam,
            t_lidar=t_cam + delay,
            gimbal_pitch_deg=gimbal,
            lidar_delay_s=delay,
            T_body_cam=cfg.rig.T_body_cam(gimbal),
            T_body_lidar=cfg.rig.T_body_lidar(gimbal),
            imu_rate_hz=cfg.imu_rate_hz,
        )

    # -------------------------------------------------------------------------------- kinematics
    def attitude(self, t: np.ndarray, with_rate: bool = False):
        """Body rotation ``R_world_body [N, 3, 3]`` (and angular rate ``[N, 3]`` in the body frame)."""
        t = np.asarray(t, np.float64)
        acc = self.position(t, 2)
        psi = self.yaw(t)[:, 0]
        v = acc + GRAVITY * _E_Z  # thrust direction: specific force in the world frame
        nv = np.linalg.norm(v, axis=1, keepdims=True)
        zb = v / nv
        cos_psi, sin_psi = portable.cos(psi), portable.sin(psi)  # the same bits on every CPU: see portable
        xc = np.stack([cos_psi, sin_psi, np.zeros_like(psi)], 1)
        w = np.cross(zb, xc)
        nw = np.linalg.norm(w, axis=1, keepdims=True)
        yb = w / nw
        xb = np.cross(yb, zb)
        R = np.stack([xb, yb, zb], axis=2)
        if not with_rate:
            return R
        jerk = self.position(t, 3)
        psi_dot = self.yaw(t, 1)[:, 0]
        zb_dot = _project_out(zb, jerk) / nv
        xc_dot = psi_dot[:, None] * np.stack([-sin_psi, cos_psi, np.zeros_like(psi)], 1)
        w_dot = np.cross(zb_dot, xc) + np.cross(zb, xc_dot)
        yb_dot = _project_out(yb, w_dot) / nw
        xb_dot = np.cross(yb_dot, zb) + np.cross(yb, zb_dot)
        R_dot = np.stack([xb_dot, yb_dot, zb_dot], axis=2)
        Omega = np.einsum("nji,njk->nik", R, R_dot)  # R^T dR/dt, skew-symmetric
        omega = np.stack([Omega[:, 2, 1], Omega[:, 0, 2], Omega[:, 1, 0]], 1)
        return R, omega

    def body_pose(self, t: np.ndarray) -> np.ndarray:
        """``T_world_body [N, 4, 4]`` at times ``t [N]``."""
        t = np.asarray(t, np.float64)
        return make_transform(self.attitude(t), self.position(t))

    def imu(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ideal IMU at ``t``: specific force ``R^T (a - g)`` (m/s^2) and angular rate (rad/s), body frame."""
        t = np.asarray(t, np.float64)
        R, omega = self.attitude(t, with_rate=True)
        f_world = self.position(t, 2) + GRAVITY * _E_Z
        return np.einsum("nji,nj->ni", R, f_world), omega

    def imu_times(self) -> np.ndarray:
        """IMU timestamps covering the frames: ``0, 1/rate, ...`` up to the last LiDAR timestamp."""
        n = math.floor(self.t_lidar[-1] * self.imu_rate_hz + 1e-9) + 1
        return np.arange(n) / self.imu_rate_hz

    @property
    def duration_s(self) -> float:
        return float(self.t_lidar[-1])


# ----------------------------------------------------------------------------------------- helpers
def _bounds(scene: TerrainQuery) -> np.ndarray:
    b = scene.bounds
    b = np.asarray(
        b.tolist() if hasattr(b, "tolist") and not isinstance(b, np.ndarray) else b, np.float64
    ).ravel()
    if b.shape != (4,):
        raise ValueError(f"scene.bounds must hold (xmin, ymin, xmax, ymax), got {b}")
    return b


def _heights(fn, xy: np.ndarray) -> np.ndarray:
    """Call a scene height query with a float32 torch tensor and return float64 numpy (accepts numpy answers)."""
    out = fn(torch.as_tensor(np.ascontiguousarray(xy), dtype=torch.float32))
    if isinstance(out, torch.Tensor):
        out = out.detach().cpu().numpy()
    return np.asarray(out, np.float64).reshape(len(xy))


def _project_out(n: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(I - n n^T) v`` row-wise."""
    return v - np.sum(n * v, axis=1, keepdims=True) * n


def _limit_slope(z: np.ndarray, max_step: float) -> np.ndarray:
    """Raise values (never lower them) until neighbours differ by at most ``max_step``.

    The result is the smallest sequence ``>= z`` with bounded slope: ``max_j z_j - max_step |i - j|``.
    """
    i = np.arange(len(z))
    return np.max(z[None, :] - max_step * np.abs(i[:, None] - i[None, :]), axis=1)


def _smooth_walk(
    rng: np.random.Generator, n: int, lo: float, hi: float, step: float, start: float | None = None
) -> np.ndarray:
    """A random walk with inertia (its rate of change is itself a damped random walk), reflected into ``[lo, hi]``.

    The inertia keeps second differences small, hence small accelerations once splined. The walk starts at
    ``start`` (clipped into the range) if given, else at a uniform draw (drawn in both cases, so the random
    stream does not depend on ``start``).
    """
    out = np.empty(n)
    x = rng.uniform(lo, hi)
    if start is not None:
        x = min(max(float(start), lo), hi)
    rate = 0.0
    for i in range(n):
        out[i] = x
        rate = 0.7 * rate + rng.normal(0.0, step)
        x += rate
        if x < lo or x > hi:
            x = min(max(2 * lo - x if x < lo else 2 * hi - x, lo), hi)
            rate = -rate
    return out


def _random_walk(
    rng: np.random.Generator, n: int, lo: np.ndarray, hi: np.ndarray, cfg: FlightConfig, dt: float
):
    """Horizontal control points: slowly turning, speed-varying walk kept inside ``[lo, hi]``."""
    speed = _smooth_walk(rng, n, *cfg.speed_mps, step=0.05 * (cfg.speed_mps[1] - cfg.speed_mps[0]))
    pos = rng.uniform(lo, hi)
    heading = rng.uniform(-math.pi, math.pi)
    centre = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    out = np.empty((n, 2))
    turn = math.radians(cfg.turn_rate_deg)
    for i in range(n):
        out[i] = pos
        heading += rng.normal(0.0, turn)
        step = speed[i] * dt
        nxt = pos + step * np.array([math.cos(heading), math.sin(heading)])
        # Near the border, steer towards the centre (at most 20 deg per knot keeps the turn gentle).
        if np.any(np.abs(nxt - centre) > 0.7 * half):
            to_centre = math.atan2(*(centre - pos)[::-1])
            diff = (to_centre - heading + math.pi) % (2 * math.pi) - math.pi
            heading += float(np.clip(diff, -math.pi / 9, math.pi / 9))
            nxt = pos + step * np.array([math.cos(heading), math.sin(heading)])
        pos = np.clip(nxt, lo, hi)
    return out
