"""Lenses drawn per sample (``data.camera.lenses``, ``data.camera.jitter``; docs/design.md, "Lenses drawn per
sample").

``data.camera.lenses`` is a list of lens specs, each a mapping with the keys of a served lens (``model``,
``fov_deg``, ``k``, or ``calibration`` and ``camera``) and an optional ``weight`` (sampling proportion; default
equal). ``data.camera.jitter`` is ``{focal: r, principal_point_px: p, distortion: d}``: each training sample's lens
is perturbed by a focal factor in ``[1 - r, 1 + r]``, a principal-point shift in ``[-p, p]`` pixels along x and y,
and one factor in ``[1 - d, 1 + d]`` per distortion coefficient of its model
(:attr:`~airfisheye_bench.geometry.cameras.CameraModel.distortion_params`).

A training sample draws its lens (by weight) and its jitter from ``(seed, epoch, index)`` alone, as its
augmentation and gimbal view do, so a resumed run serves the lenses an uninterrupted one would have. Jitter is drawn
on a grid (:data:`FOCAL_STEP`, :data:`PRINCIPAL_POINT_STEP_PX`, :data:`DISTORTION_STEP`; a range under one step
does not jitter): a lens seen again is the same lens, and its remap tables come from the cache. With ``pool: P`` an epoch draws
``P`` lenses (each from ``(seed, epoch, slot)``) and each training sample serves one of them (its slot from
``(seed, epoch, index)``): at most ``P`` tables are built per epoch, where a draw per sample builds one per sample at
512². Evaluation serves sample ``i`` through lens ``i mod n``, unjittered.

A sample carries its draw as ``lens`` (int64: the index in the list) and ``lens_params`` (float32
``[3 + D]``: focal factor, principal-point shift x and y in pixels, the ``D`` distortion factors, 1 beyond its
model's): :meth:`LensDraw.from_params` and the dataset's ``lens_camera`` rebuild the sample's camera from them.

Example:
    >>> draws = LensDraws(weights=(1.0, 3.0), jitter=LensJitter.parse({"focal": 0.05}), distortion_counts=(4, 0))
    >>> d = draws.draw(7, seed=123)
    >>> d == draws.draw(7, seed=123), d.lens in (0, 1), 0.95 <= d.jitter.focal <= 1.05
    (True, True, True)
    >>> draws.for_split(training=False).draw(5, seed=None)
    LensDraw(lens=1, jitter=Perturbation(focal=1.0, shift=(0.0, 0.0), distortion=()))
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import torch

from airfisheye_bench.geometry.cameras.ideal import LENS_MODELS
from airfisheye_bench.geometry.cameras.perturbation import Perturbation

#: Focal factors are drawn on multiples of 0.25 %.
FOCAL_STEP = 0.0025
#: Principal-point shifts are drawn on multiples of half a pixel.
PRINCIPAL_POINT_STEP_PX = 0.5
#: Distortion factors are drawn on multiples of 0.5 %.
DISTORTION_STEP = 0.005
#: The keys of ``data.camera.jitter``: the three ranges and the per-epoch pool.
JITTER_KEYS = ("focal", "principal_point_px", "distortion", "pool")
_RANGE_KEYS = JITTER_KEYS[:3]
#: The keys of a lens spec of ``data.camera.lenses`` (a served lens's, and its sampling weight).
LENS_KEYS = ("model", "fov_deg", "k", "calibration", "camera", "weight")
# Keeps the lens draws apart from the augmentation's and the gimbal's, which take the same per-sample seed.
_SALT = 0x1E45


@dataclass(frozen=True)
class LensJitter:
    """A parsed ``data.camera.jitter``: the half-widths of the focal factor, principal-point shift (pixels) and
    distortion factors, and ``pool``: how many lenses an epoch draws, each training sample serving one of them
    (``None``: every sample its own draw). A pool bounds the lookup tables an epoch builds: a jittered lens is
    rarely drawn twice, and its tables cost several times a sample at 512² (docs/benchmarks.md)."""

    focal: float = 0.0
    principal_point_px: float = 0.0
    distortion: float = 0.0
    pool: int | None = None

    @classmethod
    def parse(cls, value: Any) -> LensJitter | None:
        """``data.camera.jitter`` as given -> a :class:`LensJitter`, ``None`` for ``null``.

        Raises:
            ValueError: one line naming ``data.camera.jitter`` and the key.
        """
        if value is None:
            return None
        if not isinstance(value, Mapping):
            raise ValueError(
                f"data.camera.jitter: expected null or {{focal: r, principal_point_px: p, distortion: d, pool: n}}, got {value!r}"
            )
        unknown = sorted(set(map(str, value)) - set(JITTER_KEYS))
        if unknown:
            raise ValueError(
                f"data.camera.jitter: unknown key {unknown[0]!r}; expected some of {', '.join(JITTER_KEYS)}"
            )
        out: dict[str, Any] = {}
        pool = value.get("pool")
        if pool is not None and not (
            isinstance(pool, (int, np.integer)) and not isinstance(pool, bool) and pool >= 1
        ):
            raise ValueError(
                f"data.camera.jitter.pool={pool!r}: expected null or a whole number of lenses >= 1"
            )
        out["pool"] = None if pool is None else int(pool)
        for key in _RANGE_KEYS:
            x = value.get(key, 0.0)
            x = 0.0 if x is None else x
            limit = math.inf if key == "principal_point_px" else 1.0
            if not (_is_number(x) and 0.0 <= x < limit):
                bound = ">= 0 pixels" if key == "principal_point_px" else "in [0, 1)"
                raise ValueError(f"data.camera.jitter.{key}={x!r}: expected a number {bound}")
            out[key] = float(x)
        return cls(**out)


@dataclass(frozen=True)
class LensDraw:
    """One sample's lens: its index in the list and its jitter (the identity when unjittered). Hashable: the key of
    the sample's remap."""

    lens: int
    jitter: Perturbation = field(default_factory=Perturbation)

    def params(self, width: int) -> torch.Tensor:
        """``lens_params``: float32 ``[3 + width]`` (focal factor, shift x, shift y, distortion factors padded
        with 1)."""
        j = self.jitter
        factors = list(j.distortion) + [1.0] * (width - len(j.distortion))
        return torch.tensor([j.focal, *j.shift, *factors], dtype=torch.float32)

    @classmethod
    def from_params(
        cls, lens: int, params: Sequence[float] | torch.Tensor, distortion_count: int
    ) -> LensDraw:
        """The draw a sample's ``lens`` and ``lens_params`` describe (``distortion_count``: its model's)."""
        # float32 -> the grid's float64 values (every grid value has at most 4 decimals)
        v = [_on_grid(round(float(x), 6)) for x in params]
        return cls(int(lens), Perturbation.of(v[0], v[1:3], v[3 : 3 + distortion_count]))


