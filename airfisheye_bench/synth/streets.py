"""The street grid every environment is laid out on: streets (roads, lane markings, zebra crossings, sidewalks), the
blocks between them, and what lines the streets (parked and driving vehicles, street lights, signs, sidewalk
trees, benches, bins)."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from airfisheye_bench.synth.builder import Color, SceneBuilder
from airfisheye_bench.synth.objects import (
    BARE,
    LANE,
    ROAD,
    WALK,
    bench,
    bin_,
    sign_post,
    street_light,
    tree,
    uniform,
    vehicle,
)

__all__ = ["Block", "Street", "Style", "sidewalk_life", "street_grid", "street_objects"]


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


def sidewalk_life(b: SceneBuilder, streets: list[Street], trees: float) -> None:
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
