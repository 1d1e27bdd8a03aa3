"""The LiDAR part of a served sample (``sparse_depth``, and ``depth`` from points): the scan filtered and its rings
resolved, projected through the sample's camera with the split's occlusion correction, at the paper's density or
every return. A mixin of :class:`~datamodules.dataset.AirFisheyeDataset`, which sets what it reads: ``reader``,
``lidar_spec``, ``lidar_min_range``, ``lidar_density``, ``lidar_counts``, ``occlusion``, ``motion_compensation``,
``max_depth``, ``parallax_free``, ``camera``, ``served_lenses``, ``gimbal``, ``source`` (docs/design.md, "Sparse
depth map", "Sparse input density").
"""

from __future__ import annotations

import logging

import numpy as np
import torch

from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_density import (
    PAPER_IMAGE_SIZE,
    paper_density_subset,
    paper_scale_camera,
    reading_size,
)
from airfisheye_bench.geometry.occlusion import (
    ORACLE,
    Occlusion,
    lidar_depth_map,
    occlusion_mask,
)
from airfisheye_bench.geometry.rings import resolve_rings
from airfisheye_bench.geometry.scan_filter import filter_scan
from airfisheye_bench.io import DatasetFormatError
from datamodules.augment import rotation_about_optical_axis
from datamodules.oracle import oracle_visible

log = logging.getLogger(__name__)


