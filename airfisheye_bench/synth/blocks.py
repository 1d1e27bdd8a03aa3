"""What fills a block between streets: residential lots (house, lawn, driveway, plants, boundaries), parks,
town perimeter blocks around courtyards, and downtown towers on podiums."""

from __future__ import annotations

import math

import numpy as np

from airfisheye_bench.synth.builder import Color, SceneBuilder
from airfisheye_bench.synth.objects import (
    BARE,
    FLAT_ROOFS,
    GRASS,
    LANE,
    PARK,
    ROOFS,
    TOWERS,
    WALLS,
    WATER,
    barrier,
    bench,
    bin_,
    bush,
    flat_building,
    house,
    pick,
    tree,
    uniform,
    vehicle,
)
from airfisheye_bench.synth.streets import Block

__all__ = ["downtown_block", "park_block", "residential_block", "town_block"]


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
