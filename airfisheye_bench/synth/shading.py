"""Lighting, procedural textures and shading for the synthetic renderer.

Everything here works on flat per-ray tensors and uses only IEEE-exact elementwise operations (no ``exp``,
``pow`` or ``sin`` on ray data, no reductions), so a pixel's colour is bit-identical however the rays were
batched. Colours are stored as linear albedo (the square of an sRGB-like value) and displayed with a gamma of 2
(``sqrt``), which is exact.

Texture kinds (per primitive, see :data:`TEXTURES`): ``plain`` (mottled), ``facade`` (wall with a grid of
windows; params: floor height, window spacing), ``roof`` (tile rows; param: row spacing, 0 = gravel),
``foliage``, ``vehicle`` (painted body), ``cabin`` (glass sides, painted top), ``bark``, ``slats`` (fence
boards; param: board width).

Example:
    >>> import torch
    >>> light = Lighting.random(torch.Generator().manual_seed(0))
    >>> 20.0 <= light.sun_elevation_deg <= 75.0
    True
    >>> sky = sky_color(torch.tensor([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]), light)
    >>> sky.shape, bool((sky >= 0).all() and (sky <= 1).all())
    (torch.Size([2, 3]), True)
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch

from airfisheye_bench.geometry import portable
from airfisheye_bench.synth._ops import select, take

__all__ = [
    "TEXTURES",
    "Lighting",
    "shade",
    "sky_color",
    "surface_albedo",
    "value_noise",
]

TEXTURES: dict[str, int] = {
    "plain": 0,
    "facade": 1,
    "roof": 2,
    "foliage": 3,
    "vehicle": 4,
    "cabin": 5,
    "bark": 6,
    "slats": 7,
}


@dataclass(frozen=True)
class Lighting:
    """Sun and sky of one trajectory.

    Attributes:
        sun_elevation_deg: sun height above the horizon.
        sun_azimuth_deg: sun direction, counter-clockwise from +x (east) seen from above.
        sun_intensity: irradiance scale of the direct sun light.
        sun_color: linear RGB tint of the sun light.
        ambient: strength of the sky (ambient) light.
        ambient_color: linear RGB tint of the ambient light.
        sky_zenith: display RGB of the sky straight up.
        sky_horizon: display RGB of the sky at the horizon (also the haze colour).
        haze_distance: distance (m) at which objects are half blended into the haze.
        exposure: multiplier applied before display.

    Example:
        >>> Lighting().sun_direction()[2] > 0
        True
    """

    sun_elevation_deg: float = 50.0
    sun_azimuth_deg: float = 135.0
    sun_intensity: float = 2.2
    sun_color: tuple[float, float, float] = (1.0, 0.95, 0.85)
    ambient: float = 0.55
    ambient_color: tuple[float, float, float] = (0.75, 0.85, 1.0)
    sky_zenith: tuple[float, float, float] = (0.30, 0.50, 0.85)
    sky_horizon: tuple[float, float, float] = (0.75, 0.83, 0.92)
    haze_distance: float = 1500.0
    exposure: float = 1.0

    def sun_direction(self) -> tuple[float, float, float]:
        """Unit vector pointing from the scene towards the sun (world frame, z up)."""
        el, az = math.radians(self.sun_elevation_deg), math.radians(self.sun_azimuth_deg)
        return (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))

    def to_dict(self) -> dict:
        """Plain-Python form (for metadata files)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def random(cls, generator: torch.Generator) -> Lighting:
        """Sunny daylight with random sun position, strength and sky tint (deterministic for the generator).

        Example:
            >>> a = Lighting.random(torch.Generator().manual_seed(3))
            >>> a == Lighting.random(torch.Generator().manual_seed(3))
            True
        """
        u = torch.rand(12, generator=generator, dtype=torch.float64).tolist()
        el = 20.0 + 55.0 * u[0]
        warm = 0.12 * (1.0 - (el - 20.0) / 55.0) * u[1]  # low sun: warmer light
        zen = (0.22 + 0.12 * u[5], 0.42 + 0.12 * u[6], 0.78 + 0.15 * u[7])
        hor = (0.68 + 0.15 * u[8], 0.76 + 0.12 * u[8], 0.86 + 0.1 * u[9])
        return cls(
            sun_elevation_deg=el,
            sun_azimuth_deg=360.0 * u[2],
            sun_intensity=1.7 + 0.9 * u[3],
            sun_color=(1.0, 0.95 - 0.5 * warm, 0.86 - warm),
            ambient=0.4 + 0.3 * u[4],
            ambient_color=(0.72 + 0.1 * u[10], 0.83, 1.0),
            sky_zenith=zen,
            sky_horizon=hor,
            haze_distance=900.0 + 1500.0 * u[11],
            exposure=1.0,
        )


