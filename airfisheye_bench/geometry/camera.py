"""Fisheye camera models: projection of 3-D points to pixels and back-projection of pixels to rays.

A fisheye maps the incidence angle ``theta`` (between a ray and the optical axis) to a radial image distance
``r(theta)`` and keeps the azimuth. The models (``f`` = focal length in pixels):

================  ==========================================  ==========================
model             r(theta)                                    max FOV it can represent
================  ==========================================  ==========================
equidistant       f * theta                                   360 deg
equisolid         2 f sin(theta / 2)                          360 deg
stereographic     2 f tan(theta / 2)                          < 360 deg
orthographic      f sin(theta)                                180 deg
kannala_brandt    f * theta (1 + k1 t^2 + k2 t^4 + k3 t^6 + k4 t^8)   while r(theta) increases
================  ==========================================  ==========================

Conventions (docs/design.md): camera frame x right, y down, z forward; the centre of pixel (row i, col j) is at
``(u=j, v=i)``; the default principal point is the image centre ``((W-1)/2, (H-1)/2)``; unless ``focal`` is given
it is chosen so that the image circle (``theta = FOV/2``) is inscribed in the image: ``r_max = min(W, H) / 2``.
All maths runs in float64 internally; outputs come back in the input's dtype and kind (numpy or torch).
"""

from __future__ import annotations

import math
from functools import cached_property
from typing import Any

import torch

from airfisheye_bench.constants import LENS_MODELS
from airfisheye_bench.geometry._arrays import ArrayLike, as_tensor, back, check_last_dim

MODELS = LENS_MODELS  # the projection models implemented below (defined in constants for the config checks)

_MAX_FOV = {"equidistant": 360.0, "equisolid": 360.0, "stereographic": 360.0, "orthographic": 180.0}


