"""Serving a LiDAR at the pixel density the paper's sensor has on the paper's image (docs/design.md, "Sparse input
density", which states the assumed sensor and why there are two readings).

The paper's sensor, modelled as a 64 x 2048 scan (270 deg), projected into its 1536^2 fisheye of 190 deg gives about
one return in ten pixels at the image centre, three in a hundred at the rim; the paper trained and evaluated at
512^2 without saying how its sparse depth got there, so two readings are served: ``paper_1536`` (the returns per
pixel of the 1536^2 image, a sparse map computed there and resized; ``paper`` names it) and ``paper_512`` (the same
scan projected at 512^2, about nine times the returns per pixel). The same scan served at 128^2 lands a return on
most pixels, so completion becomes interpolation and the nearest return per pixel already hides most occluded
points. A reading keeps a fixed subset of the scan's channels and columns such that each served pixel receives as
many returns as a pixel of the reading's image does:

* beams per square degree must scale with the pixel area: ``(served pixels per degree / paper pixels per degree)^2``
  times the paper sensor's beams per square degree, so the scan keeps one beam in
  ``thin = (dv_paper dh_paper) / (dv dh scale^2)`` (``dv``, ``dh``: channel and column spacing);
* the kept beams sit on a square angular grid (channel stride ``k``, column stride ``m``, ``k dv = m dh``,
  ``k m = thin``). The paper's own 7:1 anisotropy (rows 7.7 px, columns 1.1 px apart at 1536^2) would leave 3 to 5
  channels at 64^2 to 128^2: the coverage of a ring would then depend on which scan lines cross it (measured:
  -27 % in the centre ring of the tiny preset at 64^2), where a square grid keeps every ring within a few per cent;
* strides are real numbers, evenly spread from the first beam to the last (:func:`evenly_spaced`); the column stride is taken from the
  channels actually kept, so rounding the channel count does not change the density.

No return is dropped at random: the kept beams are the same in every frame (the occlusion structure stays the
scan's), and the ground truth stays dense. :func:`beam_pixels` is the geometric yardstick: the pixels of a camera
that a sensor's nominal beams land on, which gives the paper sensor's coverage at 1536^2 of any frame
(``datamodules.coverage.sparse_coverage``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch

from airfisheye_bench.geometry.cameras import CameraModel, ideal_camera
from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.transforms import CAM_FROM_FLU

__all__ = [
    "DENSITY_ALIASES",
    "LIDAR_DENSITIES",
    "PAPER_FOV_DEG",
    "PAPER_IMAGE_SIZE",
    "PAPER_READINGS",
    "BeamSubset",
    "beam_pixels",
    "evenly_spaced",
    "paper_camera",
    "paper_density_subset",
    "paper_scale_camera",
    "reading_size",
    "shared_pixels",
]

#: The paper's fisheye: 1536 x 1536 pixels over 190 deg (Table I).
PAPER_IMAGE_SIZE = 1536
PAPER_FOV_DEG = 190.0
#: The readings of the paper's density: the image (pixels over :data:`PAPER_FOV_DEG`) on which its sensor's returns
#: per pixel are counted. ``paper_1536``: the 1536^2 image (a sparse map made there, then resized); ``paper_512``:
#: the 512^2 image the paper trained and evaluated on (the scan projected there).
PAPER_READINGS = {"paper_1536": PAPER_IMAGE_SIZE, "paper_512": 512}
#: Other names of a reading: ``paper`` is ``paper_1536``, what ``paper`` meant before there were two (and the
#: synthetic dataset's default), so a config or record that says ``paper`` keeps its meaning.
DENSITY_ALIASES = {"paper": "paper_1536"}
#: ``data.lidar.density``: ``native`` (every return of the scan) or a reading of the paper's returns per pixel.
LIDAR_DENSITIES = ("native", *DENSITY_ALIASES, *PAPER_READINGS)


def reading_size(density: str) -> int | None:
    """The image size on which ``density`` counts the paper sensor's returns per pixel; ``None`` for ``native``.

    Example:
        >>> reading_size("paper"), reading_size("paper_512"), reading_size("native")
        (1536, 512, None)
    """
    return PAPER_READINGS.get(DENSITY_ALIASES.get(density, density))


@dataclass(frozen=True, eq=False)
class BeamSubset:
    """The beams of a scan that are served: ``bool [N_C]`` kept channels and ``bool [N_PC]`` kept columns."""

    channels: np.ndarray
    columns: np.ndarray

    @property
    def fraction(self) -> float:
        """Share of the sensor's beams kept."""
        return float(self.channels.mean() * self.columns.mean())

    def mask(self, points: np.ndarray, rings: np.ndarray, spec: LidarSpec) -> np.ndarray:
        """``bool [N]``: the returns of ``points`` (LiDAR frame, ``rings`` resolved) fired by a kept beam.

        The column is the return's azimuth sector (``organize_scan``'s column), so a sensor's azimuth phase or jitter
        moves a return by at most one sector; a return without a ring (-1) is dropped.
        """
        _, azimuth, _ = spherical_coordinates(np.asarray(points, dtype=np.float64))
        column = np.floor((azimuth - spec.azimuth_edge) / spec.horizontal_resolution)
        column = column.astype(np.int64) % spec.points_per_channel
        rings = np.asarray(rings, dtype=np.int64)
        return (rings >= 0) & self.channels[rings.clip(0)] & self.columns[column]