def _vec(values: tuple[float, float, float], like: torch.Tensor) -> torch.Tensor:
    return torch.tensor(values, dtype=torch.float32, device=like.device)


# ------------------------------------------------------------------------------------------------- noise
# Lattice values of the value noise: a fixed 256 x 256 table (a cheap gather instead of an integer hash; the
# per-object seed shifts the lattice, so objects do not share a pattern).
_LATTICE = torch.rand(65536, generator=torch.Generator().manual_seed(20240613), dtype=torch.float32)
_LATTICES: dict[torch.device, torch.Tensor] = {}


def _lattice(device: torch.device) -> torch.Tensor:
    if device not in _LATTICES:
        _LATTICES[device] = _LATTICE.to(device)
    return _LATTICES[device]


def _hash(ix: torch.Tensor, iy: torch.Tensor, seed: torch.Tensor | int) -> torch.Tensor:
    """Pseudo-random value in [0, 1) per integer lattice point (int32 coordinates) and seed."""
    if isinstance(seed, torch.Tensor):
        seed = seed.to(torch.int32)
    idx = ((ix + seed * 97) & 255) | (((iy + seed * 57) & 255) << 8)
    return take(_lattice(ix.device), idx)


def value_noise(x: torch.Tensor, y: torch.Tensor, seed: torch.Tensor | int = 0) -> torch.Tensor:
    """Smooth 2-D value noise in [0, 1) with unit lattice spacing (scale the coordinates to change it).

    Example:
        >>> n = value_noise(torch.linspace(0, 10, 50), torch.zeros(50))
        >>> bool((n >= 0).all() and (n < 1).all())
        True
    """
    fx, fy = torch.floor(x), torch.floor(y)
    ix, iy = fx.to(torch.int32), fy.to(torch.int32)
    tx, ty = x - fx, y - fy
    sx = tx * tx * (3.0 - 2.0 * tx)
    sy = ty * ty * (3.0 - 2.0 * ty)
    n00, n10 = _hash(ix, iy, seed), _hash(ix + 1, iy, seed)
    n01, n11 = _hash(ix, iy + 1, seed), _hash(ix + 1, iy + 1, seed)
    a = n00 + sx * (n10 - n00)
    b = n01 + sx * (n11 - n01)
    return a + sy * (b - a)


def _frac(x: torch.Tensor) -> torch.Tensor:
    return x - torch.floor(x)


def _cell(x: torch.Tensor) -> torch.Tensor:
    return torch.floor(x).to(torch.int32)


