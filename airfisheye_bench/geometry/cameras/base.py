"""The interface every camera model implements (docs/design.md, "Fisheye camera").

A model is a small class of one shape, as in COLMAP's ``sensor/models.h`` and basalt's ``camera/`` folder: its
parameters, declared once (``declaration``, a tuple of :class:`~airfisheye_bench.geometry.cameras.params.Param`), a
float64 projection ``_project(x, y, z) -> (u, v, in_region)`` and a float64 back-projection ``_unproject(u, v) ->
(x, y, z)`` (NaN where no ray exists). :class:`CameraModel` derives the constructor, ``params``, ``defaults``,
``to_dict``, ``flat_dict`` and ``resized()`` from the declaration, and wraps the two maps with the numpy/torch
plumbing, the field-of-view limit and the per-pixel grids the rest of the project uses.

Conventions: camera frame x right, y down, z forward; the centre of pixel (row i, col j) is at ``(u=j, v=i)``.
``project`` reports ``valid`` = "the point is in the model's valid region and within ``fov_deg``"; whether its
pixel lies inside the image is the caller's test (:meth:`CameraModel.in_image`). ``unproject`` returns unit rays
for every pixel the model can back-project, also beyond ``fov_deg`` (the image circle is :meth:`valid_mask`), and NaN
where the model has no ray.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Sequence
from functools import cached_property
from typing import Any, ClassVar

import torch

from airfisheye_bench.geometry import portable
from airfisheye_bench.geometry._arrays import ArrayLike, as_tensor, back, check_last_dim
from airfisheye_bench.geometry.cameras.params import FOV_DEG, Param

#: Step (radians) of the central differences behind :meth:`CameraModel.pixels_per_radian`.
_PPR_STEP = 1e-6
#: Pixels per chunk of :meth:`CameraModel.pixels_per_radian` (bounds its temporaries to a few tens of MiB).
_PPR_CHUNK = 1 << 17
_ARG = inspect.Parameter.POSITIONAL_OR_KEYWORD


class CameraModel:
    """Base class of the camera models; a subclass sets ``model`` and ``declaration``, may add ``_setup`` (derived
    quantities and checks across parameters) and implements the two maps.

    The constructor is the declaration's: ``Model(width, height, <params in declaration order>)``, each parameter by
    position or name, defaults filled in, each value checked and stored as an attribute of its name; then
    ``_setup()`` runs. ``inspect.signature(Model)`` shows it.
    """

    #: Registry name (``CAMERA_MODELS`` key, the ``model`` entry of ``to_dict``).
    model: ClassVar[str] = ""
    #: The model's parameters, each declared once, in ``to_dict`` order (besides ``model``, ``width``, ``height``).
    declaration: ClassVar[tuple[Param, ...]] = (FOV_DEG,)
    #: Parameter names in ``to_dict`` order (from ``declaration``).
    params: ClassVar[tuple[str, ...]] = ("fov_deg",)
    #: Parameters that may be left out, with their defaults (from ``declaration``).
    defaults: ClassVar[dict[str, Any]] = {"fov_deg": None}
    #: Parameters that ``to_dict`` and ``key()`` leave out at their defaults (``Param.omit_default``).
    omitted_defaults: ClassVar[dict[str, Any]] = {}
    #: The distortion coefficients, in declaration order (``Param.distortion``).
    distortion_params: ClassVar[tuple[str, ...]] = ()
    #: Whether ``fov_deg`` is an image circle that limits the valid region (every model but the ideal pinhole, whose
    #: ``fov_deg`` is its field of view across the width and whose whole frame is valid).
    fov_limits_region: ClassVar[bool] = True
    #: The constructor's signature (from ``declaration``).
    __signature__: ClassVar[inspect.Signature]

    width: int
    height: int
    fov_deg: float | None

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        _derive_from_declaration(cls)

    def __init__(self, width: int, height: int, *args: Any, **kwargs: Any) -> None:
        values = self._bind(width, height, args, kwargs)
        if (
            isinstance(width, bool)
            or isinstance(height, bool)
            or int(width) != width
            or int(height) != height
        ):
            raise ValueError(f"width and height must be positive integers, got {width}x{height}")
        if width <= 0 or height <= 0:
            raise ValueError(f"width and height must be positive integers, got {width}x{height}")
        self.width = int(width)
        self.height = int(height)
        for p in self.declaration:
            setattr(self, p.name, p.check(p.name, values[p.name]))
        self._grid_cache: dict[tuple[torch.dtype, str], torch.Tensor] = {}
        self._setup()

    @classmethod
    def _bind(cls, width: Any, height: Any, args: tuple, kwargs: dict[str, Any]) -> dict[str, Any]:
        """Every parameter's given or default value; ``TypeError`` for a missing or unknown one, as a def's."""
        bound = cls.__signature__.bind(width, height, *args, **kwargs)
        bound.apply_defaults()
        return bound.arguments

    def _setup(self) -> None:
        """Derived quantities and checks across parameters, once every parameter is checked and set."""

    @classmethod
    def flat_dict(cls, width: int, height: int, *args: Any, **kwargs: Any) -> dict[str, Any]:
        """The flat dict of the camera these constructor arguments describe, without building or checking it
        (``camera_from_dict`` does): what the calibration readers return. Numbers become floats, lists lists of
        floats, and defaults are filled in as ``to_dict`` writes them.

        Example:
            >>> from airfisheye_bench.geometry.cameras import KannalaBrandt
            >>> d = KannalaBrandt.flat_dict(512, 512, 190.0, 190.1, 254.9, 256.8, k1=0.01)
            >>> d["model"], d["k1"], d["k4"], list(d)[3:]
            ('kannala_brandt', 0.01, 0.0, ['fx', 'fy', 'cx', 'cy', 'k1', 'k2', 'k3', 'k4', 'skew'])
        """
        values = cls._bind(width, height, args, kwargs)
        plain = {p.name: _plain(values[p.name]) for p in cls.declaration}
        return cls._flat(int(width), int(height), plain)

    # ------------------------------------------------------------------ the model (float64 tensors)
    def _project(self, x: torch.Tensor, y: torch.Tensor, z: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """``(u, v, in_region)`` of points (not necessarily unit); ``in_region``: the model's valid region."""
        raise NotImplementedError

    def _unproject(self, u: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """``(x, y, z)`` of a ray through each pixel (any positive length); NaN where the model has none."""
        raise NotImplementedError

    # ------------------------------------------------------------------ public API
    @property
    def _fov_limit(self) -> bool:
        """Whether ``fov_deg`` limits the valid region (set, and an image circle: :attr:`fov_limits_region`)."""
        return self.fov_deg is not None and self.fov_limits_region

    @property
    def max_theta(self) -> float:
        """Half the field of view in radians (``pi`` without ``fov_deg``, or where it is no image circle: the
        model's region decides alone)."""
        return math.radians(self.fov_deg) / 2.0 if self._fov_limit else math.pi

    @property
    def coverage_deg(self) -> float:
        """Full field of view the image covers (degrees): ``fov_deg`` when it is the image circle, else twice the
        largest incidence angle of a valid pixel (what the incidence-angle rings must reach)."""
        if self._fov_limit:
            return self.fov_deg
        theta = self._theta64[self._valid]
        return 2.0 * math.degrees(float(theta.max())) if len(theta) else 0.0

    def project(self, points: ArrayLike) -> tuple[ArrayLike, ArrayLike]:
        """Project camera-frame points ``[..., 3]`` to pixels.

        Returns:
            ``(uv [..., 2], valid [...])``. ``valid``: the point is finite, neither the camera centre nor on the
            optical axis behind it, inside the model's
            valid region and within ``fov_deg / 2`` of the optical axis. Whether ``uv`` lies in the image is left to
            the caller (:meth:`in_image`). ``uv`` comes back in the input's kind and dtype.
        """
        p, was_numpy = as_tensor(points, "points")
        check_last_dim(p, 3, "points")
        out_dtype = p.dtype
        batch_shape = p.shape[:-1]
        # Contiguous coordinates: torch's vectorised kernels run only on contiguous inputs (several times faster).
        x, y, z = p.to(torch.float64).reshape(-1, 3).T.contiguous()
        u, v, in_region = self._project(x, y, z)
        finite = torch.isfinite(x) & torch.isfinite(y) & torch.isfinite(z)
        # A point on the optical axis behind the camera has no azimuth (it would map to a whole circle), and the
        # camera centre has no direction: neither projects.
        off_back_axis = (x != 0) | (y != 0) | (z > 0)
        valid = finite & off_back_axis & in_region & torch.isfinite(u) & torch.isfinite(v)
        if self._fov_limit:
            valid &= torch.atan2(torch.hypot(x, y), z) <= self.max_theta + 1e-12
        uv = torch.stack([u, v], -1).view(*batch_shape, 2)
        return back(uv.to(out_dtype), was_numpy), back(valid.view(batch_shape), was_numpy)

    def unproject(self, uv: ArrayLike) -> ArrayLike:
        """Back-project pixels ``[..., 2]`` to unit rays ``[..., 3]`` in the camera frame.

        NaN where the model has no ray (outside its valid region). Rays beyond ``fov_deg / 2`` are returned as the
        model extends them; :meth:`valid_mask` marks the pixels within the field of view.
        """
        q, was_numpy = as_tensor(uv, "uv")
        check_last_dim(q, 2, "uv")
        out_dtype = q.dtype
        batch_shape = q.shape[:-1]
        u, v = q.to(torch.float64).reshape(-1, 2).T.contiguous()  # flat: the solvers index the stragglers
        x, y, z = self._unproject(u, v)
        norm = portable.sqrt(x * x + y * y + z * z)  # the rays a dataset is rendered along
        rays = torch.stack([x / norm, y / norm, z / norm], -1).view(*batch_shape, 3)
        return back(rays.to(out_dtype), was_numpy)

    def in_image(self, uv: ArrayLike) -> ArrayLike:
        """``[...]`` bool: the pixel position lies inside the image ``[-0.5, W - 0.5] x [-0.5, H - 0.5]``."""
        q, was_numpy = as_tensor(uv, "uv")
        check_last_dim(q, 2, "uv")
        u, v = q[..., 0], q[..., 1]
        inside = (u >= -0.5) & (u <= self.width - 0.5) & (v >= -0.5) & (v <= self.height - 0.5)
        return back(inside, was_numpy)

    # ------------------------------------------------------------------ per-pixel grids
    def pixel_grid(self, dtype: torch.dtype = torch.float64) -> torch.Tensor:
        """Pixel-centre coordinates ``[H, W, 2]`` as ``(u, v)``."""
        v, u = torch.meshgrid(
            torch.arange(self.height, dtype=dtype), torch.arange(self.width, dtype=dtype), indexing="ij"
        )
        return torch.stack([u, v], -1)

    def ray_grid(
        self, dtype: torch.dtype = torch.float32, device: torch.device | str | None = None
    ) -> torch.Tensor:
        """Unit rays through every pixel centre ``[H, W, 3]`` (cached per dtype and device); NaN without a ray."""
        key = (dtype, str(device or "cpu"))
        if key not in self._grid_cache:
            self._grid_cache[key] = self._rays64.to(dtype=dtype, device=device)
        return self._grid_cache[key]

    def theta_grid(self) -> torch.Tensor:
        """Incidence angle (radians, float32) of every pixel ``[H, W]``; NaN where the model has no ray."""
        return self._theta64.to(torch.float32)

    def valid_mask(self) -> torch.Tensor:
        """``[H, W]`` bool: the pixel has a ray, within ``fov_deg``, that projects back (the image's valid region)."""
        return self._valid

    def pixels_per_radian(self) -> torch.Tensor:
        """``[H, W]`` float64: the largest local image scale at each pixel, in pixels per radian of ray direction.

        The larger singular value of the projection's Jacobian with respect to the ray direction, by central
        differences (what the z-buffer window of any model needs); pixels without a ray get the scale on the
        optical axis.
        """
        return self._pixels_per_radian

    @cached_property
    def _rays64(self) -> torch.Tensor:
        return self.unproject(self.pixel_grid())

    @cached_property
    def _theta64(self) -> torch.Tensor:
        return torch.acos(self._rays64[..., 2].clamp(-1.0, 1.0))

    @cached_property
    def _valid(self) -> torch.Tensor:
        rays = self._rays64
        _, valid = self.project(rays)
        return valid & torch.isfinite(rays).all(-1)

    @cached_property
    def _pixels_per_radian(self) -> torch.Tensor:
        rays = self._rays64.reshape(-1, 3)
        # In chunks of pixels: a whole 1536^2 image's float64 temporaries (tangents, four projections) peaked at
        # ~630 MiB above the rays themselves; the result is the same, element by element.
        scale = torch.cat([_largest_local_scale(self, chunk) for chunk in rays.split(_PPR_CHUNK)])
        ok = torch.isfinite(scale) & torch.isfinite(rays).all(-1)
        if not ok.all():
            scale = torch.where(ok, scale, self._axis_scale())
        return scale.view(self.height, self.width)

    def _axis_scale(self) -> float:
        """Pixels per radian along the optical axis (fallback of :meth:`pixels_per_radian`)."""
        h = _PPR_STEP
        pts = torch.tensor(
            [
                [math.sin(h), 0, math.cos(h)],
                [-math.sin(h), 0, math.cos(h)],
                [0, math.sin(h), math.cos(h)],
                [0, -math.sin(h), math.cos(h)],
            ],
            dtype=torch.float64,
        )
        uv, _ = self.project(pts)
        return float(max((uv[0] - uv[1]).norm(), (uv[2] - uv[3]).norm()) / (2.0 * h))

    # ------------------------------------------------------------------ identity and serialisation
    def _scaled_params(self, sx: float, sy: float) -> dict[str, Any]:
        """The parameters that change on a sensor scaled by ``sx, sy`` (``Param.scale``), with their new values."""
        return {
            p.name: p.scaled(getattr(self, p.name), sx, sy) for p in self.declaration if p.scale is not None
        }

    def resized(self, width: int, height: int) -> CameraModel:
        """The same lens seen by a sensor of another resolution (intrinsics scaled with the image).

        Each parameter follows its declared rule (``Param.scale``): pixel centres scale about the image corner
        ``(-0.5, -0.5)``, ``c' = (c + 0.5) s - 0.5``, focal lengths (pixel lengths) by ``s``; the aspect ratio must be
        kept (a change of aspect would stretch the lens).
        """
        sx, sy = width / self.width, height / self.height
        if not math.isclose(sx, sy, rel_tol=1e-9):
            raise ValueError(
                f"resized() keeps the aspect ratio: {self.width}x{self.height} -> {width}x{height}"
            )
        params = {**self._param_dict(), **self._scaled_params(sx, sy)}
        return type(self)(width, height, **params)

    def perturbed(
        self, focal: float = 1.0, shift: tuple[float, float] = (0.0, 0.0), distortion: Sequence[float] = ()
    ) -> CameraModel:
        """The same model with other intrinsics, on the same sensor (a lens of the same design, calibrated apart).

        Args:
            focal: Every pixel length (``Param.scale`` other than a position: focal lengths, a polynomial's pixel
                radii) scaled by this factor about the principal point: a zoom.
            shift: ``(dx, dy)`` pixels added to the principal point (the positions ``cx``, ``cy``).
            distortion: Factors of :attr:`distortion_params`, in order (missing ones: 1).

        Example:
            >>> from airfisheye_bench.geometry.cameras import KannalaBrandt
            >>> cam = KannalaBrandt(64, 64, 20.0, 20.0, 31.5, 31.5, k1=0.1, k2=0.01)
            >>> p = cam.perturbed(1.1, (0.5, -1.0), (2.0,))
            >>> round(p.fx, 9), p.cx, p.cy, p.k1, p.k2
            (22.0, 32.0, 30.5, 0.2, 0.01)
        """
        values = self._param_dict()
        for p in self.declaration:
            if p.scale in ("cx", "cy"):
                values[p.name] += shift[0] if p.scale == "cx" else shift[1]
            elif p.scale is not None:
                values[p.name] = p.scaled(values[p.name], focal, focal)
        for name, factor in zip(self.distortion_params, distortion, strict=False):
            values[name] = values[name] * factor
        return type(self)(self.width, self.height, **values)

    def _param_dict(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in self.params}

    def _identity_dict(self) -> dict[str, Any]:
        """:meth:`_param_dict` without the parameters at a default their declaration omits (``Param.omit_default``)."""
        return {k: v for k, v in self._param_dict().items() if not self._omitted(k, v)}

    @classmethod
    def _omitted(cls, name: str, value: Any) -> bool:
        return name in cls.omitted_defaults and value == cls.omitted_defaults[name]

    def key(self) -> tuple:
        """Hashable identity of the camera (for lookup-table caches)."""
        values = tuple(tuple(v) if isinstance(v, list | tuple) else v for v in self._identity_dict().values())
        return (self.model, self.width, self.height, *values)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, CameraModel) and self.key() == other.key()

    def __hash__(self) -> int:
        return hash(self.key())

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={v!r}" for k, v in self._identity_dict().items() if v is not None)
        return f"{type(self).__name__}({self.width}x{self.height}, {inner})"

    def to_dict(self) -> dict[str, Any]:
        """Flat plain-Python description ``{"model", "width", "height", <params>}`` (``calib.yaml``, ONNX
        metadata); ``camera_from_dict`` inverts it. Optional parameters left at ``None`` are omitted, and so are
        those declared ``omit_default`` at their default."""
        return self._flat(self.width, self.height, self._param_dict())

    @classmethod
    def _flat(cls, width: int, height: int, values: dict[str, Any]) -> dict[str, Any]:
        d: dict[str, Any] = {"model": cls.model, "width": width, "height": height}
        for name, value in values.items():
            if (value is None and name in cls.defaults) or cls._omitted(name, value):
                continue
            d[name] = list(value) if isinstance(value, tuple) else value
        return d