class LidarServing:
    """The LiDAR of a sample: the filtered scan, ``T_cam_lidar`` and the sparse and point depth maps."""

    def lidar_points(self, sample_id: str) -> tuple[np.ndarray, np.ndarray, LidarSpec]:
        """``(points float64 [M, 3], rings int64 [M], spec)`` of a frame after the counted filtering."""
        return self.filtered_scan(sample_id)[:3]

    def filtered_scan(self, sample_id: str) -> tuple[np.ndarray, np.ndarray, LidarSpec, np.ndarray]:
        """:meth:`lidar_points` and the ``bool [N]`` mask of the scan's points it keeps (for per-point data)."""
        if self.lidar_spec is None:  # the source's own LiDAR
            spec, scan = self.reader.calib(sample_id).lidar_spec(), self.reader.lidar_scan(sample_id)
        else:  # data.lidar.preset's: cast where the source simulates its LiDAR from depth
            spec, scan = self.lidar_spec, self.reader.cast_scan(sample_id, self.lidar_spec)
        if len(scan.points) == 0:
            raise DatasetFormatError(scan.path, "the LiDAR scan is empty")
        if not np.isfinite(scan.points).all():
            raise DatasetFormatError(scan.path, "the LiDAR scan has non-finite coordinates")
        try:
            rings, source = resolve_rings(scan.points, spec, scan.rings, scan.firing_order)
        except ValueError as err:  # a ring field that does not fit the spec
            raise DatasetFormatError(scan.path, f"{err} (LiDAR spec: {spec.name or 'calib.yaml'})") from None
        kept = filter_scan(scan.points, rings, self.lidar_min_range)
        counts = {
            "scans": 1,
            f"rings from {source}": 1,
            "returns": len(scan.points) + scan.no_returns,
            "no_returns": scan.no_returns,
            **kept.counts(),
        }
        first = not self.lidar_counts
        for key, value in counts.items():
            self.lidar_counts[key] = self.lidar_counts.get(key, 0) + value
        if first:
            log.info(
                "LiDAR %s: rings from %s; removed %d returns within %.2f m, %d no channel explains, %d empty "
                "cells (of %d)",
                scan.path.name,
                source,
                kept.near_origin,
                self.lidar_min_range,
                kept.unexplained,
                scan.no_returns,
                counts["returns"],
            )
        points = scan.points[kept.keep]
        if self.motion_compensation:  # the sweep's points at its reference time
            points = self.reader.deskew(sample_id, points)
        return points, rings[kept.keep], spec, kept.keep

    def _sparse_depth(
        self, sample_id: str, params, turn: np.ndarray | None = None, camera: CameraModel | None = None
    ) -> torch.Tensor:
        """The LiDAR range map of a frame through ``camera`` (the sample's lens; ``None``: the served camera)."""
        camera = self.camera if camera is None else camera
        points, rings, spec, keep = self.filtered_scan(sample_id)
        method = self.occlusion
        if self.parallax_free:  # every return is seen by the camera: nothing to correct
            method = Occlusion("none")
        elif (
            isinstance(method, str) and method == ORACLE
        ):  # the truly visible points, projected without a test
            visible = oracle_visible(self.reader, sample_id, keep)
            points, rings, method = points[visible], rings[visible], Occlusion("none")
        T = _augmented(_turned(self.T_cam_lidar(sample_id), turn), params)
        image_size = reading_size(self.lidar_density)  # the paper's image this density counts returns on
        if image_size is not None:
            subset = paper_density_subset(
                spec, max(camera.width, camera.height), camera.coverage_deg, image_size=image_size
            )
            if (method.method if isinstance(method, Occlusion) else method) != "none":
                # The correction decides on the whole scan at the reading image's pixel scale, as the paper's
                # pipeline would; the subset of its kept returns is served (docs/design.md, "Sparse input density").
                visible = self._paper_scale_visible(
                    sample_id, points, T, spec, method, rings, params, turn, camera, image_size
                )
                points, rings, method = points[visible], rings[visible], Occlusion("none")
            served = subset.mask(points, rings, spec)
            points, rings = points[served], rings[served]
        depth = lidar_depth_map(
            points,
            T,
            camera,
            spec,
            method=method,
            max_depth=self.max_depth,
            mirror=params is not None and params.flip,
            rings=rings,
        )
        return torch.from_numpy(depth)[None]

    def _paper_scale_visible(
        self,
        sample_id,
        points,
        T,
        spec,
        method,
        rings,
        params,
        turn=None,
        camera=None,
        image_size=PAPER_IMAGE_SIZE,
    ) -> np.ndarray:
        """The correction's mask on the whole scan at the pixel scale of the reading's ``image_size``^2 image (the
        paper's 1536^2 by default; 1-2 s a frame at 1536^2 for the
        image-based methods). Without a rotation it is the same every epoch (a flip mirrors the kept points
        afterwards), so it is kept per frame (and lens of ``data.camera.lenses``) for the life of the worker: a few MB
        for a few hundred frames. A gimbal view that varies per sample is a rotation too, and a jittered lens a
        camera of its own."""
        camera = self.camera if camera is None else camera
        varying_view = turn is not None and (self.gimbal is None or self.gimbal.fixed is None)
        # The index of an unjittered lens of the list (the remap's camera is that lens's own object), else None.
        lens = next((i for i, s in enumerate(self.served_lenses) if s.camera is camera), None)
        cacheable = (params is None or params.angle_rad == 0.0) and not varying_view and lens is not None
        key = (sample_id, lens)
        if cacheable and key in self._visible_cache:
            return self._visible_cache[key]
        visible = np.asarray(
            occlusion_mask(points, T, paper_scale_camera(camera, image_size), spec, method, rings)
        )
        if cacheable:
            self._visible_cache[key] = visible
        return visible

    def _point_depth(
        self, sample_id: str, params, turn: np.ndarray | None = None, camera: CameraModel | None = None
    ) -> torch.Tensor:
        """The depth target of a source that gives it as LiDAR points (``depth_points``), ``[1, H, W]``: projected
        at the served camera with the sample's augmentation, as ``sparse_depth`` (no resampling of a sparse map),
        its own occlusion removed, always motion-compensated (it is the ground truth)."""
        target = self.reader.depth_points(sample_id, self.lidar_min_range)
        spec = self.lidar_spec or self.reader.calib(sample_id).lidar_spec()
        depth = lidar_depth_map(
            target.points,
            _augmented(_turned(np.asarray(self.reader.T_cam_lidar(sample_id), np.float64), turn), params),
            self.camera if camera is None else camera,
            spec,
            method=Occlusion(target.occlusion, target.occlusion_options),
            max_depth=self.max_depth,
            mirror=params is not None and params.flip,
        )
        return torch.from_numpy(depth)[None]

    def T_cam_lidar(self, sample_id: str) -> np.ndarray:
        """``[4, 4]`` float64 LiDAR -> camera transform of a frame.

        With ``motion_compensation`` it comes from the two sensors' poses at their own timestamps (the platform
        moves between the camera exposure and the LiDAR sweep); without, from the static extrinsics only.
        """
        if self.motion_compensation:
            return np.asarray(self.reader.T_cam_lidar(sample_id), dtype=np.float64)
        return np.asarray(self.reader.calib(sample_id).T_cam_lidar_static, dtype=np.float64)


def _turned(T_cam_lidar: np.ndarray, turn: np.ndarray | None) -> np.ndarray:
    """``T_cam_lidar`` of the camera turned by a gimbal view (``turn = R_src_cam``; ``None``: not turned)."""
    if turn is None:
        return T_cam_lidar
    T = np.eye(4)
    T[:3, :3] = turn.T  # source-camera directions -> the turned camera's
    return T @ T_cam_lidar


def _augmented(T_cam_lidar: np.ndarray, params) -> np.ndarray:
    """``T_cam_lidar`` turned with the sample's rotation about the optical axis (``params``: its draw or None)."""
    if params is None or params.angle_rad == 0.0:
        return T_cam_lidar
    # Dense maps are mirrored, then rotated; the points are rotated, then mirrored (in lidar_depth_map).
    # mirror . rot(a) == rot(-a) . mirror, so the points turn the other way when the frame is mirrored.
    R = rotation_about_optical_axis(-params.angle_rad if params.flip else params.angle_rad)
    return R.numpy() @ T_cam_lidar