# ------------------------------------------------------------------------------------------------ albedo
def surface_albedo(
    texture: torch.Tensor,
    base: torch.Tensor,
    params: torch.Tensor,
    seed: torch.Tensor,
    point: torch.Tensor,
    uv: torch.Tensor,
    face: torch.Tensor,
) -> torch.Tensor:
    """Textured linear albedo ``[K, 3]`` of object hits.

    Args:
        texture: ``[K]`` texture kind (:data:`TEXTURES`).
        base: ``[K, 3]`` the object's linear base albedo (already varied per object).
        params: ``[K, 2]`` texture parameters.
        seed: ``[K]`` int64 per-object seed.
        point: ``[K, 3]`` world hit points.
        uv: ``[K, 2]`` face coordinates in metres (see :mod:`~airfisheye_bench.synth.primitives`).
        face: ``[K]`` face kind (0 side, 1 top, 2 bottom).
    """
    u, v = uv[:, 0], uv[:, 1]
    px, py, pz = point[:, 0], point[:, 1], point[:, 2]
    seed = seed.to(torch.int32)
    fine = value_noise(u * 2.0, v * 2.0, seed)
    coarse = value_noise(px * 0.15 + pz * 0.1, py * 0.15, seed + 7)
    factor = 0.88 + 0.16 * fine + 0.08 * coarse  # mottling shared by every kind
    side = face == 0

    # Roof tiles: darker seams every row (param: row spacing; 0 = gravel, which keeps the mottling).
    rows = params[:, 0]
    has_rows = (texture == TEXTURES["roof"]) & (rows > 0)
    row_w = rows.clamp(min=1e-3)
    seam = has_rows & (_frac(v / row_w) < 0.15)
    tile = 0.85 + 0.3 * _hash(_cell(u / 0.4), _cell(v / row_w), seed)
    factor = factor * select(seam, torch.full_like(tile, 0.55), select(has_rows, tile, 1.0))
    # Fence slats: gaps between boards (param: board width).
    gap = (texture == TEXTURES["slats"]) & side & (_frac(u / row_w) < 0.25)
    factor = factor * select(gap, torch.full_like(factor, 0.35), 1.0)
    # Foliage: strong leafy contrast at two scales; bark: vertical streaks.
    leaf = value_noise(u * 3.0, v * 3.0, seed + 11)
    streak = value_noise(u * 4.0, v * 0.3, seed + 3)
    factor = select(texture == TEXTURES["foliage"], 0.45 + 0.9 * leaf * (0.6 + 0.5 * coarse), factor)
    factor = select(texture == TEXTURES["bark"], 0.6 + 0.7 * streak, factor)
    albedo = base * factor.unsqueeze(1)

    # Glass: facade windows on side faces (params: floor height, window spacing) and vehicle cabin sides.
    floor_h, spacing = params[:, 0].clamp(min=1e-3), params[:, 1].clamp(min=1e-3)
    wu, wv = _frac(u / spacing), _frac(v / floor_h)
    window = (texture == TEXTURES["facade"]) & side & (wu > 0.22) & (wu < 0.78) & (wv > 0.3) & (wv < 0.82)
    pane = _hash(_cell(u / spacing), _cell(v / floor_h), seed)
    glass = torch.stack([0.02 + 0.03 * pane, 0.03 + 0.04 * pane, 0.05 + 0.06 * pane], dim=1)
    cabin = (texture == TEXTURES["cabin"]) & side
    tint = 0.02 * fine
    dark = torch.stack([0.015 + tint, 0.02 + tint, 0.03 + tint], dim=1)
    glass = select(cabin.unsqueeze(1), dark, glass)
    return select((window | cabin).unsqueeze(1), glass, albedo)


def ground_albedo(
    raw: torch.Tensor, base: torch.Tensor, point: torch.Tensor, class_ids: dict[str, int]
) -> torch.Tensor:
    """Textured linear albedo ``[K, 3]`` of ground hits from the painted base colour ``[K, 3]``."""
    x, y = point[:, 0], point[:, 1]
    fine = value_noise(x * 3.0, y * 3.0, 101)
    mid = value_noise(x * 0.5, y * 0.5, 202)
    coarse = value_noise(x * 0.06, y * 0.06, 303)
    grassy = ((raw == class_ids["grass"]) | (raw == class_ids["bare_ground"])).to(x.dtype)
    amp_fine = 0.16 + 0.29 * grassy
    amp_mid = 0.1 + 0.25 * grassy
    factor = 1.0 + amp_fine * (fine - 0.5) + amp_mid * (mid - 0.5) + 0.2 * (coarse - 0.5)
    paved = (raw == class_ids["sidewalk"]) & ((_frac(x / 1.2) < 0.04) | (_frac(y / 1.2) < 0.04))
    factor = factor * (1.0 - 0.3 * paved.to(x.dtype))
    return base * factor.unsqueeze(1)