def _derive_from_declaration(cls: type[CameraModel]) -> None:
    """``params``, ``defaults`` and the constructor's signature of a model, from its ``declaration``."""
    names = [p.name for p in cls.declaration]
    if len(set(names)) != len(names) or {"model", "width", "height"} & set(names) or "fov_deg" not in names:
        raise TypeError(
            f"{cls.__name__}.declaration: unique names, fov_deg among them (the field-of-view limit), and none of "
            f"model, width, height; got {names}"
        )
    cls.params = tuple(names)
    cls.defaults = {p.name: p.default for p in cls.declaration if not p.required}
    cls.omitted_defaults = {p.name: p.default for p in cls.declaration if p.omit_default}
    cls.distortion_params = tuple(p.name for p in cls.declaration if p.distortion)
    # Signature() refuses a required parameter after an optional one, as a def would: at import.
    cls.__signature__ = inspect.Signature(
        [inspect.Parameter("width", _ARG), inspect.Parameter("height", _ARG)]
        + [inspect.Parameter(p.name, _ARG, default=p.default) for p in cls.declaration]
    )


_derive_from_declaration(CameraModel)


def _plain(value: Any) -> Any:
    """A parameter's value as plain data: a float, a list of floats, or ``None``."""
    if value is None:
        return None
    if isinstance(value, Sequence) and not isinstance(value, str):
        return [float(v) for v in value]
    return float(value)


