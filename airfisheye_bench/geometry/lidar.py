"""LiDAR sensor description and the organisation of a scan into the paper's index matrix ``I_LiDAR`` (III-C).

Frames (docs/design.md): the LiDAR frame is x forward, y left, z up. A point's spherical angles are

* azimuth ``theta = atan2(y, x)``: 0 straight ahead, increasing counter-clockwise seen from above (towards the
  sensor's left), and
* elevation ``phi = atan2(z, hypot(x, y))``: positive up.

Beam pattern (the single definition; the synthetic generator casts :meth:`LidarSpec.beam_directions`):

* channel ``i`` (row ``i`` of ``I_LiDAR``) has elevation ``linspace(lower, upper, channels)[i]``: channel 0
  is the lowest beam, so elevation increases with the row (the paper's "ascending order of phi along each
  column");
* column ``j`` has azimuth ``-hfov/2 + (j + 0.5) * hfov / points_per_channel``: the horizontal FOV, centred
  on the x axis, is split into equal cells whose centres are the beam azimuths. Azimuth increases with the
  column (the paper's "ascending order of theta from left to right"), and a 360 deg sensor has no duplicated
  column.

This is the *nominal* pattern. A real spinning sensor fires at an arbitrary azimuth phase every frame (and
per ring), with jitter and dropped returns: :func:`organize_scan` therefore uses the channel elevations and the
column width, never the column centres.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, NamedTuple

import numpy as np
import torch

from airfisheye_bench.geometry._arrays import ArrayLike


@dataclass(frozen=True)
class LidarSpec:
    """A spinning multi-channel LiDAR: the geometry needed to organise its scans (paper, III-C).

    Args:
        channels: Number of channels / rings ``N_C`` (rows of ``I_LiDAR``), at least 2.
        points_per_channel: Number of azimuth cells per channel ``N_PC`` (columns of ``I_LiDAR``).
        hfov_deg: Horizontal field of view in degrees, in ``(0, 360]``, centred on the LiDAR x axis.
        vfov_deg: ``(lower, upper)`` elevations of the lowest and highest channels in degrees, in ``[-90,
        90]``.
        max_range: Maximum range in metres (beams that hit nothing closer give no return).

    Example:
        >>> spec = LidarSpec(channels=16, points_per_channel=360, hfov_deg=360.0, vfov_deg=(-15.0, 15.0))
        >>> round(math.degrees(spec.vertical_resolution), 3)
        2.0
        >>> spec.beam_directions().shape
        torch.Size([16, 360, 3])
        >>> LidarSpec.from_dict(spec.to_dict()) == spec
        True
    """

    channels: int = 64
    points_per_channel: int = 2048
    hfov_deg: float = 270.0
    vfov_deg: tuple[float, float] = (-45.0, 15.0)
    max_range: float = 120.0

    def __post_init__(self) -> None:
        # Coerce (YAML may give ints for floats, lists for tuples) and validate; frozen, hence object.__setattr__.
        for name in ("channels", "points_per_channel"):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and not isinstance(value, bool)):
                raise ValueError(f"LidarSpec.{name} must be an integer, got {value!r}")
            object.__setattr__(self, name, int(value))
        if self.channels < 2:
            raise ValueError(f"LidarSpec.channels must be >= 2, got {self.channels}")
        if self.points_per_channel < 1:
            raise ValueError(f"LidarSpec.points_per_channel must be >= 1, got {self.points_per_channel}")
        hfov = _number(self.hfov_deg, "hfov_deg")
        if not 0.0 < hfov <= 360.0:
            raise ValueError(f"LidarSpec.hfov_deg must be in (0, 360], got {self.hfov_deg!r}")
        object.__setattr__(self, "hfov_deg", hfov)
        try:
            lower, upper = (_number(v, "vfov_deg") for v in self.vfov_deg)
        except (TypeError, ValueError) as err:
            raise ValueError(
                f"LidarSpec.vfov_deg must be a pair (lower, upper) in degrees, got {self.vfov_deg!r}"
            ) from err
        if not (-90.0 <= lower < upper <= 90.0):
            raise ValueError(
                f"LidarSpec.vfov_deg must satisfy -90 <= lower < upper <= 90, got {self.vfov_deg!r}"
            )
        object.__setattr__(self, "vfov_deg", (lower, upper))
        max_range = _number(self.max_range, "max_range")
        if max_range <= 0.0:
            raise ValueError(
                f"LidarSpec.max_range must be a positive number of metres, got {self.max_range!r}"
            )
        object.__setattr__(self, "max_range", max_range)

    # ------------------------------------------------------------------ beam pattern
    @property
    def vertical_resolution(self) -> float:
        """Elevation step between neighbouring channels, ``VFOV / (N_C - 1)``, in radians."""
        lower, upper = self.vfov_deg
        return math.radians(upper - lower) / (self.channels - 1)

    @property
    def horizontal_resolution(self) -> float:
        """Azimuth step between neighbouring columns, ``HFOV / N_PC``, in radians."""
        return math.radians(self.hfov_deg) / self.points_per_channel

    def channel_elevations(self) -> np.ndarray:
        """Elevation of every channel ``[N_C]`` (float64 radians, ascending: channel 0 is the lowest)."""
        lower, upper = self.vfov_deg
        return np.radians(np.linspace(lower, upper, self.channels))

    def column_azimuths(self) -> np.ndarray:
        """Azimuth of every column ``[N_PC]`` (float64 radians, ascending, centred on the x axis)."""
        half = math.radians(self.hfov_deg) / 2.0
        return -half + (np.arange(self.points_per_channel) + 0.5) * self.horizontal_resolution

    def beam_directions(
        self, dtype: torch.dtype = torch.float32, device: torch.device | str | None = None
    ) -> torch.Tensor:
        """Unit beam directions ``[N_C, N_PC, 3]`` (LiDAR frame); beam ``(i, j)`` fills ``I_LiDAR[i, j]``.

        Example:
            >>> spec = LidarSpec(channels=2, points_per_channel=4, hfov_deg=360.0, vfov_deg=(0.0, 90.0))
            >>> d = spec.beam_directions()
            >>> torch.allclose(d[1, 0], torch.tensor([0.0, 0.0, 1.0]))  # the upper channel points straight up
            True
        """
        el = self.channel_elevations()[:, None]
        az = self.column_azimuths()[None, :]
        dirs = np.stack(
            np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)), axis=-1
        )
        return torch.from_numpy(dirs).to(dtype=dtype, device=device)

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict[str, Any]:
        """Plain-Python description (for ``calib.yaml``)."""
        d = asdict(self)
        d["vfov_deg"] = list(self.vfov_deg)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LidarSpec:
        """Inverse of :meth:`to_dict`; unknown keys raise ``ValueError`` naming them."""
        allowed = {"channels", "points_per_channel", "hfov_deg", "vfov_deg", "max_range"}
        unknown = set(d) - allowed
        if unknown:
            raise ValueError(
                f"unknown LiDAR spec keys {sorted(unknown)}; expected a subset of {sorted(allowed)}"
            )
        kwargs = dict(d)
        if "vfov_deg" in kwargs:
            kwargs["vfov_deg"] = tuple(kwargs["vfov_deg"])
        return cls(**kwargs)


def _number(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"LidarSpec.{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"LidarSpec.{name} must be finite, got {value!r}")
    return float(value)


# ---------------------------------------------------------------------- numpy/torch plumbing and validation
def as_points64(points: Any, name: str = "points_lidar") -> np.ndarray:
    """Validate a point cloud ``[N, 3]`` (numpy or torch, floating, finite) and return it as float64 numpy."""
    if isinstance(points, torch.Tensor):
        if not points.is_floating_point():
            raise ValueError(f"{name} must have a floating dtype, got {points.dtype}")
        arr = points.detach().to("cpu", torch.float64).numpy()
    elif isinstance(points, np.ndarray):
        if not np.issubdtype(points.dtype, np.floating):
            raise ValueError(f"{name} must have a floating dtype, got {points.dtype}")
        arr = points.astype(np.float64, copy=False)
    else:
        raise ValueError(f"{name} must be a numpy array or torch tensor, got {type(points).__name__}")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape [N, 3] (x, y, z in metres), got {tuple(arr.shape)}")
    if not np.isfinite(arr).all():
        bad = int((~np.isfinite(arr).all(axis=1)).sum())
        raise ValueError(f"{name} contains {bad} non-finite point(s); drop NaN/inf returns before calling")
    return arr


def like(result: np.ndarray, reference: Any) -> ArrayLike:
    """Return ``result`` as a tensor on ``reference``'s device if ``reference`` is a tensor, else as numpy."""
    if isinstance(reference, torch.Tensor):
        return torch.from_numpy(np.ascontiguousarray(result)).to(reference.device)
    return result


