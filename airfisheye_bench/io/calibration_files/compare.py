"""Cameras named and compared for tables and messages: ``<model> <W>x<H>`` (:func:`camera_label`) and what differs
between two (:func:`camera_mismatch`).
"""

from __future__ import annotations

from typing import Any

__all__ = ["camera_label", "camera_mismatch"]


def camera_label(camera: Any) -> str:
    """A short name of a camera (its ``to_dict()`` or the dict): ``<model> <W>x<H>``, for tables and messages.

    Example:
        >>> camera_label({"model": "unified", "width": 1400, "height": 1400, "xi": 2.2})
        'unified 1400x1400'
        >>> camera_label({"width": 64, "height": 48})  # the first calib.yaml files: equidistant
        'equidistant 64x48'
    """
    d = camera.to_dict() if hasattr(camera, "to_dict") else dict(camera)
    return f"{d.get('model', 'equidistant')} {d.get('width', '?')}x{d.get('height', '?')}"


def camera_mismatch(expected: Any, served: Any) -> str | None:
    """``None`` when two cameras (objects or dicts) are the same, else one line naming both and what differs.

    Example:
        >>> a = {"model": "eucm", "width": 64, "height": 64, "fx": 24.0, "fy": 24.0, "cx": 31.5, "cy": 31.5,
        ...      "alpha": 0.6, "beta": 1.0}
        >>> camera_mismatch(a, dict(a)) is None
        True
        >>> camera_mismatch(a, {**a, "alpha": 0.5, "cx": 30.0})
        'eucm 64x64 (alpha=0.6, cx=31.5) and eucm 64x64 (alpha=0.5, cx=30.0) differ in alpha, cx'
    """
    a = expected.to_dict() if hasattr(expected, "to_dict") else dict(expected)
    b = served.to_dict() if hasattr(served, "to_dict") else dict(served)
    keys = sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))
    if not keys:
        return None
    shown = [k for k in keys if k not in ("model", "width", "height")][:4]

    def describe(d: dict) -> str:
        values = ", ".join(f"{k}={d.get(k)!r}" for k in shown)
        return camera_label(d) + (f" ({values})" if values else "")

    return f"{describe(a)} and {describe(b)} differ in {', '.join(keys)}"
