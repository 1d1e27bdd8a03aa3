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

Every layout is a street grid (roads with lane markings and zebra crossings, sidewalks;
:mod:`~airfisheye_bench.synth.streets`) whose blocks are filled by the environment's block styles
(:mod:`~airfisheye_bench.synth.blocks`); this module holds each environment's recipe and the table of them.
All randomness comes from one ``numpy.random.Generator`` seeded with ``(environment index, seed, size in mm)``,
so a layout is identical on every machine.

Example:
    >>> data = build_environment("town", seed=1, size_m=150.0)
    >>> len(data.prims) > 50
    True
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from airfisheye_bench.synth.blocks import downtown_block, park_block, residential_block, town_block
from airfisheye_bench.synth.builder import Color, SceneBuilder, SceneData
from airfisheye_bench.synth.objects import (
    BARE,
    GRASS,
    WALK,
    WATER,
    barrier,
    pick,
    tree,
    uniform,
)
from airfisheye_bench.synth.streets import Style, sidewalk_life, street_grid, street_objects

__all__ = ["ENVIRONMENTS", "build_environment"]

ENVIRONMENTS: tuple[str, ...] = ("suburban", "modular_houses", "town", "downtown")


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
    sidewalk_life(b, streets, trees=0.6)


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
    sidewalk_life(b, [s for s in streets if s is not canal], trees=0.8)
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