def evenly_spaced(count: int, stride: float) -> np.ndarray:
    """``bool [count]``: about every ``stride``-th index (a real stride >= 1), always the first and the last, so the
    kept beams span the sensor's whole field of view (its edges in the image stay where they are).

    Example:
        >>> np.flatnonzero(evenly_spaced(10, 3.0)).tolist(), np.flatnonzero(evenly_spaced(8, 2.5)).tolist()
        ([0, 3, 6, 9], [0, 2, 5, 7])
    """
    kept = max(round((count - 1) / max(float(stride), 1.0)) + 1, 2 if count > 1 else 1)
    out = np.zeros(count, dtype=bool)
    out[np.rint(np.linspace(0, count - 1, kept)).astype(np.int64)] = True
    return out


@lru_cache(maxsize=64)
def paper_density_subset(
    spec: LidarSpec,
    size: int,
    fov_deg: float = PAPER_FOV_DEG,
    reference: LidarSpec | None = None,
    image_size: int = PAPER_IMAGE_SIZE,
) -> BeamSubset:
    """The beams of ``spec`` to serve so that an image of ``size`` pixels over ``fov_deg`` gets as many returns per
    pixel as ``reference`` (default: the paper's 64 x 2048 sensor) gives an ``image_size``^2, 190 deg image (the
    reading's: :data:`PAPER_READINGS`).

    A sensor already sparser than that at this size keeps every beam (nothing can be added).

    Example:
        >>> quickstart = LidarSpec(points_per_channel=256)
        >>> subset = paper_density_subset(quickstart, 128)
        >>> int(subset.channels.sum()), int(subset.columns.sum()), round(1 / subset.fraction, 1)
        (15, 61, 17.9)
        >>> round(1 / paper_density_subset(quickstart, 128, image_size=512).fraction, 1)  # 3.3 times as dense
        5.4
        >>> paper_density_subset(LidarSpec(), 1536).fraction
        1.0
    """
    reference = reference or LidarSpec()
    scale = (size / fov_deg) / (image_size / PAPER_FOV_DEG)  # served pixels per reading pixel, per degree
    dv, dh = spec.vertical_resolution, spec.horizontal_resolution
    thin = (reference.vertical_resolution * reference.horizontal_resolution) / (dv * dh * scale**2)
    thin *= shared_pixels(reference, image_size)  # a sparse map keeps one return per pixel
    if thin <= 1.0:
        return BeamSubset(np.ones(spec.channels, bool), np.ones(spec.points_per_channel, bool))
    channels = evenly_spaced(spec.channels, math.sqrt(thin * dh / dv))  # k dv = m dh, k m = thin
    # The column stride from the channels actually kept: the total is the target whatever the rounding.
    columns = evenly_spaced(spec.points_per_channel, thin * channels.sum() / spec.channels)
    return BeamSubset(channels, columns)


