"""A planned trajectory made ready to render: its seeds, scene, flight, lighting and per-frame sensor poses.

Everything here is deterministic in ``(seed, environment, trajectory index)``: a trajectory's scene, flight and
lighting never depend on which other trajectories are generated, nor on the LiDAR scan model (its phase, jitter and
dropout have a seed stream of their own).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np
import torch

from airfisheye_bench.synth.presets import SynthConfig, TrajectoryPlan
from airfisheye_bench.synth.scene import Lighting, Scene
from airfisheye_bench.synth.trajectory import Flight


@dataclass
class TrajectoryRecording:
    """A trajectory ready to render: its plan, scene, flight, lighting and per-frame sensor poses."""

    plan: TrajectoryPlan
    scene: Scene
    flight: Flight
    lighting: Lighting
    T_world_body_cam: np.ndarray  # [N, 4, 4] at t_cam
    T_world_body_lidar: np.ndarray  # [N, 4, 4] at t_lidar
    scan_seed: int = 0  # seeds the LiDAR's per-frame phase, jitter and dropout (scan_rng)

    def T_world_cam(self, i: int) -> np.ndarray:
        return self.T_world_body_cam[i] @ self.flight.T_body_cam

    def T_world_lidar(self, i: int) -> np.ndarray:
        return self.T_world_body_lidar[i] @ self.flight.T_body_lidar


def trajectory_seeds(seed: int, plan: TrajectoryPlan) -> tuple[int, int, int, int]:
    """Scene, flight, lighting and stratum-jitter seeds of a trajectory, from ``(seed, environment, index)`` only."""
    ss = np.random.SeedSequence([int(seed), zlib.crc32(plan.env.encode()), int(plan.index)])
    scene_seed, flight_seed, light_seed, strata_seed = (int(v) for v in ss.generate_state(4))
    return scene_seed, flight_seed, light_seed, strata_seed


def scan_seed(seed: int, plan: TrajectoryPlan) -> int:
    """Seed of a trajectory's LiDAR phase, jitter and dropout: a stream of its own, so that the seeds of
    :func:`trajectory_seeds` (and the bytes of datasets with ideal scans) do not depend on the scan model."""
    ss = np.random.SeedSequence([int(seed), zlib.crc32(plan.env.encode()), int(plan.index), 1])
    return int(ss.generate_state(1)[0])


def scan_rng(scan_seed: int, frame: int) -> np.random.Generator:
    """The generator of frame ``frame``'s LiDAR phase, jitter and dropout (depends on the trajectory and frame only)."""
    return np.random.default_rng([int(scan_seed), int(frame)])


def stratified_value(index: int, count: int, low: float, high: float, phase: float, jitter: float) -> float:
    """A value in ``[low, high]`` for trajectory ``index`` of ``count``, spread evenly over the trajectories.

    Trajectory ``i`` takes the fraction ``(i * 0.618... + phase) mod 1`` (a golden-ratio sequence: any run of
    consecutive indices, e.g. the validation or test trajectories, covers the range evenly), moved by
    ``jitter`` (in ``[-0.5, 0.5]``) times the spacing ``1 / count``.

    Example:
        >>> sorted(round(stratified_value(i, 4, 0.0, 40.0, phase=0.0, jitter=0.0)) for i in range(4))
        [0, 9, 25, 34]
    """
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    frac = (index * golden + phase + jitter / max(count, 1)) % 1.0
    return low + (high - low) * frac


def build_trajectory(
    config: SynthConfig, seed: int, plan: TrajectoryPlan, device: str = "cpu"
) -> TrajectoryRecording:
    """Generate the scene, flight and lighting of one planned trajectory (deterministic)."""
    scene_seed, flight_seed, light_seed, strata_seed = trajectory_seeds(seed, plan)
    scene = Scene.generate(plan.env, scene_seed, size_m=config.scene_size_m, device=device)
    # Gimbal pitch and starting altitude are stratified over the trajectories: with a dozen trajectories,
    # independent draws often leave a split without steep or high views.
    jitter = np.random.default_rng(strata_seed).uniform(-0.5, 0.5, size=2)
    n, fc = config.num_trajectories, config.flight
    flight = Flight.generate(
        scene,
        fc,
        plan.num_frames,
        np.random.default_rng(flight_seed),
        gimbal_pitch_deg=stratified_value(plan.index, n, *fc.gimbal_pitch_deg, phase=0.1, jitter=jitter[0]),
        start_altitude_m=stratified_value(plan.index, n, *fc.altitude_m, phase=0.45, jitter=jitter[1]),
    )
    lighting = Lighting.random(torch.Generator().manual_seed(light_seed))
    return TrajectoryRecording(
        plan,
        scene,
        flight,
        lighting,
        flight.body_pose(flight.t_cam),
        flight.body_pose(flight.t_lidar),
        scan_seed(seed, plan),
    )


def frame_phases(rec: TrajectoryRecording, config: SynthConfig) -> np.ndarray:
    """The LiDAR azimuth phase of every frame of a trajectory (radians), as the writer draws them."""
    scan, spec = config.scan_model(), config.lidar_spec()
    return np.array(
        [scan.frame_phase(spec, t, scan_rng(rec.scan_seed, i)) for i, t in enumerate(rec.flight.t_lidar)]
    )


def frame_name(index: int) -> str:
    return f"{index:06d}"
