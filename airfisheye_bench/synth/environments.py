"""Procedural environments in the spirit of the paper's four Unreal Engine scenes.

============== ==========================================================================================
name           what it looks like
============== ==========================================================================================
suburban       detached houses with gable/hip roofs on lawns, driveways, hedges, fences, garden trees,
               pools, parks with ponds; two-lane streets with parked cars and street lights
modular_houses denser, more varied small houses (flat, pyramid, gable roofs), garden walls, bare
               building plots with lorries, a lake
town           perimeter blocks of 3-6 storey buildings (flat and gable roofs) around parking courtyards
               or gardens, sidewalk trees, benches, bins, signs, vans
downtown       towers on podiums up to ~110 m, plazas, wide multi-lane roads with lorries, traffic
               lights, a canal
============== ==========================================================================================

Every layout is a street grid (roads with lane markings and zebra crossings, sidewalks) whose blocks are filled
by the environment's block styles. All randomness comes from one ``numpy.random.Generator`` seeded with
``(environment index, seed, size in mm)``, so a layout is identical on every machine.

Example:
    >>> data = build_environment("town", seed=1, size_m=150.0)
    >>> len(data.prims) > 50
    True
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from airfisheye_bench.synth.builder import Color, SceneBuilder, SceneData
from airfisheye_bench.synth.objects import (
    BARE,
    FLAT_ROOFS,
    GRASS,
    LANE,
    PARK,
    ROAD,
    ROOFS,
    TOWERS,
    WALK,
    WALLS,
    WATER,
    barrier,
    bench,
    bin_,
    bush,
    flat_building,
    house,
    pick,
    sign_post,
    street_light,
    tree,
    uniform,
    vehicle,
)

__all__ = ["ENVIRONMENTS", "build_environment"]

ENVIRONMENTS: tuple[str, ...] = ("suburban", "modular_houses", "town", "downtown")


@dataclass
class Street:
    """One straight street across the scene: ``vertical`` streets run along y at ``x = pos``."""

    pos: float
    width: float
    walk: float
    vertical: bool
    lanes: int  # lanes per direction


@dataclass
class Block:
    """The buildable rectangle between streets."""

    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def w(self) -> float:
        return self.x1 - self.x0

    @property
    def h(self) -> float:
        return self.y1 - self.y0


@dataclass
class Style:
    """Street-grid parameters of an environment."""

    block: tuple[float, float]
    road: tuple[float, float]
    walk: tuple[float, float]
    lanes: int = 1
    park_density: float = 0.4  # parked vehicles per curb metre / 6
    drive_density: float = 0.15
    vehicle_mix: tuple[float, float, float] = (0.8, 0.15, 0.05)  # car, van, lorry
    light_spacing: float = 30.0
    utility_poles: bool = False


# ---------------------------------------------------------------------------------------------- streets
def _positions(rng: np.random.Generator, half: float, style: Style) -> list[tuple[float, float, float]]:
    out = []
    pos = -half + uniform(rng, 10.0, 0.6 * style.block[0])
    while pos < half - 10.0:
        w, ws = uniform(rng, *style.road), uniform(rng, *style.walk)
        out.append((pos, w, ws))
        pos += w / 2 + ws + uniform(rng, *style.block) + ws + w / 2
    return out


def street_grid(b: SceneBuilder, style: Style) -> tuple[list[Street], list[Block]]:
    """Paint a grid of streets (sidewalks, roads, markings, zebra crossings); return streets and blocks."""
    rng, half = b.rng, b.half
    xs = _positions(rng, half, style)
    ys = _positions(rng, half, style)
    streets = [Street(p, w, ws, True, style.lanes) for p, w, ws in xs] + [
        Street(p, w, ws, False, style.lanes) for p, w, ws in ys
    ]

    def rect(
        st: Street, a0: float, a1: float, c0: float, c1: float, raw: str, color: Color, noise: float = 0.0
    ):
        # (a along the street, c across it relative to its centre) -> world rectangle
        if st.vertical:
            b.paint_rect(st.pos + c0, a0, st.pos + c1, a1, raw, color, noise)
        else:
            b.paint_rect(a0, st.pos + c0, a1, st.pos + c1, raw, color, noise)

    for st in streets:
        edge = st.width / 2 + st.walk
        rect(st, -half, half, -edge, edge, "sidewalk", b.jitter(WALK, 0.02, 0.06))
    for st in streets:
        rect(st, -half, half, -st.width / 2, st.width / 2, "road", b.jitter(ROAD, 0.01, 0.08), noise=0.06)
    crossings = {True: [s for s in streets if not s.vertical], False: [s for s in streets if s.vertical]}
    for st in streets:
        lane_w = st.width / (2 * st.lanes)
        lines = [(0.0, st.lanes > 1)] + [(k * lane_w * s, False) for k in range(1, st.lanes) for s in (-1, 1)]
        a = -half
        while a < half:  # dashed lines, solid double centre line on multi-lane roads
            for c, solid in lines:
                if solid:
                    for sgn in (-1, 1):
                        rect(st, a, a + 6.0, c + sgn * 0.15 - 0.1, c + sgn * 0.15 + 0.1, "lane_marking", LANE)
                else:
                    rect(st, a, a + 3.0, c - 0.15, c + 0.15, "lane_marking", LANE)
            a += 6.0
    # Clear the markings inside intersections, then paint zebra crossings on their approaches.
    for st in streets:
        for cr in crossings[st.vertical]:
            half_c = cr.width / 2
            rect(
                st,
                cr.pos - half_c,
                cr.pos + half_c,
                -st.width / 2,
                st.width / 2,
                "road",
                b.jitter(ROAD, 0.01, 0.05),
            )
            if rng.random() < 0.6:
                for sgn in (-1, 1):
                    a0 = cr.pos + sgn * (half_c + cr.walk * 0.3)
                    a1 = a0 + sgn * 3.0
                    c = -st.width / 2 + 0.3
                    while c < st.width / 2 - 0.5:
                        rect(st, min(a0, a1), max(a0, a1), c, c + 0.5, "lane_marking", LANE)
                        c += 1.0
    blocks = []
    xe = [(-half - 1.0, 0.0, 0.0), *xs, (half + 1.0, 0.0, 0.0)]
    ye = [(-half - 1.0, 0.0, 0.0), *ys, (half + 1.0, 0.0, 0.0)]
    for (xa, wa, wsa), (xb, wb, wsb) in itertools.pairwise(xe):
        for (ya, ha, hsa), (yb, hb, hsb) in itertools.pairwise(ye):
            x0 = max(xa + wa / 2 + wsa, -half + 2.0)
            x1 = min(xb - wb / 2 - wsb, half - 2.0)
            y0 = max(ya + ha / 2 + hsa, -half + 2.0)
            y1 = min(yb - hb / 2 - hsb, half - 2.0)
            if x1 - x0 > 12.0 and y1 - y0 > 12.0:
                blocks.append(Block(x0, y0, x1, y1))
    return streets, blocks


def street_objects(
    b: SceneBuilder, streets: list[Street], style: Style, traffic_lights: bool = False
) -> None:
    """Vehicles (parked and driving), street lights / utility poles and signs along every street."""
    rng, half = b.rng, b.half
    crossing = {True: [s for s in streets if not s.vertical], False: [s for s in streets if s.vertical]}
    kinds = ("car", "van", "lorry")
    for st in streets:
        base_yaw = math.pi / 2 if st.vertical else 0.0

        def near_crossing(a: float, margin: float, st: Street = st) -> bool:
            return any(abs(a - cr.pos) < cr.width / 2 + cr.walk + margin for cr in crossing[st.vertical])

        def world(a: float, c: float, st: Street = st) -> tuple[float, float]:
            return (st.pos + c, a) if st.vertical else (a, st.pos + c)

        lane_w = st.width / (2 * st.lanes)
        for side in (-1, 1):  # right-hand traffic: side +1 drives along +a
            yaw = base_yaw if side > 0 else base_yaw + math.pi
            slots = [(st.width / 2 - 1.1, style.park_density)] + [
                ((k + 0.5) * lane_w, style.drive_density) for k in range(st.lanes)
            ]
            for c_off, density in slots:
                a = -half + uniform(rng, 0.0, 10.0)
                while a < half - 6.0:
                    if rng.random() < density and not near_crossing(a, 5.0):
                        kind = kinds[
                            int(rng.choice(3, p=np.asarray(style.vehicle_mix) / sum(style.vehicle_mix)))
                        ]
                        x, y = world(a, -side * c_off if st.vertical else side * c_off)
                        length = vehicle(b, x, y, yaw, kind)
                        a += length + uniform(rng, 1.0, 4.0)
                    else:
                        a += uniform(rng, 4.0, 9.0)
        # Street lights (or utility poles) alternating sides; signs at some corners.
        a = -half + uniform(rng, 0.0, style.light_spacing)
        side = 1
        while a < half:
            if not near_crossing(a, 2.0):
                c = side * (st.width / 2 + 0.6)
                x, y = world(a, c)
                if style.utility_poles:
                    b.add_cylinder(
                        x, y, 0.14, 0.0, uniform(rng, 8.0, 10.0), "pole", b.jitter((0.42, 0.33, 0.24))
                    )
                else:
                    toward = (
                        (0.0 if side < 0 else math.pi)
                        if st.vertical
                        else (math.pi / 2 if side < 0 else -math.pi / 2)
                    )
                    street_light(b, x, y, toward, uniform(rng, 7.0, 9.0))
            side = -side
            a += style.light_spacing
        for cr in crossing[st.vertical]:
            for sgn in (-1, 1):
                if rng.random() < (0.5 if traffic_lights else 0.25):
                    a = cr.pos + sgn * (cr.width / 2 + cr.walk + 1.0)
                    c = sgn * (st.width / 2 + 0.5)
                    x, y = world(a, c)
                    sign_post(b, x, y, base_yaw, traffic_light=traffic_lights)


# ----------------------------------------------------------------------------------------------- blocks
class _Frame:
    """A block edge: ``u`` runs along the street, ``v`` goes inward from the block edge."""

    def __init__(self, block: Block, edge: int) -> None:
        self.block = block
        self.edge = edge  # 0 south (v = +y), 1 north (v = -y), 2 west (v = +x), 3 east (v = -x)
        self.length = block.w if edge < 2 else block.h
        self.depth = block.h if edge < 2 else block.w
        self.yaw = 0.0 if edge < 2 else math.pi / 2

    def world(self, u: float, v: float) -> tuple[float, float]:
        b = self.block
        if self.edge == 0:
            return b.x0 + u, b.y0 + v
        if self.edge == 1:
            return b.x0 + u, b.y1 - v
        if self.edge == 2:
            return b.x0 + v, b.y0 + u
        return b.x1 - v, b.y0 + u

    def paint(
        self,
        sb: SceneBuilder,
        u0: float,
        v0: float,
        u1: float,
        v1: float,
        raw: str,
        color: Color,
        noise: float = 0.0,
    ) -> None:
        xa, ya = self.world(u0, v0)
        xb, yb = self.world(u1, v1)
        sb.paint_rect(min(xa, xb), min(ya, yb), max(xa, xb), max(ya, yb), raw, color, noise)


def residential_block(b: SceneBuilder, blk: Block, lot_width: tuple[float, float], modular: bool) -> None:
    """Two rows of lots, each with a house, lawn, driveway, plants, boundaries and extras."""
    rng = b.rng
    b.paint_rect(blk.x0, blk.y0, blk.x1, blk.y1, "grass", b.jitter(GRASS, 0.03, 0.1))
    edges = (0, 1) if blk.w >= blk.h else (2, 3)
    for edge in edges:
        fr = _Frame(blk, edge)
        depth = fr.depth / 2
        u = 0.0
        while u < fr.length - 8.0:
            w = min(uniform(rng, *lot_width), fr.length - u)
            if fr.length - (u + w) < 8.0:
                w = fr.length - u
            _lot(b, fr, u, u + w, depth, modular)
            u += w


def _lot(b: SceneBuilder, fr: _Frame, u0: float, u1: float, depth: float, modular: bool) -> None:
    rng = b.rng
    width = u1 - u0
    fr.paint(b, u0, 0.0, u1, depth, "grass", b.jitter(GRASS, 0.04, 0.15))
    if modular and rng.random() < 0.1:  # bare building plot
        fr.paint(
            b, u0 + 0.5, 0.5, u1 - 0.5, depth - 0.5, "bare_ground", b.jitter(BARE, 0.05, 0.15), noise=0.15
        )
        if rng.random() < 0.6:
            x, y = fr.world(u0 + width / 2, depth * 0.4)
            vehicle(b, x, y, fr.yaw, "lorry")
        for _ in range(int(rng.integers(0, 4))):
            x, y = fr.world(uniform(rng, u0 + 2, u1 - 2), uniform(rng, 3, depth - 3))
            b.add_box(
                x,
                y,
                0.0,
                uniform(rng, 1, 3),
                uniform(rng, 1, 3),
                uniform(rng, 0.5, 1.5),
                uniform(rng, 0, 3),
                "wall",
                b.jitter((0.6, 0.55, 0.5)),
            )
        return
    along = min(width - 4.0, uniform(rng, 8.0, 13.0) if not modular else uniform(rng, 7.0, 11.0))
    deep = min(depth - 8.0, uniform(rng, 7.5, 11.0))
    setback = uniform(rng, 4.0, 7.5) if not modular else uniform(rng, 3.0, 5.0)
    uc = u0 + width / 2 + uniform(rng, -1.0, 1.0) * max(0.0, (width - along - 4.0) / 2)
    if along > 5.0 and deep > 5.0:
        x, y = fr.world(uc, setback + deep / 2)
        if modular:
            roof = pick(rng, ["flat", "flat", "pyramid", "gable", "hip"])
            floors = int(rng.integers(1, 4))
        else:
            roof = pick(rng, ["gable", "gable", "hip", "hip", "pyramid"])
            floors = int(rng.integers(1, 3))
        house(b, x, y, along, deep, fr.yaw, floors, roof)
        # Driveway to the street beside the house, with a car on it.
        du = uc + along / 2 + 1.8 if rng.random() < 0.5 else uc - along / 2 - 1.8
        if u0 + 1.5 < du < u1 - 1.5:
            fr.paint(
                b,
                du - 1.5,
                0.0,
                du + 1.5,
                setback + deep * 0.8,
                "parking",
                b.jitter((0.58, 0.56, 0.53), 0.03, 0.1),
            )
            if rng.random() < 0.6:
                x, y = fr.world(du, setback * 0.5 + 1.5)
                vehicle(b, x, y, fr.yaw + math.pi / 2, "car" if rng.random() < 0.85 else "van")
        for _ in range(int(rng.integers(1, 5))):  # bushes along the front
            x, y = fr.world(uc + uniform(rng, -along / 2, along / 2), setback - uniform(rng, 0.8, 1.5))
            bush(b, x, y, 0.8)
    back = setback + deep + 1.5
    if depth - back > 4.0:
        if rng.random() < (0.15 if not modular else 0.05):
            fr.paint(
                b,
                uc - 2.0,
                back + 0.5,
                uc + 2.0,
                min(back + 8.5, depth - 1.0),
                "water",
                b.jitter((0.2, 0.45, 0.55)),
            )
        elif rng.random() < 0.25:
            fr.paint(
                b,
                u0 + 1.0,
                back,
                u0 + min(6.0, width - 2),
                min(back + 5.0, depth - 1.0),
                "bare_ground",
                b.jitter(BARE, 0.04, 0.15),
                noise=0.2,
            )
        for _ in range(int(rng.integers(0, 3 if not modular else 2))):
            x, y = fr.world(uniform(rng, u0 + 2.5, u1 - 2.5), uniform(rng, back + 1.5, depth - 1.5))
            tree(b, x, y, uniform(rng, 0.7, 1.1))
        for _ in range(int(rng.integers(0, 3))):
            x, y = fr.world(uniform(rng, u0 + 1.0, u1 - 1.0), uniform(rng, back, depth - 1.0))
            bush(b, x, y)
    # Lot boundaries: side line and back line.
    kind = pick(
        rng,
        ["fence", "fence", "hedge", "wall", "none"]
        if not modular
        else ["wall", "wall", "fence", "hedge", "none"],
    )
    if kind != "none":
        height = {
            "fence": uniform(rng, 1.0, 1.8),
            "hedge": uniform(rng, 1.0, 2.0),
            "wall": uniform(rng, 0.8, 2.0),
        }[kind]
        xa, ya = fr.world(u1, 2.0)
        xb, yb = fr.world(u1, depth - 0.5)
        barrier(b, xa, ya, xb, yb, kind, height)
        xa, ya = fr.world(u0, depth - 0.5)
        barrier(b, xa, ya, xb, yb, kind, height)
        if rng.random() < 0.3:  # low front boundary
            xa, ya = fr.world(u0 + 0.5, 0.5)
            xb, yb = fr.world(u0 + width * 0.35, 0.5)
            barrier(b, xa, ya, xb, yb, kind, 0.9)


def park_block(b: SceneBuilder, blk: Block, pond: bool) -> None:
    """Lawn, crossing paths, a pond, many trees, bush clusters and benches."""
    rng = b.rng
    b.paint_rect(blk.x0, blk.y0, blk.x1, blk.y1, "grass", b.jitter(GRASS, 0.04, 0.12))
    cx, cy = (blk.x0 + blk.x1) / 2 + uniform(rng, -5, 5), (blk.y0 + blk.y1) / 2 + uniform(rng, -5, 5)
    b.paint_rect(blk.x0, cy - 1.5, blk.x1, cy + 1.5, "sidewalk", b.jitter((0.7, 0.64, 0.52)))
    b.paint_rect(cx - 1.5, blk.y0, cx + 1.5, blk.y1, "sidewalk", b.jitter((0.7, 0.64, 0.52)))
    pond_xy = None
    if pond:
        rx, ry = min(blk.w, blk.h) * uniform(rng, 0.12, 0.22), min(blk.w, blk.h) * uniform(rng, 0.1, 0.2)
        px = blk.x0 + blk.w * uniform(rng, 0.25, 0.35)
        py = blk.y0 + blk.h * uniform(rng, 0.65, 0.75)
        b.paint_ellipse(px, py, rx + 1.5, ry + 1.5, "bare_ground", b.jitter(BARE))
        b.paint_ellipse(px, py, rx, ry, "water", b.jitter(WATER, 0.03, 0.1))
        pond_xy = (px, py, rx + 2.5, ry + 2.5)
    n = int(blk.w * blk.h / uniform(rng, 90.0, 160.0))
    for _ in range(n):
        x, y = uniform(rng, blk.x0 + 2, blk.x1 - 2), uniform(rng, blk.y0 + 2, blk.y1 - 2)
        if abs(x - cx) < 3.5 or abs(y - cy) < 3.5:
            continue
        if pond_xy and ((x - pond_xy[0]) / pond_xy[2]) ** 2 + ((y - pond_xy[1]) / pond_xy[3]) ** 2 < 1:
            continue
        if rng.random() < 0.7:
            tree(b, x, y, uniform(rng, 0.8, 1.3))
        else:
            bush(b, x, y, 1.3)
    for _ in range(int(rng.integers(2, 7))):
        if rng.random() < 0.5:
            bench(b, uniform(rng, blk.x0 + 3, blk.x1 - 3), cy + 2.3, 0.0)
        else:
            bench(b, cx + 2.3, uniform(rng, blk.y0 + 3, blk.y1 - 3), math.pi / 2)
    if rng.random() < 0.5:
        bin_(b, cx + 2.5, cy + 2.5)


def town_block(b: SceneBuilder, blk: Block, floors: tuple[int, int], gable: float) -> None:
    """Perimeter buildings around a parking or garden courtyard."""
    rng = b.rng
    b.paint_rect(blk.x0, blk.y0, blk.x1, blk.y1, "sidewalk", b.jitter((0.6, 0.58, 0.55)))
    depth = uniform(rng, 10.0, 15.0)
    inner = Block(blk.x0 + depth + 2, blk.y0 + depth + 2, blk.x1 - depth - 2, blk.y1 - depth - 2)
    for edge in range(4):
        fr = _Frame(blk, edge)
        u0 = depth if edge >= 2 else 0.0
        u1 = fr.length - (depth if edge >= 2 else 0.0)
        u = u0
        while u < u1 - 6.0:
            w = min(uniform(rng, 12.0, 28.0), u1 - u)
            if u1 - (u + w) < 8.0:
                w = u1 - u
            if rng.random() < 0.12 and w < u1 - u:  # alley
                u += uniform(rng, 3.0, 6.0)
                continue
            x, y = fr.world(u + w / 2, depth / 2)
            n = int(rng.integers(floors[0], floors[1] + 1))
            wall = b.jitter(pick(rng, WALLS), 0.04, 0.1)
            if rng.random() < gable:
                house_h = n * 3.1
                b.add_box(
                    x,
                    y,
                    0.0,
                    w - 0.2,
                    depth,
                    house_h,
                    fr.yaw,
                    "building",
                    wall,
                    texture="facade",
                    params=(3.1, uniform(rng, 2.4, 3.2)),
                )
                b.add_roof(
                    x,
                    y,
                    house_h,
                    w - 0.2,
                    depth + 0.8,
                    depth * uniform(rng, 0.3, 0.45),
                    fr.yaw,
                    "gable",
                    "roof",
                    b.jitter(pick(rng, ROOFS)),
                    params=(0.35, 0.0),
                )
            else:
                flat_building(
                    b, x, y, w - 0.2, depth, fr.yaw, n * 3.2, 3.2, wall, spacing=uniform(rng, 2.2, 3.2)
                )
            u += w
    if inner.w < 8 or inner.h < 8:
        return
    if rng.random() < 0.6:
        b.paint_rect(inner.x0, inner.y0, inner.x1, inner.y1, "parking", b.jitter(PARK, 0.02, 0.08))
        y = inner.y0 + 3.0
        while y < inner.y1 - 3.0:
            x = inner.x0 + 1.5
            while x < inner.x1 - 1.5:
                b.paint_rect(x - 0.06, y - 2.5, x + 0.06, y + 2.5, "lane_marking", LANE)
                if rng.random() < 0.65 and x + 2.6 < inner.x1:
                    vehicle(
                        b,
                        x + 1.3,
                        y,
                        math.pi / 2 * (1 if rng.random() < 0.5 else -1),
                        "car" if rng.random() < 0.8 else "van",
                    )
                x += 2.6
            y += 7.0
    else:
        b.paint_rect(inner.x0, inner.y0, inner.x1, inner.y1, "grass", b.jitter(GRASS))
        for _ in range(int(inner.w * inner.h / 80.0)):
            x, y = uniform(rng, inner.x0 + 1, inner.x1 - 1), uniform(rng, inner.y0 + 1, inner.y1 - 1)
            (tree if rng.random() < 0.5 else bush)(b, x, y)


def downtown_block(b: SceneBuilder, blk: Block, plaza: float) -> None:
    """One to four parcels: towers on podiums, mid-rise blocks or plazas."""
    rng = b.rng
    b.paint_rect(blk.x0, blk.y0, blk.x1, blk.y1, "sidewalk", b.jitter((0.66, 0.64, 0.6)))
    parcels = [blk]
    for _ in range(int(rng.integers(0, 3))):
        p = parcels.pop(int(np.argmax([q.w * q.h for q in parcels])))
        if p.w >= p.h and p.w > 40:
            cut = p.x0 + p.w * uniform(rng, 0.4, 0.6)
            parcels += [Block(p.x0, p.y0, cut - 2, p.y1), Block(cut + 2, p.y0, p.x1, p.y1)]
        elif p.h > 40:
            cut = p.y0 + p.h * uniform(rng, 0.4, 0.6)
            parcels += [Block(p.x0, p.y0, p.x1, cut - 2), Block(p.x0, cut + 2, p.x1, p.y1)]
        else:
            parcels.append(p)
    for p in parcels:
        cx, cy = (p.x0 + p.x1) / 2, (p.y0 + p.y1) / 2
        r = rng.random()
        if r < plaza:
            b.paint_rect(p.x0, p.y0, p.x1, p.y1, "sidewalk", b.jitter((0.75, 0.72, 0.66), 0.03, 0.1))
            if rng.random() < 0.5:
                b.add_cylinder(
                    cx, cy, min(p.w, p.h) * 0.15 + 0.3, 0.0, 0.5, "wall", b.jitter((0.7, 0.7, 0.68))
                )
                b.paint_ellipse(
                    cx, cy, min(p.w, p.h) * 0.15, min(p.w, p.h) * 0.15, "water", b.jitter((0.2, 0.4, 0.5))
                )
            for _ in range(int(p.w * p.h / 120.0)):
                x, y = uniform(rng, p.x0 + 2, p.x1 - 2), uniform(rng, p.y0 + 2, p.y1 - 2)
                if abs(x - cx) < min(p.w, p.h) * 0.2 + 1 and abs(y - cy) < min(p.w, p.h) * 0.2 + 1:
                    continue
                k = rng.random()
                if k < 0.45:
                    b.paint_rect(x - 1.2, y - 1.2, x + 1.2, y + 1.2, "bare_ground", b.jitter(BARE))
                    tree(b, x, y, 0.9, conifer=False)
                elif k < 0.7:
                    bench(b, x, y, pick(rng, [0.0, math.pi / 2]))
                elif k < 0.85:
                    bin_(b, x, y)
                else:
                    b.paint_rect(x - 2, y - 2, x + 2, y + 2, "grass", b.jitter(GRASS))
                    bush(b, x, y, 1.2)
            continue
        wall = b.jitter(pick(rng, TOWERS), 0.04, 0.1)
        floor_h = uniform(rng, 3.4, 4.0)
        if r < plaza + (1 - plaza) * 0.65 and p.w > 20 and p.h > 20:
            podium = int(rng.integers(1, 4)) * floor_h
            flat_building(
                b,
                cx,
                cy,
                p.w - 1,
                p.h - 1,
                0.0,
                podium,
                floor_h,
                b.jitter(pick(rng, WALLS)),
                spacing=3.0,
                rooftop=0,
            )
            tw, th = p.w * uniform(rng, 0.45, 0.75), p.h * uniform(rng, 0.45, 0.75)
            height = podium + uniform(rng, 25.0, 105.0)
            tx = cx + uniform(rng, -1, 1) * (p.w - tw) / 4
            ty = cy + uniform(rng, -1, 1) * (p.h - th) / 4
            b.add_box(
                tx,
                ty,
                podium,
                tw,
                th,
                height - podium,
                0.0,
                "building",
                wall,
                texture="facade",
                params=(floor_h, uniform(rng, 1.6, 2.6)),
            )
            b.add_roof(
                tx,
                ty,
                height,
                tw,
                th,
                0.8,
                0.0,
                "flat",
                "roof",
                b.jitter(pick(rng, FLAT_ROOFS)),
                params=(0.0, 0.0),
            )
            if rng.random() < 0.5:  # setback crown
                b.add_box(
                    tx,
                    ty,
                    height + 0.8,
                    tw * 0.6,
                    th * 0.6,
                    uniform(rng, 4, 12),
                    0.0,
                    "roof",
                    b.jitter((0.5, 0.5, 0.52)),
                )
        else:
            n = int(rng.integers(5, 12))
            flat_building(
                b,
                cx,
                cy,
                p.w - 1,
                p.h - 1,
                0.0,
                n * floor_h,
                floor_h,
                wall,
                spacing=uniform(rng, 1.8, 3.0),
                rooftop=3,
            )


def forest_edge(b: SceneBuilder, width: float, density: float) -> None:
    """Trees along the border, so the horizon is not an empty plain."""
    rng, half = b.rng, b.half
    n = int(4 * 2 * half * width * density / 100.0)
    for _ in range(n):
        side = int(rng.integers(4))
        a = uniform(rng, -half + 2, half - 2)
        c = half - uniform(rng, 2.0, width)
        x, y = [(a, -c), (a, c), (-c, a), (c, a)][side]
        tree(b, x, y, uniform(rng, 0.9, 1.4))


# ----------------------------------------------------------------------------------------- environments
def _suburban(b: SceneBuilder) -> None:
    style = Style(
        block=(70.0, 100.0),
        road=(7.0, 9.0),
        walk=(1.8, 2.8),
        park_density=0.35,
        drive_density=0.08,
        light_spacing=32.0,
    )
    streets, blocks = street_grid(b, style)
    for blk in blocks:
        r = b.rng.random()
        if r < 0.15:
            park_block(b, blk, pond=b.rng.random() < 0.6)
        else:
            residential_block(b, blk, (16.0, 24.0), modular=False)
    street_objects(b, streets, style)
    forest_edge(b, 12.0, 0.5)


def _modular_houses(b: SceneBuilder) -> None:
    style = Style(
        block=(55.0, 80.0),
        road=(6.0, 7.5),
        walk=(1.5, 2.2),
        park_density=0.45,
        drive_density=0.06,
        vehicle_mix=(0.7, 0.22, 0.08),
        light_spacing=40.0,
        utility_poles=True,
    )
    streets, blocks = street_grid(b, style)
    lake = int(b.rng.integers(len(blocks))) if blocks else -1
    for i, blk in enumerate(blocks):
        if i == lake:
            b.paint_rect(blk.x0, blk.y0, blk.x1, blk.y1, "grass", b.jitter(GRASS))
            b.paint_ellipse(
                (blk.x0 + blk.x1) / 2,
                (blk.y0 + blk.y1) / 2,
                blk.w * 0.42,
                blk.h * 0.42,
                "bare_ground",
                b.jitter(BARE),
            )
            b.paint_ellipse(
                (blk.x0 + blk.x1) / 2,
                (blk.y0 + blk.y1) / 2,
                blk.w * 0.38,
                blk.h * 0.38,
                "water",
                b.jitter(WATER),
            )
            for _ in range(12):
                a = uniform(b.rng, 0, 2 * math.pi)
                tree(
                    b,
                    (blk.x0 + blk.x1) / 2 + 0.46 * blk.w * math.cos(a),
                    (blk.y0 + blk.y1) / 2 + 0.46 * blk.h * math.sin(a),
                )
        elif b.rng.random() < 0.08:
            park_block(b, blk, pond=False)
        else:
            residential_block(b, blk, (11.0, 16.0), modular=True)
    street_objects(b, streets, style)
    forest_edge(b, 10.0, 0.4)


def _town(b: SceneBuilder) -> None:
    style = Style(
        block=(55.0, 85.0),
        road=(8.0, 11.0),
        walk=(2.5, 4.0),
        park_density=0.5,
        drive_density=0.2,
        vehicle_mix=(0.72, 0.22, 0.06),
        light_spacing=25.0,
    )
    streets, blocks = street_grid(b, style)
    for blk in blocks:
        if b.rng.random() < 0.12:
            park_block(b, blk, pond=b.rng.random() < 0.3)
        else:
            town_block(b, blk, (3, 6), gable=0.3)
    street_objects(b, streets, style)
    _sidewalk_life(b, streets, trees=0.6)


def _downtown(b: SceneBuilder) -> None:
    style = Style(
        block=(60.0, 95.0),
        road=(14.0, 19.0),
        walk=(3.5, 5.5),
        lanes=2,
        park_density=0.3,
        drive_density=0.3,
        vehicle_mix=(0.6, 0.25, 0.15),
        light_spacing=25.0,
    )
    streets, blocks = street_grid(b, style)
    # A canal replaces one street.
    canal = pick(b.rng, streets) if streets else None
    for blk in blocks:
        if b.rng.random() < 0.08:
            park_block(b, blk, pond=True)
        else:
            downtown_block(b, blk, plaza=0.2)
    street_objects(b, [s for s in streets if s is not canal], style, traffic_lights=True)
    _sidewalk_life(b, [s for s in streets if s is not canal], trees=0.8)
    if canal is not None:
        w = canal.width
        lo, hi = (canal.pos - w / 2, canal.pos + w / 2)
        h = b.half
        if canal.vertical:
            b.paint_rect(lo, -h, hi, h, "water", b.jitter(WATER, 0.02, 0.05))
        else:
            b.paint_rect(-h, lo, h, hi, "water", b.jitter(WATER, 0.02, 0.05))
        # Railings along both banks.
        for c in (lo - 0.2, hi + 0.2):
            for a in np.arange(-h, h, 20.0):
                xa, ya, xb, yb = (c, a, c, a + 20.0) if canal.vertical else (a, c, a + 20.0, c)
                barrier(b, xa, ya, xb, yb, "fence", 1.1)


def _sidewalk_life(b: SceneBuilder, streets: list[Street], trees: float) -> None:
    """Street trees in tree pits, benches and bins on wide sidewalks."""
    rng, half = b.rng, b.half
    crossing = {True: [s for s in streets if not s.vertical], False: [s for s in streets if s.vertical]}
    for st in streets:
        if st.walk < 2.4:
            continue
        for side in (-1, 1):
            a = -half + uniform(rng, 0, 12)
            while a < half:
                if not any(abs(a - cr.pos) < cr.width / 2 + cr.walk + 3 for cr in crossing[st.vertical]):
                    c = side * (st.width / 2 + st.walk * 0.55)
                    x, y = (st.pos + c, a) if st.vertical else (a, st.pos + c)
                    r = rng.random()
                    if r < trees:
                        b.paint_rect(x - 0.8, y - 0.8, x + 0.8, y + 0.8, "bare_ground", b.jitter(BARE))
                        tree(b, x, y, 0.75, conifer=False)
                    elif r < trees + 0.15:
                        bench(b, x, y, math.pi / 2 if st.vertical else 0.0)
                    elif r < trees + 0.3:
                        bin_(b, x, y)
                a += uniform(rng, 10.0, 18.0)


_GENERATORS: dict[str, Callable[[SceneBuilder], None]] = {
    "suburban": _suburban,
    "modular_houses": _modular_houses,
    "town": _town,
    "downtown": _downtown,
}
_GROUND: dict[str, tuple[str, Color]] = {
    "suburban": ("grass", GRASS),
    "modular_houses": ("grass", GRASS),
    "town": ("grass", GRASS),
    "downtown": ("sidewalk", WALK),
}


def build_environment(env: str, seed: int, size_m: float = 400.0) -> SceneData:
    """Generate the layout of environment ``env`` (deterministic for ``(env, seed, size_m)``)."""
    if env not in _GENERATORS:
        raise ValueError(f"env must be one of {ENVIRONMENTS}, got {env!r}")
    if int(seed) < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed}")
    rng = np.random.default_rng([ENVIRONMENTS.index(env), int(seed), round(size_m * 1000)])
    b = SceneBuilder(size_m, rng, ground=_GROUND[env])
    _GENERATORS[env](b)
    return b.finish()