def spherical_coordinates(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Range, azimuth ``atan2(y, x)`` and elevation ``atan2(z, hypot(x, y))`` of float64 points ``[N, 3]``."""
    # Contiguous coordinates let numpy's SIMD arctan2 run (3x faster than on strided columns); sqrt(x^2 + y^2)
    # instead of np.hypot (a scalar libm call, 10x slower): no overflow is possible at LiDAR ranges.
    x, y, z = np.ascontiguousarray(points.T)
    rho = x * x
    rho += y * y
    r = z * z
    r += rho
    np.sqrt(rho, out=rho)
    return np.sqrt(r, out=r), np.arctan2(y, x), np.arctan2(z, rho)


# ---------------------------------------------------------------------- organisation (step 1 of III-C)
class ScanLayout(NamedTuple):
    """Where each point of a scan sits in ``I_LiDAR`` (see :func:`organize_scan`); ``int64 [N]`` arrays.

    Attributes:
        ring: Channel (row of ``I_LiDAR``, 0 = the lowest beam), or -1 for a point no beam of the sensor can
            have returned (at the origin, or more than half a channel spacing outside the vertical FOV).
        position: Rank of the point in azimuth within its ring (its place along the row; -1 where ``ring`` is).
        column: Azimuth sector, ``floor((azimuth + HFOV/2) / (HFOV/N_PC))``: the spec's column ``j`` covers
            ``[-HFOV/2 + j * res, -HFOV/2 + (j + 1) * res)``. Points outside a partial HFOV get the sectors
            beyond ``[0, N_PC)`` (negative or ``>= N_PC``), so that they are organised (and tested) too.
    """

    ring: ArrayLike
    position: ArrayLike
    column: ArrayLike


def column_range(spec: LidarSpec) -> tuple[int, int]:
    """``(first, count)`` of the azimuth sectors that :class:`ScanLayout` can hold for this spec.

    ``first`` is the sector of azimuth ``-pi`` (<= 0), ``count`` the number of sectors up to ``+pi``.
    """
    if spec.hfov_deg == 360.0:
        return 0, spec.points_per_channel
    edge, res = -math.radians(spec.hfov_deg) / 2.0, spec.horizontal_resolution
    first = math.floor((-math.pi - edge) / res)
    return first, math.floor((math.pi - edge) / res) - first + 1


def layout_from_angles(r: np.ndarray, az: np.ndarray, el: np.ndarray, spec: LidarSpec) -> ScanLayout:
    """:func:`organize_scan` from the points' spherical coordinates (see :func:`spherical_coordinates`).

    The numpy reference of the compiled ``_kernels.lidar_layout`` (bit-identical: the same float64
    operations); numpy in, numpy out.
    """
    ring = np.rint((el - math.radians(spec.vfov_deg[0])) / spec.vertical_resolution)
    ring = np.where((r > 0) & (ring >= 0) & (ring < spec.channels), ring, -1).astype(np.int64)
    column = np.floor((az - (-math.radians(spec.hfov_deg) / 2.0)) / spec.horizontal_resolution)
    if spec.hfov_deg == 360.0:
        column = np.minimum(column, spec.points_per_channel - 1)  # azimuth +pi exactly: the last sector
    # Rank in azimuth within the ring; lexsort is stable, so equal azimuths keep the lower index first.
    order = np.lexsort((az, ring))
    ranked = ring[order]
    position = np.empty(len(r), dtype=np.int64)
    position[order] = np.arange(len(r)) - np.searchsorted(ranked, ranked)
    position[ring < 0] = -1
    return ScanLayout(ring, position, column.astype(np.int64))


def organize_scan(points_lidar: ArrayLike, spec: LidarSpec) -> ScanLayout:
    """Organise a LiDAR scan into the paper's ``I_LiDAR`` (III-C, first step), wherever its beams sit.

    Row ``i`` of ``I_LiDAR`` is ring ``i`` (the channel nearest the point's elevation: rings are a full
    channel spacing apart, so jitter cannot move a point to another ring) with its points in ascending
    azimuth; column ``j`` is the spec's azimuth sector ``j``. No point competes for a cell: a real scan's
    beams sit at an arbitrary azimuth phase (per frame, per ring), with jitter and dropped returns, so a
    sector may hold zero, one or two points of a ring, and every one of them keeps its place. The result
    does not depend on the order of the points.

    Args:
        points_lidar: ``[N, 3]`` points in the LiDAR frame (numpy or torch, floating, finite).
        spec: The sensor that recorded the scan (channel elevations, sector width).

    Returns:
        :class:`ScanLayout` of ``int64 [N]`` arrays, numpy or torch like the input.

    Example:
        >>> spec = LidarSpec(channels=4, points_per_channel=8)
        >>> beams = spec.beam_directions(torch.float64).reshape(-1, 3)
        >>> layout = organize_scan(10.0 * beams.flip(0), spec)  # points listed in reverse order
        >>> [int(v[0]) for v in layout], [int(v[31]) for v in layout]  # (ring, position, column)
        ([3, 7, 7], [0, 0, 0])
    """
    if not isinstance(spec, LidarSpec):
        raise ValueError(f"spec must be a LidarSpec, got {type(spec).__name__}")
    points = as_points64(points_lidar, "points_lidar")
    layout = layout_from_angles(*spherical_coordinates(points), spec)
    return ScanLayout(*(like(v, points_lidar) for v in layout))


__all__ = ["LidarSpec", "ScanLayout", "organize_scan", "spherical_coordinates"]
