"""The occlusion methods, their options and defaults, the one check of a method's options, and :class:`Occlusion`,
a method with its checked options, which the projection takes as it is.

What each method and option means: docs/design.md, "LiDAR and occlusion".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

OCCLUSION_METHODS = ("ordering", "zbuffer", "hpr", "none")

#: The sparse input built from the generator's exact per-point visibility (a synthetic release's
#: ``lidar_visible``): the upper bound of every method. It is no method of :func:`occlusion_mask`, which sees
#: only the points; the dataset serves it beside the methods (``data.occlusion=oracle``).
ORACLE = "oracle"
#: Every sparse input a dataset can serve: the methods, then the oracle.
SPARSE_INPUTS = (*OCCLUSION_METHODS, ORACLE)

#: Every method's options and their defaults (see :func:`occlusion_mask`).
OCCLUSION_OPTIONS: dict[str, dict[str, Any]] = {
    "ordering": {"azimuth_window": None, "elevation_window": None, "elevation_tolerance": 0.0},
    "zbuffer": {"kernel": None, "threshold": None, "relative": True, "max_incidence_deg": 87.0},
    "hpr": {"radius": 1000.0},
    "none": {},
}


def check_occlusion_options(method: str, options: dict[str, Any]) -> dict[str, Any]:
    """Validate ``options`` for ``method``; returns them completed with the defaults.

    Raises:
        ValueError: naming the unknown method, the unknown option(s) and the allowed ones, or the option
            with a bad value and what was expected.

    Example:
        >>> check_occlusion_options("hpr", {"radius": 100})
        {'radius': 100}
        >>> check_occlusion_options("zbuffer", {"size": 3})
        Traceback (most recent call last):
        ...
        ValueError: unknown option(s) ['size'] for method 'zbuffer'; allowed: ['kernel', ...]
    """
    if method not in OCCLUSION_METHODS:
        raise ValueError(f"occlusion method must be one of {OCCLUSION_METHODS}, got {method!r}")
    allowed = OCCLUSION_OPTIONS[method]
    unknown = set(options) - set(allowed)
    if unknown:
        raise ValueError(
            f"unknown option(s) {sorted(unknown)} for method {method!r}; allowed: {sorted(allowed)}"
        )
    opts = {**allowed, **options}
    for name in ("azimuth_window", "elevation_window"):
        if name in opts and opts[name] is not None and not (_is_int(opts[name]) and opts[name] >= 0):
            raise ValueError(f"{name} must be None or a non-negative integer, got {opts[name]!r}")
    if "elevation_tolerance" in opts and not _is_real(opts["elevation_tolerance"]):
        raise ValueError(f"elevation_tolerance must be a finite number, got {opts['elevation_tolerance']!r}")
    if "kernel" in opts and not (
        opts["kernel"] is None
        or (_is_int(opts["kernel"]) and opts["kernel"] >= 1 and opts["kernel"] % 2 == 1)
    ):
        raise ValueError(f"kernel must be None or a positive odd integer, got {opts['kernel']!r}")
    if "threshold" in opts and not (opts["threshold"] is None or _is_nonneg(opts["threshold"])):
        raise ValueError(f"threshold must be None or a non-negative number, got {opts['threshold']!r}")
    if "max_incidence_deg" in opts and not (
        _is_real(opts["max_incidence_deg"]) and 0 <= opts["max_incidence_deg"] < 90
    ):
        raise ValueError(f"max_incidence_deg must be a number in [0, 90), got {opts['max_incidence_deg']!r}")
    if "radius" in opts and not (_is_real(opts["radius"]) and opts["radius"] > 1):
        raise ValueError(
            f"radius must be a number > 1 (a multiple of the farthest point's range), got {opts['radius']!r}"
        )
    if "relative" in opts and not isinstance(opts["relative"], bool):
        raise ValueError(f"relative must be a bool, got {opts['relative']!r}")
    if method == "zbuffer" and opts["threshold"] is None and not opts["relative"]:
        raise ValueError(
            "relative=False needs a threshold in metres (threshold=None derives a relative margin)"
        )
    return opts


def check_sparse_input_options(name: str, options: dict[str, Any]) -> dict[str, Any]:
    """:func:`check_occlusion_options` for any of :data:`SPARSE_INPUTS`: the oracle takes no options.

    Example:
        >>> check_sparse_input_options("oracle", {})
        {}
        >>> check_sparse_input_options("oracle", {"kernel": 3})
        Traceback (most recent call last):
        ...
        ValueError: the oracle takes no options, got ['kernel']
    """
    if name == ORACLE:
        if options:
            raise ValueError(f"the oracle takes no options, got {sorted(options)}")
        return {}
    if name not in OCCLUSION_METHODS:
        raise ValueError(f"sparse input must be one of {SPARSE_INPUTS}, got {name!r}")
    return check_occlusion_options(name, options)


@dataclass(frozen=True)
class Occlusion:
    """An occlusion correction: the method and its options, checked once when built, unset options completed with
    their defaults. :func:`~airfisheye_bench.geometry.occlusion.project_lidar` and the functions built on it take
    one as their ``method`` without checking it again (a dataset builds one and projects every frame with it).

    Raises:
        ValueError: as :func:`check_occlusion_options`.

    Example:
        >>> Occlusion("hpr", {"radius": 100}).options
        {'radius': 100}
        >>> Occlusion("zbuffer").options["relative"], Occlusion().method
        (True, 'ordering')
        >>> Occlusion("zbufer")
        Traceback (most recent call last):
        ...
        ValueError: occlusion method must be one of ('ordering', 'zbuffer', 'hpr', 'none'), got 'zbufer'
    """

    method: str = "ordering"
    options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "options", check_occlusion_options(self.method, dict(self.options)))


def sparse_input(method: str, options: Mapping[str, Any] | None = None) -> Occlusion | str:
    """A sparse input's method resolved once: an :class:`Occlusion` (a correction with its checked options), or
    :data:`ORACLE` (the generator's exact visibility, which takes no options).

    Raises:
        ValueError: as :func:`check_sparse_input_options`.

    Example:
        >>> sparse_input("zbuffer", {"kernel": 3}).options["kernel"], sparse_input("oracle")
        (3, 'oracle')
    """
    if method == ORACLE:
        check_sparse_input_options(ORACLE, dict(options or {}))
        return ORACLE
    return Occlusion(method, options or {})


def _is_int(x: Any) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def _is_real(x: Any) -> bool:
    return (
        isinstance(x, (int, float, np.floating, np.integer)) and not isinstance(x, bool) and math.isfinite(x)
    )


def _is_nonneg(x: Any) -> bool:
    return _is_real(x) and x >= 0


__all__ = ["OCCLUSION_METHODS", "OCCLUSION_OPTIONS", "Occlusion", "check_occlusion_options"]