class FisheyeCamera:
    """A central fisheye camera with a radially symmetric lens model.

    Args:
        width: Image width in pixels.
        height: Image height in pixels.
        fov_deg: Full field of view in degrees; pixels with ``theta > fov_deg / 2`` are outside the image circle.
        model: One of ``equidistant`` (default), ``equisolid``, ``stereographic``, ``orthographic``,
            ``kannala_brandt``.
        cx: Principal point column; default ``(width - 1) / 2``.
        cy: Principal point row; default ``(height - 1) / 2``.
        focal: Focal length in pixels; default inscribes the image circle in the image.
        k: Kannala-Brandt coefficients ``(k1, k2, k3, k4)``; only for ``kannala_brandt``.

    Example:
        >>> import numpy as np
        >>> cam = FisheyeCamera(512, 512)  # 190 deg equidistant, image circle inscribed
        >>> uv, valid = cam.project(np.array([[0.0, 0.0, 5.0], [1.0, 0.0, -0.05]]))
        >>> uv[0].round(3).tolist(), valid.tolist()
        ([255.5, 255.5], [True, True])
        >>> np.allclose(cam.unproject(uv[:1]), [[0.0, 0.0, 1.0]])
        True
    """

    def __init__(
        self,
        width: int,
        height: int,
        fov_deg: float = 190.0,
        model: str = "equidistant",
        cx: float | None = None,
        cy: float | None = None,
        focal: float | None = None,
        k: tuple[float, float, float, float] | list[float] | None = None,
    ) -> None:
        if int(width) != width or int(height) != height or width <= 0 or height <= 0:
            raise ValueError(f"width and height must be positive integers, got {width}x{height}")
        if model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}, got {model!r}")
        if not (math.isfinite(fov_deg) and 0.0 < fov_deg <= 360.0):
            raise ValueError(f"fov_deg must be in (0, 360], got {fov_deg}")
        if model in _MAX_FOV and (
            fov_deg > _MAX_FOV[model] or (model == "stereographic" and fov_deg >= 360.0)
        ):
            raise ValueError(
                f"fov_deg={fov_deg} cannot be represented by the {model} model (maximum {_MAX_FOV[model]:g} deg"
                f"{', exclusive' if model == 'stereographic' else ''})"
            )
        if model == "kannala_brandt":
            k = tuple(float(x) for x in (k if k is not None else (0.0, 0.0, 0.0, 0.0)))
            if len(k) != 4 or not all(math.isfinite(x) for x in k):
                raise ValueError(f"k must be four finite Kannala-Brandt coefficients (k1..k4), got {k}")
        elif k is not None and any(float(x) != 0.0 for x in k):
            raise ValueError(
                f"k (distortion coefficients) is only used by the kannala_brandt model, not {model!r}"
            )
        else:
            k = (0.0, 0.0, 0.0, 0.0)

        self.width = int(width)
        self.height = int(height)
        self.fov_deg = float(fov_deg)
        self.model = model
        self.k = tuple(k)
        self.max_theta = math.radians(self.fov_deg) / 2.0
        if model == "kannala_brandt":
            self._check_kb_monotonic()
        self.cx = float(cx) if cx is not None else (self.width - 1) / 2.0
        self.cy = float(cy) if cy is not None else (self.height - 1) / 2.0
        if focal is None:
            focal = (min(self.width, self.height) / 2.0) / self._radius_unit(self.max_theta)
        if not (math.isfinite(focal) and focal > 0):
            raise ValueError(f"focal must be a positive number of pixels, got {focal}")
        self.focal = float(focal)
        self._grid_cache: dict[tuple[torch.dtype, str], torch.Tensor] = {}

    # ------------------------------------------------------------------ lens model (unit focal)
    def _radius_unit(self, theta: Any) -> Any:
        """``r(theta) / f`` for a float or a float64 tensor."""
        lib = torch if isinstance(theta, torch.Tensor) else math
        if self.model == "equidistant":
            return theta
        if self.model == "equisolid":
            return 2.0 * lib.sin(theta / 2.0)
        if self.model == "stereographic":
            return 2.0 * lib.tan(theta / 2.0)
        if self.model == "orthographic":
            return lib.sin(theta)
        k1, k2, k3, k4 = self.k
        t2 = theta * theta
        return theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))

    def _kb_derivative(self, theta: torch.Tensor) -> torch.Tensor:
        k1, k2, k3, k4 = self.k
        t2 = theta * theta
        return 1.0 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))

    def _check_kb_monotonic(self) -> None:
        theta = torch.linspace(0.0, self.max_theta, 4097, dtype=torch.float64)
        if (self._kb_derivative(theta) <= 0).any():
            raise ValueError(
                f"k={self.k}: the Kannala-Brandt polynomial is not increasing up to fov_deg/2={self.fov_deg / 2:g} deg,"
                " so it cannot be inverted there; reduce fov_deg or fix the coefficients"
            )

    def _theta_from_radius_unit(self, rho: torch.Tensor) -> torch.Tensor:
        """Inverse lens model: incidence angle for a radial distance ``r / f`` (float64). NaN outside the model."""
        if self.model == "equidistant":
            return rho
        if self.model == "equisolid":
            return torch.where(rho <= 2.0, 2.0 * torch.asin((rho / 2.0).clamp(max=1.0)), torch.nan)
        if self.model == "stereographic":
            return 2.0 * torch.atan(rho / 2.0)
        if self.model == "orthographic":
            return torch.where(rho <= 1.0, torch.asin(rho.clamp(max=1.0)), torch.nan)
        return self._kb_inverse(rho)

    def _kb_inverse(self, rho: torch.Tensor) -> torch.Tensor:
        """Solve ``theta_d(theta) = rho`` for ``theta`` (float64); NaN where no solution exists.

        ``theta_d`` increases on ``[0, theta_hi]`` (checked up to FOV/2 at construction), so the root is unique.
        A dense table bracket each root; linear interpolation inside the bracket gives a start within ~1e-9 rad and
        Newton steps clamped to the bracket polish it to machine precision, independently of the coefficients.
        """
        theta_hi = self._kb_monotonic_limit()
        table_theta = torch.linspace(0.0, theta_hi, 1 << 14, dtype=torch.float64)
        table_rho = self._radius_unit(table_theta)
        solvable = (rho >= 0) & (rho <= table_rho[-1])
        idx = torch.searchsorted(table_rho, rho.clamp(0.0, float(table_rho[-1]))).clamp(1, len(table_rho) - 1)
        lo, hi = table_theta[idx - 1], table_theta[idx]
        r0, r1 = table_rho[idx - 1], table_rho[idx]
        theta = lo + (hi - lo) * (rho - r0) / (r1 - r0)
        for _ in range(3):
            theta = (theta - (self._radius_unit(theta) - rho) / self._kb_derivative(theta)).clamp(lo, hi)
        return torch.where(solvable, theta, torch.nan)

    def _kb_monotonic_limit(self) -> float:
        """Largest angle (<= pi) up to which the KB polynomial keeps increasing."""
        theta = torch.linspace(0.0, math.pi, 8193, dtype=torch.float64)
        bad = (self._kb_derivative(theta) <= 0).nonzero()
        return float(theta[bad[0, 0] - 1]) if len(bad) else math.pi

    # ------------------------------------------------------------------ public API
    def project(self, points: ArrayLike) -> tuple[ArrayLike, ArrayLike]:
        """Project camera-frame points ``[..., 3]`` to pixels.

        Returns:
            ``(uv [..., 2], valid [...])``. ``valid`` is True for points in front of the lens within ``FOV/2`` of the
            optical axis whose pixel lies inside the image. Points beyond ``FOV/2`` (including those behind the
            camera) are never wrapped into the image: they are reported invalid.
        """
        p, was_numpy = as_tensor(points, "points")
        check_last_dim(p, 3, "points")
        out_dtype = p.dtype
        p = p.to(torch.float64)
        batch_shape = p.shape[:-1]
        # Contiguous coordinates: torch's vectorised hypot/atan2 run only on contiguous inputs (8x faster).
        x, y, z = p.reshape(-1, 3).T.contiguous()
        rho_xy = torch.hypot(x, y)
        theta = torch.atan2(rho_xy, z)
        r = self.focal * self._radius_unit(theta)
        # Direction in the image plane. rho_xy is 0 only on the optical axis, where x = y = 0 and the clamped
        # division gives 0: the axis maps to the principal point with no special case.
        rho_c = rho_xy.clamp_min(1e-300)
        u = self.cx + r * (x / rho_c)
        v = self.cy + r * (y / rho_c)
        uv = torch.stack([u, v], -1).view(*batch_shape, 2)
        # NaN anywhere fails the comparisons below; what they cannot catch is z = +-inf with finite x, y (theta
        # 0 or pi) and the origin itself (theta 0).
        valid = (
            torch.isfinite(z)
            & ((rho_xy > 0) | (z != 0))
            & (theta <= self.max_theta + 1e-12)
            & (u >= -0.5)
            & (u <= self.width - 0.5)
            & (v >= -0.5)
            & (v <= self.height - 0.5)
        ).view(batch_shape)
        return back(uv.to(out_dtype), was_numpy), back(valid, was_numpy)

    def unproject(self, uv: ArrayLike) -> ArrayLike:
        """Back-project pixels ``[..., 2]`` to unit rays ``[..., 3]`` in the camera frame.

        Pixels whose radius the lens model cannot produce (e.g. beyond ``r = f`` for orthographic) give NaN rays.
        Rays beyond ``FOV/2`` are returned as the model extends them; ``valid_mask`` marks the image circle.
        """
        q, was_numpy = as_tensor(uv, "uv")
        check_last_dim(q, 2, "uv")
        out_dtype = q.dtype
        q = q.to(torch.float64)
        dx = q[..., 0] - self.cx
        dy = q[..., 1] - self.cy
        r = torch.hypot(dx, dy)
        theta = self._theta_from_radius_unit(r / self.focal)
        s = torch.sin(theta)
        safe = r > 0
        rays = torch.stack(
            [
                torch.where(safe, s * dx / r.clamp_min(1e-300), 0.0),
                torch.where(safe, s * dy / r.clamp_min(1e-300), 0.0),
                torch.cos(theta),
            ],
            -1,
        )
        return back(rays.to(out_dtype), was_numpy)

    def pixel_grid(self, dtype: torch.dtype = torch.float64) -> torch.Tensor:
        """Pixel-centre coordinates ``[H, W, 2]`` as ``(u, v)``."""
        v, u = torch.meshgrid(
            torch.arange(self.height, dtype=dtype), torch.arange(self.width, dtype=dtype), indexing="ij"
        )
        return torch.stack([u, v], -1)

    def ray_grid(
        self, dtype: torch.dtype = torch.float32, device: torch.device | str | None = None
    ) -> torch.Tensor:
        """Unit rays through every pixel centre ``[H, W, 3]`` (cached per dtype and device)."""
        key = (dtype, str(device or "cpu"))
        if key not in self._grid_cache:
            self._grid_cache[key] = self._rays64.to(dtype=dtype, device=device)
        return self._grid_cache[key]

    def theta_grid(self) -> torch.Tensor:
        """Incidence angle (radians, float32) of every pixel ``[H, W]``; NaN where the model has no ray."""
        return self._theta64.to(torch.float32)

    def valid_mask(self) -> torch.Tensor:
        """``[H, W]`` bool: the pixel lies inside the image circle (``theta <= FOV/2``)."""
        return self._valid

    @cached_property
    def _rays64(self) -> torch.Tensor:
        return self.unproject(self.pixel_grid())

    @cached_property
    def _theta64(self) -> torch.Tensor:
        return torch.acos(self._rays64[..., 2].clamp(-1.0, 1.0))

    @cached_property
    def _valid(self) -> torch.Tensor:
        theta = self._theta64
        return torch.isfinite(theta) & (theta <= self.max_theta + 1e-12)

    # ------------------------------------------------------------------ identity and serialisation
    def resized(self, width: int, height: int) -> FisheyeCamera:
        """The same lens seen by a sensor of another resolution (focal and principal point scaled).

        Pixel centres scale about the image corner ``(-0.5, -0.5)``, so the default principal point and the
        inscribed image circle are preserved exactly.
        """
        sx, sy = width / self.width, height / self.height
        if not math.isclose(sx, sy, rel_tol=1e-9):
            raise ValueError(
                f"resized() keeps the aspect ratio: {self.width}x{self.height} -> {width}x{height}"
            )
        return FisheyeCamera(
            width,
            height,
            self.fov_deg,
            self.model,
            cx=(self.cx + 0.5) * sx - 0.5,
            cy=(self.cy + 0.5) * sy - 0.5,
            focal=self.focal * sx,
            k=self.k if self.model == "kannala_brandt" else None,
        )

    def key(self) -> tuple:
        """Hashable identity of the camera (for lookup-table caches)."""
        return (self.width, self.height, self.fov_deg, self.model, self.cx, self.cy, self.focal, self.k)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, FisheyeCamera) and self.key() == other.key()

    def __hash__(self) -> int:
        return hash(self.key())

    def __repr__(self) -> str:
        extra = f", k={self.k}" if self.model == "kannala_brandt" else ""
        return (
            f"FisheyeCamera({self.width}x{self.height}, fov={self.fov_deg:g} deg, {self.model}, "
            f"f={self.focal:.3f}, c=({self.cx:.3f}, {self.cy:.3f}){extra})"
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python description (for ``calib.yaml`` and ONNX metadata)."""
        d: dict[str, Any] = {
            "model": self.model,
            "width": self.width,
            "height": self.height,
            "fov_deg": self.fov_deg,
            "cx": self.cx,
            "cy": self.cy,
            "focal": self.focal,
        }
        if self.model == "kannala_brandt":
            d["k"] = list(self.k)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> FisheyeCamera:
        """Inverse of :meth:`to_dict`; unknown keys raise ``ValueError`` naming them."""
        allowed = {"model", "width", "height", "fov_deg", "cx", "cy", "focal", "k"}
        unknown = set(d) - allowed
        if unknown:
            raise ValueError(f"unknown camera keys {sorted(unknown)}; expected a subset of {sorted(allowed)}")
        missing = {"width", "height"} - set(d)
        if missing:
            raise ValueError(f"camera description is missing {sorted(missing)}")
        return cls(**{key: d[key] for key in d})


def incidence_angle(points: ArrayLike) -> ArrayLike:
    """Angle (radians) between camera-frame points ``[..., 3]`` and the optical axis."""
    p, was_numpy = as_tensor(points, "points")
    check_last_dim(p, 3, "points")
    return back(torch.atan2(torch.hypot(p[..., 0], p[..., 1]), p[..., 2]), was_numpy)


__all__ = ["MODELS", "FisheyeCamera", "incidence_angle"]
