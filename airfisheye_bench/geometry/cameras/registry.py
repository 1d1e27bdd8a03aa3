"""The table of camera models (``CAMERA_MODELS``) and ``camera_from_dict``, the inverse of ``to_dict``."""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import Any

from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.division import Division
from airfisheye_bench.geometry.cameras.double_sphere import DoubleSphere
from airfisheye_bench.geometry.cameras.eucm import EUCM
from airfisheye_bench.geometry.cameras.fov import Fov
from airfisheye_bench.geometry.cameras.kannala_brandt import KannalaBrandt
from airfisheye_bench.geometry.cameras.ocam import Ocam
from airfisheye_bench.geometry.cameras.pinhole_radtan import PinholeRadtan
from airfisheye_bench.geometry.cameras.radial import RADIAL_MODELS, Pinhole
from airfisheye_bench.geometry.cameras.radial_poly import RadialPoly
from airfisheye_bench.geometry.cameras.thin_prism import RadTanThinPrismFisheye, ThinPrismFisheye
from airfisheye_bench.geometry.cameras.unified import Unified

#: Every camera model by its registry name (the ``model`` entry of ``to_dict``).
CAMERA_MODELS: dict[str, type[CameraModel]] = {
    **RADIAL_MODELS,
    KannalaBrandt.model: KannalaBrandt,
    Unified.model: Unified,
    DoubleSphere.model: DoubleSphere,
    EUCM.model: EUCM,
    Fov.model: Fov,
    Division.model: Division,
    ThinPrismFisheye.model: ThinPrismFisheye,
    RadTanThinPrismFisheye.model: RadTanThinPrismFisheye,
    Ocam.model: Ocam,
    RadialPoly.model: RadialPoly,
    PinholeRadtan.model: PinholeRadtan,
    Pinhole.model: Pinhole,
}

#: Keys of the single-focal Kannala-Brandt form written before issue #22 (``focal``, ``k: [k1..k4]``).
_LEGACY_KB_KEYS = frozenset({"focal", "k"})


def camera_from_dict(d: Mapping[str, Any]) -> CameraModel:
    """Build a camera from its flat description ``{"model", "width", "height", <params>}``.

    A missing ``model`` means ``equidistant`` (the first ``calib.yaml`` files). Unknown or missing keys raise
    ``ValueError`` naming them and the model's parameters.

    Example:
        >>> cam = camera_from_dict({"model": "double_sphere", "width": 512, "height": 512, "fx": 158.3,
        ...                         "fy": 158.3, "cx": 255.0, "cy": 256.9, "xi": -0.17, "alpha": 0.59})
        >>> camera_from_dict(cam.to_dict()) == cam
        True
    """
    if not isinstance(d, Mapping):
        raise ValueError(f"a camera description must be a mapping, got {type(d).__name__}")
    name = d.get("model", "equidistant")
    if name not in CAMERA_MODELS:
        raise ValueError(f"unknown camera model {name!r}; expected one of {sorted(CAMERA_MODELS)}")
    cls = CAMERA_MODELS[name]
    kwargs = {k: v for k, v in d.items() if k != "model"}
    if cls is KannalaBrandt and _LEGACY_KB_KEYS & kwargs.keys():
        allowed = set(inspect.signature(KannalaBrandt.from_focal).parameters)
        _check_keys(name, kwargs, allowed, {"width", "height"})
        return KannalaBrandt.from_focal(**kwargs)
    required = {"width", "height", *(p.name for p in cls.declaration if p.required)}
    _check_keys(name, kwargs, {"width", "height", *cls.params}, required)
    return cls(**kwargs)


def _check_keys(name: str, kwargs: Mapping[str, Any], allowed: set[str], required: set[str]) -> None:
    unknown = set(kwargs) - allowed
    if unknown:
        raise ValueError(
            f"unknown camera keys {sorted(unknown)} for model {name!r}; expected a subset of "
            f"{sorted(allowed | {'model'})}"
        )
    missing = required - set(kwargs)
    if missing:
        raise ValueError(
            f"camera description of model {name!r} is missing {sorted(missing)}; its parameters are "
            f"{sorted(allowed)} (required: {sorted(required)})"
        )


__all__ = ["CAMERA_MODELS", "camera_from_dict"]