@lru_cache(maxsize=8)
def shared_pixels(reference: LidarSpec, image_size: int) -> float:
    """How many times fewer pixels ``reference``'s nominal beams land on in an ``image_size``^2, 190 deg fisheye than
    on the paper's 1536^2 one (where a pixel rarely gets two beams): 1 at 1536^2.
    At 512^2 the paper sensor's columns are 0.36 px apart and several beams share a pixel, whose sparse map keeps
    one: the 512^2 reading counts the pixels with a return, not the returns (docs/design.md, "Sparse input
    density"). The sensor looks along the camera's optical axis, as on the synthetic rig.

    Example:
        >>> shared_pixels(LidarSpec(), 1536), round(shared_pixels(LidarSpec(), 512), 2)
        (1.0, 2.71)
    """
    if image_size == PAPER_IMAGE_SIZE:
        return 1.0
    pixels = {
        s: len(beam_pixels(reference, paper_camera(s), CAM_FROM_FLU)) for s in (PAPER_IMAGE_SIZE, image_size)
    }
    return pixels[PAPER_IMAGE_SIZE] / pixels[image_size]


def paper_camera(size: int = PAPER_IMAGE_SIZE) -> CameraModel:
    """The paper's fisheye: equidistant, 190 deg, ``size`` x ``size`` (1536: its recordings; 512: its training)."""
    return ideal_camera(size, size, PAPER_FOV_DEG)


def paper_scale_camera(camera: CameraModel, image_size: int = PAPER_IMAGE_SIZE) -> CameraModel:
    """The same lens with the reading image's pixels per degree (``image_size`` px over 190 deg; 1536 by default),
    where an occlusion correction decides what the paper's pipeline would keep; ``camera`` itself when it is already
    that fine.

    A correction run on the thinned scan at a small size would see occluders through a few coarse rings and
    pixels and change a fraction of what it changes at the paper's scale (docs/design.md, "Sparse input
    density"); deciding on the whole scan at the paper's scale and serving the kept returns of the subset gives
    the input that the paper's image would have, at the paper's density per pixel.

    Example:
        >>> from airfisheye_bench.geometry.cameras import ideal_camera
        >>> big = paper_scale_camera(ideal_camera(128, 128, 190.0))
        >>> big.width, big.height
        (1536, 1536)
        >>> paper_scale_camera(ideal_camera(2048, 2048, 190.0)).width
        2048
        >>> paper_scale_camera(ideal_camera(128, 128, 190.0), image_size=512).width
        512
    """
    size = max(camera.width, camera.height)
    factor = (image_size / PAPER_FOV_DEG) / (size / camera.coverage_deg)
    if factor <= 1.0:
        return camera
    return camera.resized(round(camera.width * factor), round(camera.height * factor))


def beam_pixels(
    spec: LidarSpec, camera: CameraModel, R_cam_lidar: np.ndarray, subset: BeamSubset | None = None
) -> torch.Tensor:
    """``int64 [K, 2]``: the pixels ``(u, v)`` of ``camera`` that a nominal beam of ``spec`` (or of its ``subset``)
    lands on, each once (a sparse depth map keeps one return per pixel).

    Directions only (a return far away compared with the camera-LiDAR offset), turned into the camera by
    ``R_cam_lidar``. No per-pixel grid of the camera is made, so the paper's 1536^2 image costs only its beams.

    Example:
        >>> from airfisheye_bench.geometry.transforms import CAM_FROM_FLU
        >>> len(beam_pixels(LidarSpec(), paper_camera(), np.asarray(CAM_FROM_FLU)))
        89230
    """
    directions = spec.beam_directions(torch.float64)
    if subset is not None:
        directions = directions[torch.from_numpy(subset.channels)][:, torch.from_numpy(subset.columns)]
    rays = directions.reshape(-1, 3) @ torch.as_tensor(np.asarray(R_cam_lidar, dtype=np.float64)[:3, :3]).T
    uv, valid = camera.project(rays)
    valid &= camera.in_image(uv)
    pixel = uv[valid].round().long()
    index = torch.unique(pixel[:, 1] * camera.width + pixel[:, 0])
    return torch.stack([index % camera.width, index // camera.width], dim=-1)
