"""A change of a lens's intrinsics: one unit of a lens design calibrated apart from another.

Training's jitter draws one per sample (:mod:`airfisheye_bench.geometry.lens_draws`); the cross-lens benchmark's
perturbed test lenses and its robustness row apply fixed ones (:mod:`airfisheye_bench.evaluation.cross_lens`). Both
go through :meth:`CameraModel.perturbed`, which says what each field scales.

Example:
    >>> from airfisheye_bench.geometry.cameras import ideal_camera
    >>> change = Perturbation.of(1.02, (0.5, 0.0), (1.0, 1.0))
    >>> change, change.describe()
    (Perturbation(focal=1.02, shift=(0.5, 0.0), distortion=()), 'focal ×1.02, principal point +0.5, +0 px')
    >>> camera = ideal_camera(64, 64, fov_deg=190.0, model="equidistant")
    >>> round(change.apply(camera).focal / camera.focal, 6), Perturbation().apply(camera) is camera
    (1.02, True)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from airfisheye_bench.geometry.cameras.base import CameraModel

__all__ = ["Perturbation"]


@dataclass(frozen=True)
class Perturbation:
    """Focal factor, principal-point shift ``(dx, dy)`` in pixels and factors of the model's distortion terms, in
    order (missing ones: 1). Hashable: part of a remap's cache key."""

    focal: float = 1.0
    shift: tuple[float, float] = (0.0, 0.0)
    distortion: tuple[float, ...] = ()

    @classmethod
    def of(
        cls, focal: float = 1.0, shift: Sequence[float] = (0.0, 0.0), distortion: Sequence[float] = ()
    ) -> Perturbation:
        """A perturbation in its one spelling: no distortion factors when all are 1 (one lens, one key)."""
        factors = tuple(float(f) for f in distortion)
        return cls(
            float(focal),
            (float(shift[0]), float(shift[1])),
            () if all(f == 1.0 for f in factors) else factors,
        )

    @property
    def identity(self) -> bool:
        """Whether it leaves every lens as it is."""
        return self.focal == 1.0 and self.shift == (0.0, 0.0) and all(f == 1.0 for f in self.distortion)

    def describe(self) -> str:
        """What it changes, for a lens's name (``unchanged`` for none)."""
        parts = []
        if self.focal != 1.0:
            parts.append(f"focal ×{self.focal:g}")
        if self.shift != (0.0, 0.0):
            parts.append(f"principal point {self.shift[0]:+g}, {self.shift[1]:+g} px")
        for i, factor in enumerate(self.distortion):
            if factor != 1.0:
                parts.append(f"distortion[{i}] ×{factor:g}")
        return ", ".join(parts) or "unchanged"

    def apply(self, camera: CameraModel) -> CameraModel:
        """``camera`` with these intrinsics (``camera`` itself when :attr:`identity`)."""
        if self.identity:
            return camera
        return camera.perturbed(self.focal, self.shift, self.distortion)
