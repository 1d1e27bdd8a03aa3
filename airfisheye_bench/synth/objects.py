"""Object builders shared by the environments: trees, bushes, vehicles, street furniture and buildings.

Each function adds a few primitives to a :class:`~airfisheye_bench.synth.builder.SceneBuilder` with a raw class,
a per-object colour variation (drawn from the builder's random generator) and a texture. The palettes are
sRGB-like base colours; some are deliberately shared across classes (grey flat roofs and asphalt, white vans and
white walls, hedges and lawns) so that segmentation has to use shape as well as colour.

Example:
    >>> import numpy as np
    >>> from airfisheye_bench.synth.builder import SceneBuilder
    >>> b = SceneBuilder(40.0, np.random.default_rng(0))
    >>> length = vehicle(b, 0.0, 0.0, 0.0, "lorry")
    >>> tree(b, 10.0, 10.0)
    >>> 8.0 <= length <= 11.0 and len(b.finish().prims) >= 6
    True
"""

from __future__ import annotations

import math

import numpy as np

from airfisheye_bench.synth.builder import Color, SceneBuilder

__all__ = [
    "barrier",
    "bench",
    "bin_",
    "bush",
    "flat_building",
    "house",
    "pick",
    "sign_post",
    "street_light",
    "tree",
    "uniform",
    "vehicle",
]

# sRGB-like base colours; every object jitters its own.
WALLS: list[Color] = [
    (0.92, 0.9, 0.84),
    (0.86, 0.79, 0.64),
    (0.78, 0.77, 0.74),
    (0.93, 0.86, 0.62),
    (0.68, 0.37, 0.29),
    (0.62, 0.68, 0.73),
    (0.8, 0.62, 0.47),
]
ROOFS: list[Color] = [
    (0.56, 0.23, 0.17),
    (0.3, 0.3, 0.32),
    (0.42, 0.29, 0.2),
    (0.23, 0.26, 0.31),
    (0.62, 0.36, 0.26),
]
FLAT_ROOFS: list[Color] = [(0.42, 0.42, 0.41), (0.55, 0.54, 0.5), (0.3, 0.31, 0.32), (0.62, 0.6, 0.58)]
TOWERS: list[Color] = [
    (0.36, 0.44, 0.52),
    (0.55, 0.58, 0.6),
    (0.7, 0.68, 0.62),
    (0.3, 0.33, 0.36),
    (0.45, 0.5, 0.45),
]
CARS: list[Color] = [
    (0.9, 0.9, 0.9),
    (0.08, 0.08, 0.09),
    (0.65, 0.66, 0.68),
    (0.62, 0.08, 0.07),
    (0.12, 0.2, 0.5),
    (0.36, 0.37, 0.39),
    (0.22, 0.32, 0.24),
    (0.75, 0.6, 0.2),
]
GRASS: Color = (0.36, 0.5, 0.22)
BARE: Color = (0.5, 0.41, 0.29)
ROAD: Color = (0.31, 0.31, 0.32)
WALK: Color = (0.62, 0.6, 0.57)
PARK: Color = (0.4, 0.39, 0.38)
LANE: Color = (0.9, 0.9, 0.86)
WATER: Color = (0.12, 0.22, 0.26)
LEAF: Color = (0.22, 0.4, 0.13)
TRUNK: Color = (0.36, 0.26, 0.18)
METAL: Color = (0.46, 0.47, 0.5)


def uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A uniform float in ``[lo, hi)``."""
    return float(rng.uniform(lo, hi))


def pick(rng: np.random.Generator, items: list):
    """One of ``items``, uniformly."""
    return items[int(rng.integers(len(items)))]


# ------------------------------------------------------------------------------------------ small objects
def tree(b: SceneBuilder, x: float, y: float, size: float = 1.0, conifer: bool | None = None) -> None:
    """A tree: trunk cylinder and one or two ellipsoidal crowns (a stacked narrow pair for a conifer)."""
    rng = b.rng
    if conifer is None:
        conifer = rng.random() < 0.2
    leaf = b.jitter(LEAF, 0.05, 0.25)
    if rng.random() < 0.08:  # a few yellowing / reddish crowns
        leaf = b.jitter((0.5, 0.42, 0.14), 0.05, 0.15)
    trunk_h = size * uniform(rng, 1.8, 3.5)
    r_trunk = size * uniform(rng, 0.14, 0.28)
    if conifer:
        rc = size * uniform(rng, 1.6, 2.6)
        hc = size * uniform(rng, 6.0, 10.0)
        b.add_cylinder(x, y, r_trunk, 0.0, trunk_h + 0.5, "trunk", b.jitter(TRUNK), texture="bark")
        z = trunk_h * 0.6
        b.add_ellipsoid(x, y, z + hc * 0.35, rc, rc, hc * 0.38, "tree", leaf)
        b.add_ellipsoid(x, y, z + hc * 0.72, rc * 0.6, rc * 0.6, hc * 0.3, "tree", leaf)
    else:
        rc = size * uniform(rng, 2.2, 4.2)
        hc = rc * uniform(rng, 0.8, 1.3)
        b.add_cylinder(x, y, r_trunk, 0.0, trunk_h + hc * 0.5, "trunk", b.jitter(TRUNK), texture="bark")
        b.add_ellipsoid(x, y, trunk_h + hc * 0.9, rc, rc * uniform(rng, 0.85, 1.15), hc, "tree", leaf)
        if rng.random() < 0.5:
            a = uniform(rng, 0, 2 * math.pi)
            off = rc * 0.5
            b.add_ellipsoid(
                x + off * math.cos(a),
                y + off * math.sin(a),
                trunk_h + hc * 1.2,
                rc * 0.7,
                rc * 0.7,
                hc * 0.7,
                "tree",
                leaf,
            )


def bush(b: SceneBuilder, x: float, y: float, size: float = 1.0) -> None:
    r = size * uniform(b.rng, 0.5, 1.3)
    b.add_ellipsoid(
        x,
        y,
        r * 0.45,
        r,
        r * uniform(b.rng, 0.8, 1.2),
        r * uniform(b.rng, 0.6, 0.9),
        "bush",
        b.jitter(LEAF, 0.06, 0.3),
    )


def vehicle(b: SceneBuilder, x: float, y: float, yaw: float, kind: str) -> float:
    """A car, van or lorry centred at ``(x, y)`` heading along ``yaw``; returns its length."""
    rng = b.rng
    c, s = math.cos(yaw), math.sin(yaw)
    if kind == "car":
        length, width = uniform(rng, 3.9, 4.9), uniform(rng, 1.7, 1.9)
        paint = b.jitter(pick(rng, CARS), 0.03, 0.1)
        b.add_box(x, y, 0.12, length, width, 0.78, yaw, "car", paint, texture="vehicle")
        off = -0.08 * length
        b.add_box(
            x + off * c, y + off * s, 0.9, length * 0.5, width * 0.9, 0.5, yaw, "car", paint, texture="cabin"
        )
    elif kind == "van":
        length, width = uniform(rng, 4.8, 5.8), uniform(rng, 1.9, 2.1)
        paint = b.jitter(
            pick(rng, [(0.92, 0.92, 0.92), (0.92, 0.92, 0.92), (0.65, 0.66, 0.68), *CARS]), 0.03, 0.1
        )
        b.add_box(x, y, 0.15, length, width, uniform(rng, 1.9, 2.3), yaw, "van", paint, texture="vehicle")
        off = 0.5 * length - 0.25
        b.add_box(x + off * c, y + off * s, 1.1, 0.6, width * 0.96, 0.75, yaw, "van", paint, texture="cabin")
    else:
        length, width = uniform(rng, 8.0, 11.0), 2.5
        cab = b.jitter(pick(rng, CARS), 0.03, 0.1)
        cargo = b.jitter(pick(rng, [(0.9, 0.9, 0.88), (0.6, 0.62, 0.64), (0.2, 0.35, 0.6), (0.7, 0.2, 0.15)]))
        cab_l = 2.3
        off = 0.5 * length - cab_l / 2
        b.add_box(x + off * c, y + off * s, 0.45, cab_l, width, 2.0, yaw, "lorry", cab, texture="vehicle")
        b.add_box(x + off * c, y + off * s, 2.45, cab_l * 0.9, width, 0.7, yaw, "lorry", cab, texture="cabin")
        off = -cab_l / 2 - 0.15
        b.add_box(x + off * c, y + off * s, 1.0, length - cab_l - 0.3, width, 2.9, yaw, "lorry", cargo)
        b.add_box(x, y, 0.35, length * 0.95, 1.6, 0.65, yaw, "lorry", (0.12, 0.12, 0.13))
    return length


def street_light(b: SceneBuilder, x: float, y: float, toward: float, height: float = 8.0) -> None:
    """A lamp post at ``(x, y)`` with its arm pointing along ``toward`` (radians)."""
    paint = b.jitter(METAL, 0.03, 0.15)
    b.add_cylinder(x, y, 0.11, 0.0, height, "pole", paint)
    arm = 1.8
    c, s = math.cos(toward), math.sin(toward)
    b.add_box(x + c * arm / 2, y + s * arm / 2, height - 0.15, arm, 0.12, 0.12, toward, "pole", paint)
    b.add_box(x + c * arm, y + s * arm, height - 0.35, 0.7, 0.3, 0.2, toward, "pole", paint)


def sign_post(b: SceneBuilder, x: float, y: float, facing: float, traffic_light: bool = False) -> None:
    paint = b.jitter(METAL, 0.03, 0.15)
    if traffic_light:
        b.add_cylinder(x, y, 0.1, 0.0, 4.2, "pole", paint)
        b.add_box(x, y, 3.0, 0.35, 0.35, 1.0, facing, "traffic_sign", (0.1, 0.1, 0.1))
        return
    plate = pick(b.rng, [(0.75, 0.1, 0.1), (0.1, 0.3, 0.7), (0.9, 0.75, 0.1), (0.9, 0.9, 0.9)])
    b.add_cylinder(x, y, 0.04, 0.0, 2.6, "pole", paint)
    b.add_box(x, y, 2.0, 0.06, 0.7, 0.7, facing, "traffic_sign", b.jitter(plate, 0.03, 0.1))


def bench(b: SceneBuilder, x: float, y: float, yaw: float) -> None:
    wood = b.jitter((0.5, 0.36, 0.22), 0.04, 0.15)
    b.add_box(x, y, 0.0, 1.8, 0.55, 0.45, yaw, "street_furniture", wood, texture="slats", params=(0.12, 0.0))
    c, s = math.cos(yaw + math.pi / 2), math.sin(yaw + math.pi / 2)
    b.add_box(x - 0.25 * c, y - 0.25 * s, 0.45, 1.8, 0.08, 0.45, yaw, "street_furniture", wood)


def bin_(b: SceneBuilder, x: float, y: float) -> None:
    b.add_cylinder(x, y, 0.3, 0.0, 1.0, "street_furniture", b.jitter((0.2, 0.3, 0.22), 0.05, 0.2))


def barrier(b: SceneBuilder, x0: float, y0: float, x1: float, y1: float, kind: str, height: float) -> None:
    """A fence, hedge or wall along the segment ``(x0, y0)-(x1, y1)``."""
    length = math.hypot(x1 - x0, y1 - y0)
    if length < 0.5:
        return
    yaw = math.atan2(y1 - y0, x1 - x0)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    if kind == "fence":
        color = b.jitter(pick(b.rng, [(0.55, 0.42, 0.3), (0.88, 0.88, 0.86), (0.4, 0.33, 0.26)]), 0.03, 0.1)
        b.add_box(cx, cy, 0.0, length, 0.06, height, yaw, "fence", color, texture="slats", params=(0.15, 0.0))
    elif kind == "hedge":
        b.add_box(
            cx, cy, 0.0, length, 0.9, height, yaw, "hedge", b.jitter(LEAF, 0.05, 0.25), texture="foliage"
        )
    else:
        color = b.jitter(pick(b.rng, [(0.6, 0.57, 0.52), (0.68, 0.4, 0.32), (0.85, 0.84, 0.8)]), 0.03, 0.1)
        b.add_box(cx, cy, 0.0, length, 0.25, height, yaw, "wall", color)


# --------------------------------------------------------------------------------------------- buildings
def house(
    b: SceneBuilder,
    cx: float,
    cy: float,
    along: float,
    deep: float,
    yaw: float,
    floors: int,
    roof: str,
    wall: Color | None = None,
) -> None:
    """A house with footprint ``along x deep`` (``along`` parallel to ``yaw``) and a roof of shape ``roof``."""
    rng = b.rng
    wall = b.jitter(wall or pick(rng, WALLS), 0.04, 0.08)
    floor_h = uniform(rng, 2.7, 3.0)
    height = floors * floor_h + 0.3
    b.add_box(
        cx,
        cy,
        0.0,
        along,
        deep,
        height,
        yaw,
        "house",
        wall,
        texture="facade",
        params=(floor_h, uniform(rng, 2.4, 3.4)),
    )
    if roof == "flat":
        b.add_roof(
            cx,
            cy,
            height,
            along + 0.3,
            deep + 0.3,
            0.4,
            yaw,
            "flat",
            "roof",
            b.jitter(pick(rng, FLAT_ROOFS)),
            params=(0.0, 0.0),
        )
        return
    # Ridge along the longer side.
    ryaw, lx, ly = (yaw, along, deep) if along >= deep else (yaw + math.pi / 2, deep, along)
    over = 0.5
    rh = ly * (uniform(rng, 0.3, 0.5) if roof == "gable" else uniform(rng, 0.25, 0.4))
    color = b.jitter(pick(rng, ROOFS), 0.04, 0.12)
    b.add_roof(
        cx,
        cy,
        height,
        lx + 2 * over,
        ly + 2 * over,
        rh,
        ryaw,
        roof,
        "roof",
        color,
        params=(uniform(rng, 0.3, 0.45), 0.0),
    )
    if rng.random() < 0.35:  # chimney
        c, s = math.cos(ryaw), math.sin(ryaw)
        off = lx * uniform(rng, -0.3, 0.3)
        b.add_box(
            cx + off * c, cy + off * s, height, 0.6, 0.6, rh + 0.8, ryaw, "roof", b.jitter((0.5, 0.3, 0.25))
        )


def flat_building(
    b: SceneBuilder,
    cx: float,
    cy: float,
    along: float,
    deep: float,
    yaw: float,
    height: float,
    floor_h: float,
    wall: Color,
    raw: str = "building",
    spacing: float = 2.8,
    rooftop: int = 2,
) -> None:
    """A building with a flat roof (a parapet slab labelled roof) and some rooftop units."""
    rng = b.rng
    b.add_box(cx, cy, 0.0, along, deep, height, yaw, raw, wall, texture="facade", params=(floor_h, spacing))
    roof_c = b.jitter(pick(rng, FLAT_ROOFS), 0.03, 0.1)
    b.add_roof(
        cx, cy, height, along, deep, uniform(rng, 0.3, 0.7), yaw, "flat", "roof", roof_c, params=(0.0, 0.0)
    )
    c, s = math.cos(yaw), math.sin(yaw)
    for _ in range(int(rng.integers(0, rooftop + 1))):
        u, v = uniform(rng, -0.35, 0.35) * along, uniform(rng, -0.35, 0.35) * deep
        b.add_box(
            cx + u * c - v * s,
            cy + u * s + v * c,
            height + 0.4,
            uniform(rng, 1.2, 3.5),
            uniform(rng, 1.0, 2.5),
            uniform(rng, 0.8, 2.2),
            yaw,
            "roof",
            b.jitter((0.6, 0.6, 0.6)),
        )