# ---------------------------------------------------------------------------------------------- shading
def sky_color(dirs: torch.Tensor, lighting: Lighting) -> torch.Tensor:
    """Display RGB ``[N, 3]`` of the sky along unit directions: horizon-to-zenith gradient plus a sun glow."""
    up = dirs[:, 2].clamp(0.0, 1.0)
    s = portable.sqrt(up).unsqueeze(1)
    hor, zen = _vec(lighting.sky_horizon, dirs), _vec(lighting.sky_zenith, dirs)
    sky = hor + s * (zen - hor)
    lx, ly, lz = lighting.sun_direction()
    c = (dirs[:, 0] * lx + dirs[:, 1] * ly + dirs[:, 2] * lz).clamp(min=0.0)
    c2 = c * c
    c8 = c2 * c2
    c8 = c8 * c8
    c64 = c8 * c8
    c64 = c64 * c64
    c64 = c64 * c64
    c512 = c64 * c64
    c512 = c512 * c512
    c512 = c512 * c512
    glow = (0.25 * c8 + 0.5 * c64 + 2.0 * c512).unsqueeze(1)
    return (sky + glow * _vec((1.0, 0.92, 0.75), dirs)).clamp(0.0, 1.0)


def shade(
    albedo: torch.Tensor,
    normal: torch.Tensor,
    dirs: torch.Tensor,
    dist: torch.Tensor,
    sunlit: torch.Tensor,
    water: torch.Tensor,
    lighting: Lighting,
) -> torch.Tensor:
    """Display RGB ``[K, 3]`` of surface hits.

    Args:
        albedo: ``[K, 3]`` linear albedo.
        normal: ``[K, 3]`` unit normals facing the viewer.
        dirs: ``[K, 3]`` viewing ray directions.
        dist: ``[K]`` hit distances (for haze).
        sunlit: ``[K]`` bool, the shadow ray reached the sun.
        water: ``[K]`` bool, the surface reflects the sky (Schlick Fresnel).
        lighting: the light.
    """
    lx, ly, lz = lighting.sun_direction()
    nx, ny, nz = normal[:, 0], normal[:, 1], normal[:, 2]
    ndl = (nx * lx + ny * ly + nz * lz).clamp(min=0.0) * sunlit.to(albedo.dtype)
    sky_term = lighting.ambient * (0.55 + 0.45 * nz)
    light = sky_term.unsqueeze(1) * _vec(lighting.ambient_color, albedo) + (
        lighting.sun_intensity * ndl
    ).unsqueeze(1) * _vec(lighting.sun_color, albedo)
    lin = albedo * light * lighting.exposure
    rgb = portable.sqrt(lin.clamp(0.0, 1.0))
    # Water: mix in the reflected sky with Schlick's Fresnel term.
    if bool(water.any()):
        cos_i = (-(dirs[:, 0] * nx + dirs[:, 1] * ny + dirs[:, 2] * nz)).clamp(0.0, 1.0)
        m = 1.0 - cos_i
        m2 = m * m
        fres = 0.02 + 0.98 * (m2 * m2 * m)
        refl_dir = torch.stack(
            [dirs[:, 0] + 2.0 * cos_i * nx, dirs[:, 1] + 2.0 * cos_i * ny, dirs[:, 2] + 2.0 * cos_i * nz],
            dim=1,
        )
        refl = sky_color(refl_dir, lighting)
        mixed = rgb + (0.15 + 0.85 * fres).unsqueeze(1) * (refl - rgb)
        rgb = select(water.unsqueeze(1), mixed, rgb)
    # Aerial perspective: blend far surfaces into the horizon colour.
    f = (dist / (dist + lighting.haze_distance)).unsqueeze(1)
    hor = _vec(lighting.sky_horizon, albedo)
    return (rgb + f * (hor - rgb)).clamp(0.0, 1.0)