def _largest_local_scale(camera: CameraModel, rays: torch.Tensor) -> torch.Tensor:
    """``[N]``: the larger singular value of ``camera``'s projection Jacobian at unit rays ``[N, 3]`` (rays
    that are not finite take the optical axis), by central differences along two tangents."""
    has_ray = torch.isfinite(rays).all(-1)
    axis = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    d = torch.where(has_ray[:, None], rays, axis)
    # Two unit tangents orthogonal to d: e1 = normalise(d x a) with a helper axis not parallel to d, e2 = d x e1.
    helper = torch.where(d[:, 2:3].abs() < 0.9, axis, torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64))
    e1 = torch.linalg.cross(d, helper)
    e1 = e1 / e1.norm(dim=-1, keepdim=True)
    e2 = torch.linalg.cross(d, e1)
    h = _PPR_STEP
    cols = []
    for e in (e1, e2):
        plus, _ = camera.project(d * math.cos(h) + e * math.sin(h))
        minus, _ = camera.project(d * math.cos(h) - e * math.sin(h))
        cols.append((plus - minus) / (2.0 * h))
    # Largest singular value of the 2x2 Jacobian [c1 c2]: sqrt of the largest eigenvalue of J^T J.
    a, b, c = (cols[0] * cols[0]).sum(-1), (cols[0] * cols[1]).sum(-1), (cols[1] * cols[1]).sum(-1)
    return torch.sqrt(0.5 * (a + c) + torch.sqrt(0.25 * (a - c) ** 2 + b * b))