@dataclass(frozen=True)
class LensDraws:
    """How a split's samples get their lens.

    Attributes:
        weights: One sampling weight per lens of the list (one lens without a list).
        jitter: The training jitter, or ``None``.
        distortion_counts: How many distortion coefficients each lens's model has.
        training: Draw per sample and epoch (training), or serve lens ``i mod n`` unjittered (evaluation).
    """

    weights: tuple[float, ...]
    jitter: LensJitter | None = None
    distortion_counts: tuple[int, ...] = ()
    training: bool = True

    def for_split(self, training: bool) -> LensDraws:
        return replace(self, training=bool(training))

    @property
    def varies(self) -> bool:
        """Whether samples of this split may get different lenses."""
        return len(self.weights) > 1 or (self.training and self._grid() != (0, 0, 0))

    @property
    def width(self) -> int:
        """``D`` of ``lens_params``: the most distortion coefficients of a lens of the list."""
        return max(self.distortion_counts, default=0)

    @property
    def pool(self) -> int | None:
        """How many lenses a training epoch draws (``data.camera.jitter.pool``; ``None``: one per sample)."""
        return self.jitter.pool if self.jitter is not None and self.training else None

    def draw(self, index: int, seed: int | None) -> LensDraw:
        """The lens of sample ``index``: ``seed`` is its per-sample, per-epoch draw seed (training; ignored, and
        ``None`` allowed, for evaluation)."""
        if not self.training:
            return LensDraw(index % len(self.weights))
        if seed is None:
            raise ValueError("a training split's lens needs the sample's draw seed")
        rng = np.random.default_rng([int(seed) & (2**63 - 1), _SALT])
        p = np.asarray(self.weights) / sum(self.weights)
        lens = int(rng.choice(len(p), p=p)) if len(p) > 1 else 0
        if self.jitter is None:
            return LensDraw(lens)
        focal_cells, shift_cells, distortion_cells = self._grid()
        count = self.distortion_counts[lens] if self.distortion_counts else 0
        k = rng.integers(-focal_cells, focal_cells + 1)
        dx, dy = rng.integers(-shift_cells, shift_cells + 1, size=2)
        m = rng.integers(-distortion_cells, distortion_cells + 1, size=count)
        return LensDraw(
            lens,
            Perturbation.of(
                _on_grid(1.0 + k * FOCAL_STEP),
                (_on_grid(dx * PRINCIPAL_POINT_STEP_PX), _on_grid(dy * PRINCIPAL_POINT_STEP_PX)),
                [_on_grid(1.0 + x * DISTORTION_STEP) for x in m],
            ),
        )

    def _grid(self) -> tuple[int, int, int]:
        """Grid cells on each side of the identity: focal, principal point, distortion."""
        j = self.jitter
        if j is None:
            return (0, 0, 0)
        return (
            math.floor(j.focal / FOCAL_STEP + 1e-9),
            math.floor(j.principal_point_px / PRINCIPAL_POINT_STEP_PX + 1e-9),
            math.floor(j.distortion / DISTORTION_STEP + 1e-9),
        )

    def count(self) -> int:
        """How many distinct lenses this split can serve (each needs its own lookup tables)."""
        if not self.training:
            return len(self.weights)
        f, s, d = self._grid()
        counts = self.distortion_counts or (0,) * len(self.weights)
        return sum((2 * f + 1) * (2 * s + 1) ** 2 * (2 * d + 1) ** n for n in counts)


