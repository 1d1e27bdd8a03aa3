"""The parameters of the camera models: each model declares its own once, as a tuple of :class:`Param`.

A parameter is its name, its default (:data:`REQUIRED`: none), the check that turns a given value into the stored
one (or raises ``ValueError`` naming the parameter), and how it follows the image in ``resized()``. A model's
``declaration`` lists them in ``to_dict`` order, as COLMAP's ``sensor/models.h`` declares a model once;
:class:`~airfisheye_bench.geometry.cameras.base.CameraModel` derives everything else from it: the constructor's
arguments and their checks, ``params``, ``defaults``, ``to_dict`` and ``camera_from_dict``, the calibration
readers' dicts (``flat_dict``) and ``resized()``.

Example:
    >>> BETA = Param("beta", check=positive)
    >>> BETA.check("beta", 1)
    1.0
    >>> FX.scaled(200.0, 0.5, 0.5), CX.scaled(255.5, 0.5, 0.5)  # a length, and a position about the corner
    (100.0, 127.5)
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

#: ``Param.default`` of a parameter that must be given (the constructor's signature reads it as "no default").
REQUIRED: Any = inspect.Parameter.empty

#: A check: ``(name, value) -> stored value``, ``ValueError`` naming the parameter for a wrong value.
Check = Callable[[str, Any], Any]
#: A scaling rule: ``(value, sx, sy) -> value`` on a sensor scaled by ``sx, sy``.
Scale = Callable[[Any, float, float], Any]


def finite_float(name: str, value: Any, positive: bool = False) -> float:
    """``value`` as a float, or ``ValueError`` naming the parameter."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(out) or (positive and out <= 0):
        raise ValueError(f"{name} must be a finite{' positive' if positive else ''} number, got {value!r}")
    return out


def float_list(name: str, values: Any, min_len: int = 1) -> tuple[float, ...]:
    """A sequence of finite floats as a tuple, or ``ValueError`` naming the parameter."""
    if isinstance(values, str) or not hasattr(values, "__len__") or len(values) < min_len:
        raise ValueError(f"{name} must be a list of at least {min_len} numbers, got {values!r}")
    return tuple(finite_float(f"{name}[{i}]", v) for i, v in enumerate(values))


# ---------------------------------------------------------------------------------------------------- checks
def number(name: str, value: Any) -> float:
    """Any finite number (the default check)."""
    return finite_float(name, value)


def positive(name: str, value: Any) -> float:
    """A finite number > 0 (focal lengths, scales)."""
    return finite_float(name, value, positive=True)


def interval(lo: float, hi: float, *, open_lo: bool = False, open_hi: bool = False, text: str = "") -> Check:
    """A finite number in ``[lo, hi]`` (``open_lo`` / ``open_hi`` exclude an end); ``text`` shows the range."""
    shown = text or f"{'(' if open_lo else '['}{lo:g}, {hi:g}{')' if open_hi else ']'}"

    def check(name: str, value: Any) -> float:
        out = finite_float(name, value)
        if out < lo or out > hi or (open_lo and out == lo) or (open_hi and out == hi):
            raise ValueError(f"{name} must be in {shown}, got {value!r}")
        return out

    return check


def numbers(min_len: int) -> Check:
    """A list of at least ``min_len`` finite numbers (polynomial coefficients), stored as a tuple."""

    def check(name: str, value: Any) -> tuple[float, ...]:
        return float_list(name, value, min_len)

    return check


def optional(check: Check) -> Check:
    """``check``, or ``None`` left as it is (a value the model fills in, or a limit it does without)."""

    def optional_check(name: str, value: Any) -> Any:
        return None if value is None else check(name, value)

    return optional_check


#: A full field of view in degrees.
field_of_view = interval(0.0, 360.0, open_lo=True)


# ---------------------------------------------------------------------------------------------------- scaling
#: How a parameter follows the image in ``resized()``, by name (``Param.scale``); a list scales element by element.
SCALES: dict[str, Scale] = {
    "fx": lambda v, sx, sy: v * sx,  # a length along u, in pixels
    "fy": lambda v, sx, sy: v * sy,
    # A position: pixel centres scale about the image corner (-0.5, -0.5), c' = (c + 0.5) s - 0.5.
    "cx": lambda v, sx, sy: (v + 0.5) * sx - 0.5,
    "cy": lambda v, sx, sy: (v + 0.5) * sy - 0.5,
}


@dataclass(frozen=True)
class Param:
    """One parameter of a camera model.

    Args:
        name: Its name (the constructor's argument, the attribute, the ``to_dict`` key).
        default: Its value when left out; :data:`REQUIRED` when it must be given.
        check: Turns a given value into the stored one, or raises ``ValueError`` naming the parameter.
        scale: How it follows the image in ``resized()``: a key of :data:`SCALES` (``"fx"``: a pixel length along
            u, ``"cx"``: a pixel position along u, ...), a rule ``(value, sx, sy) -> value``, or ``None``
            (unchanged: angles, ratios, coefficients of normalised coordinates).
        omit_default: Left out of ``to_dict`` and the camera's ``key()`` while at its default: a parameter added
            to a model later, so the dicts, files, content identities and cache names of the cameras that do
            without it stay what they were.
        distortion: A distortion coefficient: a number that bends the model's projection away from its base
            (``data.camera.jitter``'s ``distortion`` scales these, and only these; ``zeros`` declares them).
    """

    name: str
    default: Any = REQUIRED
    check: Check = number
    scale: str | Scale | None = None
    omit_default: bool = False
    distortion: bool = False

    def __post_init__(self) -> None:
        if isinstance(self.scale, str) and self.scale not in SCALES:
            raise ValueError(
                f"{self.name}: scale must be one of {sorted(SCALES)} or a function, got {self.scale!r}"
            )

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def scaled(self, value: Any, sx: float, sy: float) -> Any:
        """``value`` on a sensor scaled by ``sx, sy``."""
        if self.scale is None or value is None:
            return value
        if callable(self.scale):
            return self.scale(value, sx, sy)
        rule = SCALES[self.scale]
        if isinstance(value, Sequence):
            return [rule(v, sx, sy) for v in value]
        return rule(value, sx, sy)


def zeros(*names: str, omit_default: bool = False) -> tuple[Param, ...]:
    """Distortion coefficients that default to 0 (of normalised coordinates: unchanged by ``resized()``; declared
    ``distortion``); ``omit_default``: see :class:`Param`."""
    return tuple(Param(name, 0.0, omit_default=omit_default, distortion=True) for name in names)


# ---------------------------------------------------------------------------------------------------- shared
FX = Param("fx", check=positive, scale="fx")
FY = Param("fy", check=positive, scale="fy")
CX = Param("cx", scale="cx")
CY = Param("cy", scale="cy")
#: ``fx, fy, cx, cy``: the intrinsics most models start with.
PINHOLE = (FX, FY, CX, CY)
#: The optional field of view (degrees) that limits the valid region to an image circle; ``None``: the model's own
#: region decides.
FOV_DEG = Param("fov_deg", None, check=optional(field_of_view))


__all__ = [
    "CX",
    "CY",
    "FOV_DEG",
    "FX",
    "FY",
    "PINHOLE",
    "REQUIRED",
    "SCALES",
    "Param",
    "field_of_view",
    "finite_float",
    "float_list",
    "interval",
    "number",
    "numbers",
    "optional",
    "positive",
    "zeros",
]
