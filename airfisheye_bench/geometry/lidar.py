"""LiDAR sensor description: channels, columns, beam origins (the organisation of a scan into the paper's index
matrix ``I_LiDAR``, III-C, is :mod:`~airfisheye_bench.geometry.lidar_layout`).

Frames (docs/design.md): the LiDAR frame is x forward, y left, z up. A point's spherical angles are

* azimuth ``theta = atan2(y, x)``: 0 straight ahead, increasing counter-clockwise seen from above (towards the
  sensor's left), and
* elevation ``phi = atan2(z, hypot(x, y))``: positive up.

Beam pattern (the single definition; the synthetic generator casts :meth:`LidarSpec.beam_rays`):

* channel ``i`` (row ``i`` of ``I_LiDAR``) has elevation ``elevations_deg[i]`` (a sensor's channel table,
  ascending) or, for a uniform sensor, ``linspace(lower, upper, channels)[i]``: channel 0 is the lowest beam, so
  elevation increases with the row (the paper's "ascending order of phi along each column");
* column ``j`` has azimuth ``centre - hfov/2 + (j + 0.5) * hfov / points_per_channel`` (plus the channel's
  ``azimuth_offsets_deg``, where the sensor's lasers do not fire in one vertical line): the horizontal FOV,
  centred on the x axis (``azimuth_center_deg`` = 0, or where a sensor's column window puts it), is split into
  equal cells whose centres are the beam azimuths. Azimuth increases with
  the column (the paper's "ascending order of theta from left to right"), and a 360 deg sensor has no duplicated
  column;
* a beam starts at the sensor's centre, or where ``beam_origins_m`` puts its channel's laser: ``(radial,
  tangential, vertical)`` metres, along the beam's horizontal direction, to its left, and up. Real sensors'
  beams do (the HDL-64E's up to 0.21 m above its base), which biases the elevation of near returns.

Named sensors with their datasheet or calibration tables are in :mod:`~airfisheye_bench.geometry.lidar_presets`
(``LidarSpec.from_preset("hdl64e")``).

This is the *nominal* pattern. A real spinning sensor fires at an arbitrary azimuth phase every frame (and
per ring), with jitter and dropped returns: the organisation of a scan into ``I_LiDAR``
(:mod:`~airfisheye_bench.geometry.lidar_layout`) therefore uses the channel elevations and the column width,
never the column centres.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch

from airfisheye_bench.geometry import portable
from airfisheye_bench.geometry._arrays import ArrayLike
from airfisheye_bench.geometry.lidar_presets import LIDAR_PRESETS


@dataclass(frozen=True)
class LidarSpec:
    """A spinning multi-channel LiDAR: the geometry needed to organise its scans (paper, III-C).

    Args:
        channels: Number of channels / rings ``N_C`` (rows of ``I_LiDAR``), at least 2.
        points_per_channel: Number of azimuth cells per channel ``N_PC`` (columns of ``I_LiDAR``): the points per
            revolution (or per ``hfov_deg``).
        hfov_deg: Horizontal field of view in degrees, in ``(0, 360]``, centred on ``azimuth_center_deg``.
        vfov_deg: ``(lower, upper)`` elevations of the lowest and highest channels in degrees, in ``[-90,
            90]``. With ``elevations_deg`` it is their first and last value (given or not).
        max_range: Maximum range in metres (beams that hit nothing closer give no return).
        elevations_deg: The channel table: one elevation per channel in degrees, strictly ascending (ring 0 is
            the lowest). ``None``: ``channels`` channels evenly spaced over ``vfov_deg``.
        azimuth_offsets_deg: Per channel, the azimuth of its laser relative to the column's (degrees, counter-
            clockwise seen from above). ``None``: all zero.
        beam_origins_m: Per channel, where its beam starts: ``(radial, tangential, vertical)`` metres from the
            sensor's centre, along the beam's horizontal direction, to its left and up. ``None``: the centre.
        name: The preset's name, if the spec is one (kept in ``to_dict``).
        azimuth_center_deg: Azimuth of the middle of a partial ``hfov_deg`` (degrees, counter-clockwise from x):
            0, or where a sensor returns only a window of its columns (an Ouster ``column_window``). The field of
            view may not cross azimuth +-180 deg (the layout's sectors would be split there); 0 at 360 deg.

    Example:
        >>> spec = LidarSpec(channels=16, points_per_channel=360, hfov_deg=360.0, vfov_deg=(-15.0, 15.0))
        >>> round(math.degrees(spec.vertical_resolution), 3)
        2.0
        >>> spec.beam_directions().shape
        torch.Size([16, 360, 3])
        >>> LidarSpec.from_dict(spec.to_dict()) == spec
        True
        >>> table = LidarSpec(elevations_deg=(-10.0, -2.0, 0.0, 1.0), points_per_channel=8)
        >>> table.channels, table.vfov_deg, table.is_uniform
        (4, (-10.0, 1.0), False)
    """

    channels: int = 64
    points_per_channel: int = 2048
    hfov_deg: float = 270.0
    vfov_deg: tuple[float, float] = (-45.0, 15.0)
    max_range: float = 120.0
    elevations_deg: tuple[float, ...] | None = None
    azimuth_offsets_deg: tuple[float, ...] | None = None
    beam_origins_m: tuple[tuple[float, float, float], ...] | None = None
    name: str | None = None
    azimuth_center_deg: float = 0.0

    def __post_init__(self) -> None:
        # Coerce (YAML may give ints for floats, lists for tuples) and validate; frozen, hence object.__setattr__.
        if self.elevations_deg is not None:
            table = _table(self.elevations_deg, "elevations_deg")
            if len(table) < 2 or any(b <= a for a, b in itertools.pairwise(table)):
                raise ValueError(
                    "LidarSpec.elevations_deg must hold at least 2 strictly ascending elevations (ring 0 the "
                    f"lowest), got {list(self.elevations_deg)!r}"
                )
            if not all(-90.0 <= v <= 90.0 for v in table):
                raise ValueError(f"LidarSpec.elevations_deg must lie in [-90, 90], got {list(table)!r}")
            object.__setattr__(self, "elevations_deg", table)
            if self.channels != 64 and self.channels != len(table):  # 64: the default, i.e. not given
                raise ValueError(
                    f"LidarSpec.channels={self.channels} but elevations_deg has {len(table)} entries"
                )
            object.__setattr__(self, "channels", len(table))
            object.__setattr__(self, "vfov_deg", (table[0], table[-1]))
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
        centre = _number(self.azimuth_center_deg, "azimuth_center_deg")
        # A window across +-180 deg would split the layout's sectors (columns are counted from -pi): refused.
        if centre and (hfov == 360.0 or abs(centre) + hfov / 2.0 > 180.0 + 1e-9):
            raise ValueError(
                f"LidarSpec.azimuth_center_deg={centre:g} with hfov_deg={hfov:g}: the field of view must lie "
                "within azimuths [-180, 180] (and a 360 deg one is centred on 0)"
            )
        object.__setattr__(self, "azimuth_center_deg", centre)
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
        if self.azimuth_offsets_deg is not None:
            offsets = _table(self.azimuth_offsets_deg, "azimuth_offsets_deg")
            if len(offsets) != self.channels or any(abs(v) >= 180.0 for v in offsets):
                raise ValueError(
                    f"LidarSpec.azimuth_offsets_deg must hold {self.channels} angles in (-180, 180) degrees, "
                    f"one per channel, got {len(offsets)}"
                )
            object.__setattr__(self, "azimuth_offsets_deg", offsets)
        if self.beam_origins_m is not None:
            try:
                origins = tuple(tuple(_number(v, "beam_origins_m") for v in o) for o in self.beam_origins_m)
            except TypeError as err:
                raise ValueError(
                    "LidarSpec.beam_origins_m must be one (radial, tangential, vertical) per channel"
                ) from err
            if len(origins) != self.channels or any(len(o) != 3 or max(map(abs, o)) > 1.0 for o in origins):
                raise ValueError(
                    f"LidarSpec.beam_origins_m must hold {self.channels} triples (radial, tangential, vertical) of "
                    f"metres within 1 m of the centre, one per channel, got {len(origins)}"
                )
            object.__setattr__(self, "beam_origins_m", origins)
        if self.name is not None and not isinstance(self.name, str):
            raise ValueError(f"LidarSpec.name must be a string or None, got {self.name!r}")

    # ------------------------------------------------------------------ beam pattern
    @property
    def is_uniform(self) -> bool:
        """Evenly spaced channels, all beams from the centre: the ring of a point is its rounded elevation."""
        return self.elevations_deg is None and self.beam_origins_m is None

    @property
    def vertical_resolution(self) -> float:
        """Mean elevation step between neighbouring channels, ``VFOV / (N_C - 1)``, in radians."""
        lower, upper = self.vfov_deg
        return math.radians(upper - lower) / (self.channels - 1)

    @property
    def azimuth_edge(self) -> float:
        """Azimuth where column 0 starts, ``centre - HFOV / 2``, in radians (the layout's sectors count from it)."""
        return math.radians(self.azimuth_center_deg) - math.radians(self.hfov_deg) / 2.0

    @property
    def horizontal_resolution(self) -> float:
        """Azimuth step between neighbouring columns, ``HFOV / N_PC``, in radians."""
        return math.radians(self.hfov_deg) / self.points_per_channel

    def channel_elevations(self) -> np.ndarray:
        """Elevation of every channel ``[N_C]`` (float64 radians, ascending: channel 0 is the lowest)."""
        if self.elevations_deg is not None:
            return np.radians(np.asarray(self.elevations_deg, dtype=np.float64))
        lower, upper = self.vfov_deg
        return np.radians(np.linspace(lower, upper, self.channels))

    def channel_azimuth_offsets(self) -> np.ndarray:
        """Azimuth offset of every channel ``[N_C]`` (float64 radians; zeros without ``azimuth_offsets_deg``)."""
        if self.azimuth_offsets_deg is None:
            return np.zeros(self.channels)
        return np.radians(np.asarray(self.azimuth_offsets_deg, dtype=np.float64))

    def channel_origins(self) -> np.ndarray:
        """``[N_C, 3]`` float64 ``(radial, tangential, vertical)`` beam origins in metres (zeros: the centre)."""
        if self.beam_origins_m is None:
            return np.zeros((self.channels, 3))
        return np.asarray(self.beam_origins_m, dtype=np.float64)

    def column_azimuths(self) -> np.ndarray:
        """Azimuth of every column ``[N_PC]`` (float64 radians, ascending, centred on ``azimuth_center_deg``)."""
        return self.azimuth_edge + (np.arange(self.points_per_channel) + 0.5) * self.horizontal_resolution

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
        az = self.column_azimuths()[None, :] + self.channel_azimuth_offsets()[:, None]
        dirs = np.stack(
            np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)), axis=-1
        )
        return torch.from_numpy(dirs).to(dtype=dtype, device=device)

    def beam_origins(self, azimuth: np.ndarray, channel: np.ndarray) -> np.ndarray:
        """Start points ``[N, 3]`` (float64, LiDAR frame) of beams fired at ``azimuth [N]`` by ``channel [N]``.

        Example:
            >>> spec = LidarSpec(channels=2, vfov_deg=(-1.0, 1.0), beam_origins_m=((0.0, 0.0, 0.2), (0.1, 0.0, 0.0)))
            >>> spec.beam_origins(np.array([0.0, np.pi / 2]), np.array([0, 1])).round(6).tolist()
            [[0.0, 0.0, 0.2], [0.0, 0.1, 0.0]]
        """
        radial, tangential, vertical = self.channel_origins()[np.asarray(channel)].T
        c, s = (
            portable.cos(azimuth),
            portable.sin(azimuth),
        )  # generated scans start here: the same bits on any CPU
        return np.stack([radial * c - tangential * s, radial * s + tangential * c, vertical], axis=-1)

    # ------------------------------------------------------------------ construction and serialisation
    @classmethod
    def from_preset(cls, name: str, **changes: Any) -> LidarSpec:
        """A named sensor (:data:`~airfisheye_bench.geometry.lidar_presets.LIDAR_PRESETS`), with ``changes``.

        Example:
            >>> spec = LidarSpec.from_preset("hdl64e")
            >>> spec.channels, spec.hfov_deg, round(spec.vfov_deg[1], 2)
            (64, 360.0, 1.94)
        """
        if name not in LIDAR_PRESETS:
            raise ValueError(f"unknown LiDAR preset {name!r}; expected one of {sorted(LIDAR_PRESETS)}")
        return cls(**{**LIDAR_PRESETS[name], "name": name, **changes})

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python description (for ``calib.yaml``); the optional tables only where they are set."""
        d = asdict(self)
        d["vfov_deg"] = list(self.vfov_deg)
        if not self.azimuth_center_deg:  # written only where set: older calib.yaml files stay as they were
            del d["azimuth_center_deg"]
        for key in _OPTIONAL:
            if d[key] is None:
                del d[key]
            elif key != "name":
                d[key] = [list(v) if isinstance(v, tuple) else v for v in d[key]]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LidarSpec:
        """Inverse of :meth:`to_dict`; ``{"preset": name, ...}`` starts from a preset. Unknown keys raise
        ``ValueError`` naming them."""
        allowed = {
            "channels",
            "points_per_channel",
            "hfov_deg",
            "vfov_deg",
            "max_range",
            "preset",
            "azimuth_center_deg",
            *_OPTIONAL,
        }
        unknown = set(d) - allowed
        if unknown:
            raise ValueError(
                f"unknown LiDAR spec keys {sorted(unknown)}; expected a subset of {sorted(allowed)}"
            )
        kwargs = dict(d)
        for key in ("vfov_deg", "elevations_deg", "azimuth_offsets_deg"):
            if kwargs.get(key) is not None:
                kwargs[key] = tuple(kwargs[key])
        if kwargs.get("beam_origins_m") is not None:
            kwargs["beam_origins_m"] = tuple(tuple(o) for o in kwargs["beam_origins_m"])
        preset = kwargs.pop("preset", None)
        if preset is not None:
            return cls.from_preset(preset, **kwargs)
        return cls(**kwargs)


_OPTIONAL = ("elevations_deg", "azimuth_offsets_deg", "beam_origins_m", "name")


def _table(values: Any, name: str) -> tuple[float, ...]:
    try:
        return tuple(_number(v, name) for v in values)
    except TypeError as err:
        raise ValueError(f"LidarSpec.{name} must be a list of numbers, got {values!r}") from err


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


__all__ = ["LidarSpec", "as_points64", "like", "spherical_coordinates"]
