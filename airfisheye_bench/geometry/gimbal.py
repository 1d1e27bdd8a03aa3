"""A virtual gimbal: the orientations a served camera is turned to relative to its remap source (docs/design.md,
"Virtual gimbal"; the ``data.gimbal`` key).

A view is ``(yaw, pitch, roll)`` in degrees, turned into ``R_src_cam`` by
:func:`~airfisheye_bench.geometry.transforms.gimbal_rotation` (positive yaw to the left, positive pitch down, as the
synthetic rig's ``gimbal_pitch_deg``). ``data.gimbal`` is one of

- ``null``: the camera as recorded;
- ``[yaw, pitch]`` or ``[yaw, pitch, roll]``: one fixed view, every split;
- a list of views: training draws one per sample and epoch, evaluation serves sample ``i`` through view
  ``i mod n``;
- a mapping ``{yaw_deg, pitch_deg, roll_deg, step_deg, eval}``: each angle a number (fixed) or ``[low, high]``
  (drawn uniformly per training sample and epoch, then rounded to the grid ``low + k * step_deg``, 1 deg by
  default, so that a few lookup tables serve every draw); evaluation serves sample ``i`` through a fixed view:
  ``eval`` when given, else one drawn from the ranges by the sample's index alone (the same for every run and model).

Draws are a function of a seed the caller derives from the run's seed, the epoch and the sample index, so a resumed
run serves the views the uninterrupted run would have.

Example:
    >>> g = Gimbal.parse({"pitch_deg": [0, 45]})
    >>> g.view(3, draw=12345) == g.view(3, draw=12345), g.view(3, draw=12345)[1] in range(46)
    (True, True)
    >>> g.for_split(training=False).view(3, draw=None)  # evaluation: the sample's fixed view
    (0.0, 30.0, 0.0)
    >>> g.view_count(), Gimbal.parse([10, 30]).view(7, draw=1)
    (46, (10.0, 30.0, 0.0))
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from airfisheye_bench.geometry.transforms import gimbal_rotation

#: A view: ``(yaw, pitch, roll)`` in degrees.
View = tuple[float, float, float]
#: The keys of the mapping form of ``data.gimbal``.
GIMBAL_KEYS = ("yaw_deg", "pitch_deg", "roll_deg", "step_deg", "eval")
_ANGLES = ("yaw_deg", "pitch_deg", "roll_deg")
_FORMS = (
    "null, [yaw, pitch] or [yaw, pitch, roll] in degrees, a list of such views, or "
    "{yaw_deg, pitch_deg, roll_deg: a number or [low, high], step_deg, eval: a view}"
)
# Keeps the gimbal's draws apart from the augmentation's, which take the same per-sample seed.
_SALT = 0x61B5A1


@dataclass(frozen=True)
class Gimbal:
    """A parsed ``data.gimbal`` for one split (:meth:`parse`, then :meth:`for_split`).

    Attributes:
        views: Explicit views (the fixed and the list forms), else empty.
        ranges: ``(low, high)`` of yaw, pitch and roll (the mapping form), else ``None``.
        step_deg: The grid drawn angles are rounded to.
        eval_view: The mapping form's ``eval`` view, if given.
        training: Draw per epoch (training) or serve each sample's fixed view (evaluation).
    """

    views: tuple[View, ...] = ()
    ranges: tuple[tuple[float, float], ...] | None = None
    step_deg: float = 1.0
    eval_view: View | None = None
    training: bool = True

    @classmethod
    def parse(cls, value: Any) -> Gimbal | None:
        """``data.gimbal`` as given (plain or OmegaConf containers) -> a :class:`Gimbal`, ``None`` for ``null``.

        Raises:
            ValueError: one line, ``data.gimbal: <the entry>: <what is expected>``.
        """
        if value is None:
            return None
        if isinstance(value, Mapping):
            return cls._parse_mapping(value)
        if isinstance(value, Sequence) and not isinstance(value, str) and len(value) > 0:
            if all(_is_number(v) for v in value):
                return cls(views=(_view(value, "view"),))
            if all(isinstance(v, Sequence) and not isinstance(v, str) for v in value):
                return cls(views=tuple(_view(v, f"view {i}") for i, v in enumerate(value)))
        raise ValueError(f"data.gimbal: expected {_FORMS}, got {_show(value)}")

    @classmethod
    def _parse_mapping(cls, value: Mapping) -> Gimbal:
        unknown = sorted(set(map(str, value)) - set(GIMBAL_KEYS))
        if unknown:
            raise ValueError(
                f"data.gimbal: unknown key {unknown[0]!r}; expected keys among {', '.join(GIMBAL_KEYS)}"
            )
        ranges = []
        for name in _ANGLES:
            x = value.get(name, 0.0)
            x = 0.0 if x is None else x
            if _is_number(x) and math.isfinite(x):
                ranges.append((float(x), float(x)))
            elif (
                isinstance(x, Sequence)
                and not isinstance(x, str)
                and len(x) == 2
                and all(_is_number(v) and math.isfinite(v) for v in x)
                and x[0] <= x[1]
            ):
                ranges.append((float(x[0]), float(x[1])))
            else:
                raise ValueError(
                    f"data.gimbal: {name}={_show(x)}: expected a number of degrees or [low, high] with low <= high"
                )
        step = value.get("step_deg", 1.0)
        step = 1.0 if step is None else step
        if not (_is_number(step) and math.isfinite(step) and step > 0):
            raise ValueError(f"data.gimbal: step_deg={_show(step)}: expected a number of degrees > 0")
        raw_eval = value.get("eval")
        eval_view = None if raw_eval is None else _view(raw_eval, "eval")
        if all(lo == hi for lo, hi in ranges):  # nothing to draw: one fixed view
            return cls(views=(tuple(lo for lo, _ in ranges),), eval_view=eval_view)  # type: ignore[arg-type]
        return cls(ranges=tuple(ranges), step_deg=float(step), eval_view=eval_view)

    def for_split(self, training: bool) -> Gimbal:
        """This gimbal for a training split (draws per epoch) or an evaluation split (fixed views)."""
        return replace(self, training=bool(training))

    @property
    def fixed(self) -> View | None:
        """The one view every sample of this split gets, or ``None`` when views vary."""
        if not self.training and self.eval_view is not None:
            return self.eval_view
        return self.views[0] if len(self.views) == 1 else None

    def view(self, index: int, draw: int | None) -> View:
        """The view of sample ``index``: ``draw`` is its per-sample, per-epoch seed (training), ignored (``None``
        allowed) for an evaluation split, whose views depend on the index alone."""
        if self.fixed is not None:
            return self.fixed
        if not self.training:
            if self.views:
                return self.views[index % len(self.views)]
            draw = index  # the sample's own fixed view, the same for every run and model
        elif draw is None:
            raise ValueError("a training split's view needs the sample's draw seed")
        rng = np.random.default_rng([int(draw) & (2**63 - 1), _SALT, int(not self.training)])
        if self.views:
            return self.views[int(rng.integers(len(self.views)))]
        assert self.ranges is not None
        return tuple(self._on_grid(lo, hi, rng.uniform(lo, hi)) for lo, hi in self.ranges)  # type: ignore[return-value]

    def _on_grid(self, lo: float, hi: float, x: float) -> float:
        if lo == hi:
            return lo
        k = min(round((x - lo) / self.step_deg), self._cells(lo, hi) - 1)
        return round(lo + k * self.step_deg, 9)

    def _cells(self, lo: float, hi: float) -> int:
        return math.floor((hi - lo) / self.step_deg + 1e-9) + 1 if hi > lo else 1

    def view_count(self) -> int:
        """How many distinct views this split can serve (each needs its own lookup tables)."""
        if self.fixed is not None:
            return 1
        if self.views:
            return len(self.views)
        assert self.ranges is not None
        return math.prod(self._cells(lo, hi) for lo, hi in self.ranges)

    def all_views(self) -> list[View]:
        """Every view this split can serve (the grid of the ranges; the list; the fixed view)."""
        if self.fixed is not None:
            return [self.fixed]
        if self.views:
            return list(dict.fromkeys(self.views))
        assert self.ranges is not None
        axes = [
            [self._on_grid(lo, hi, lo + k * self.step_deg) for k in range(self._cells(lo, hi))]
            for lo, hi in self.ranges
        ]
        return [(y, p, r) for y in axes[0] for p in axes[1] for r in axes[2]]

    @staticmethod
    def rotation(view: View) -> np.ndarray | None:
        """``R_src_cam`` of a view, ``None`` for the recorded orientation ``(0, 0, 0)``."""
        return None if tuple(view) == (0.0, 0.0, 0.0) else gimbal_rotation(*view)


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


def _view(value: Any, name: str) -> View:
    if (
        isinstance(value, Sequence)
        and not isinstance(value, str)
        and len(value) in (2, 3)
        and all(_is_number(v) and math.isfinite(v) for v in value)
    ):
        yaw, pitch, *roll = (float(v) for v in value)
        return (yaw, pitch, roll[0] if roll else 0.0)
    raise ValueError(
        f"data.gimbal: {name} {_show(value)}: expected [yaw, pitch] or [yaw, pitch, roll] in degrees"
    )


def _show(value: Any) -> str:
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}: {_show(v)}" for k, v in value.items()) + "}"
    if isinstance(value, Sequence) and not isinstance(value, str):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    return repr(value)


__all__ = ["GIMBAL_KEYS", "Gimbal", "View"]