def parse_lenses(value: Any) -> tuple[tuple[dict[str, Any], ...], tuple[float, ...]] | None:
    """``data.camera.lenses`` as given -> ``(specs without weight, weights)``, ``None`` for ``null``.

    Raises:
        ValueError: one line naming the lens's index and key (``data.camera.lenses[1].fov_deg``).
    """
    if value is None:
        return None
    if isinstance(value, (str, Mapping)) or not isinstance(value, Sequence) or len(value) == 0:
        raise ValueError(
            f"data.camera.lenses: expected null or a non-empty list of lens specs, got {value!r}"
        )
    specs, weights = [], []
    for i, spec in enumerate(value):
        where = f"data.camera.lenses[{i}]"
        if not isinstance(spec, Mapping):
            raise ValueError(
                f"{where}: expected a mapping with model and fov_deg (+ k), or calibration (+ camera)"
            )
        spec = {str(k): v for k, v in spec.items()}
        unknown = sorted(set(spec) - set(LENS_KEYS))
        if unknown:
            raise ValueError(f"{where}: unknown key {unknown[0]!r}; expected some of {', '.join(LENS_KEYS)}")
        weight = spec.pop("weight", None)
        weight = 1.0 if weight is None else weight
        if not (_is_number(weight) and math.isfinite(weight) and weight > 0):
            raise ValueError(f"{where}.weight={weight!r}: expected a number > 0")
        lens = {k: v for k, v in spec.items() if v is not None}
        if "calibration" in lens and {"model", "fov_deg", "k"} & set(lens):
            raise ValueError(f"{where}: calibration gives the lens; drop model / fov_deg / k")
        if "calibration" not in lens and "model" not in lens:
            raise ValueError(f"{where}: expected model (+ fov_deg, k) or calibration (+ camera)")
        if "camera" in lens and "calibration" not in lens:
            raise ValueError(f"{where}.camera: names a camera of a calibration file; give calibration too")
        if "model" in lens and lens["model"] not in LENS_MODELS:
            raise ValueError(f"{where}.model={lens['model']!r}: expected one of {', '.join(LENS_MODELS)}")
        if "fov_deg" in lens and not (_is_number(lens["fov_deg"]) and 0 < lens["fov_deg"] <= 360):
            raise ValueError(f"{where}.fov_deg={lens['fov_deg']!r}: expected degrees in (0, 360]")
        if "k" in lens:
            k = lens["k"]
            if (
                isinstance(k, str)
                or not isinstance(k, Sequence)
                or len(k) != 4
                or not all(map(_is_number, k))
            ):
                raise ValueError(f"{where}.k={k!r}: expected four numbers [k1, k2, k3, k4]")
            lens["k"] = tuple(float(v) for v in k)
        specs.append(lens)
        weights.append(float(weight))
    return tuple(specs), tuple(weights)


def _on_grid(x: float) -> float:
    return round(float(x), 9) + 0.0


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


__all__ = [
    "DISTORTION_STEP",
    "FOCAL_STEP",
    "JITTER_KEYS",
    "LENS_KEYS",
    "PRINCIPAL_POINT_STEP_PX",
    "LensDraw",
    "LensDraws",
    "LensJitter",
    "parse_lenses",
]