def ray_at_incidence(
    theta: torch.Tensor, x: torch.Tensor, y: torch.Tensor, r: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The unit ray at incidence ``theta`` in the direction ``(x, y)`` of the image plane, whose norm is ``r``
    (the back-projection of every radially symmetric model): the optical axis where ``r == 0``, NaN where
    ``theta`` is.

    Example:
        >>> ray = ray_at_incidence(torch.tensor([0.5, 0.3]), torch.tensor([3.0, 0.0]), torch.tensor([4.0, 0.0]),
        ...                        torch.tensor([5.0, 0.0]))
        >>> [round(float(c), 4) for c in torch.stack(ray)[:, 0]], [float(c) for c in torch.stack(ray)[:2, 1]]
        ([0.2877, 0.3835, 0.8776], [0.0, 0.0])
    """
    s = torch.sin(theta) / r.clamp_min(1e-300)
    on_axis = r == 0
    return torch.where(on_axis, 0.0, s * x), torch.where(on_axis, 0.0, s * y), torch.cos(theta)


def incidence_angle(points: ArrayLike) -> ArrayLike:
    """Angle (radians) between camera-frame points ``[..., 3]`` and the optical axis.

    Example:
        >>> import numpy as np
        >>> incidence_angle(np.array([[0.0, 0.0, 2.0], [1.0, 0.0, 0.0]])).round(4).tolist()
        [0.0, 1.5708]
    """
    p, was_numpy = as_tensor(points, "points")
    check_last_dim(p, 3, "points")
    return back(torch.atan2(torch.hypot(p[..., 0], p[..., 1]), p[..., 2]), was_numpy)


__all__ = ["CameraModel", "incidence_angle"]
