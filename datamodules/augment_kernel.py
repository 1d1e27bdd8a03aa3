"""Fused CPU kernel (numba) for the training augmentation of one sample.

The torch composition (flip, rotation grid, two ``grid_sample`` calls, colour transform, clamp, mask) makes about a
dozen passes over the image and cost 5.9 ms per 512^2 completion sample on one core; this single pass over the output
pixels costs ~2 ms (``docs/benchmarks.md``, data loading). Compiled on first use and cached on disk (``cache=True``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


# fastmath lets LLVM reorder the sums (last-bit differences in the image) and is 1.3x faster here.
@njit(cache=True, nogil=True, fastmath=True)
def warp_and_colour(
    rgb, valid, maps, fills, flip, cos_a, sin_a, cx, cy, colour, offset, rgb_out, valid_out, maps_out
):  # pragma: no cover - compiled
    """Flip, then rotate about ``(cx, cy)``, every map of a sample; colour-transform the RGB image.

    The output pixel at offset ``d`` from ``(cx, cy)`` reads the flipped input at ``(cx, cy) + R(-a) d``
    (``augment.apply_geometry``). The valid mask and the ``maps`` are copied from the nearest pixel (round half
    to even, as ``grid_sample``); RGB is interpolated bilinearly with zero padding, mapped by
    ``clamp(colour @ rgb + offset, 0, 1)`` and set to 0 where the moved mask is False, as are the maps (to
    ``fills``).

    Args:
        rgb: ``uint8 [3, H, W]`` planar image.
        valid: ``bool [H, W]`` pixels that carry data.
        maps: ``float32 [D, H, W]`` maps copied, never blended (labels, depth); ``D`` may be 0.
        fills: ``float32 [D]`` value of each map outside the moved valid mask.
        flip: Mirror the input about the principal point's column (``u -> 2 cx - u``) before rotating.
        cos_a, sin_a: Cosine and sine of the rotation angle.
        cx, cy: Principal point.
        colour, offset: ``float32 [3, 3]`` and ``[3]``: the colour transform of 0-255 RGB values.
        rgb_out, valid_out, maps_out: Outputs, ``float32 [3, H, W]``, ``bool [H, W]``, ``float32 [D, H, W]``.
    """
    n_maps = maps.shape[0]
    h, w = valid.shape
    c00, c01, c02 = colour[0, 0], colour[0, 1], colour[0, 2]
    c10, c11, c12 = colour[1, 0], colour[1, 1], colour[1, 2]
    c20, c21, c22 = colour[2, 0], colour[2, 1], colour[2, 2]
    o0, o1, o2 = offset[0], offset[1], offset[2]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    for i in range(h):
        dy = i - cy
        u_row = cx + sin_a * dy
        v_row = cy + cos_a * dy
        for j in range(w):
            dx = j - cx
            us = u_row + cos_a * dx
            vs = v_row - sin_a * dx
            if flip:
                us = 2.0 * cx - us
            jn = int(np.rint(us))
            i_n = int(np.rint(vs))
            ok = False
            if jn >= 0 and jn < w and i_n >= 0 and i_n < h:
                ok = valid[i_n, jn]
            valid_out[i, j] = ok
            if not ok:
                for d in range(n_maps):
                    maps_out[d, i, j] = fills[d]
                rgb_out[0, i, j] = zero
                rgb_out[1, i, j] = zero
                rgb_out[2, i, j] = zero
                continue
            for d in range(n_maps):
                maps_out[d, i, j] = maps[d, i_n, jn]
            fxd = np.floor(us)
            fyd = np.floor(vs)
            x0 = int(fxd)
            y0 = int(fyd)
            fx = np.float32(us - fxd)
            fy = np.float32(vs - fyd)
            if x0 >= 0 and y0 >= 0 and x0 + 1 < w and y0 + 1 < h:  # all four taps on the image
                w00 = (one - fx) * (one - fy)
                w01 = fx * (one - fy)
                w10 = (one - fx) * fy
                w11 = fx * fy
                r = (
                    w00 * np.float32(rgb[0, y0, x0])
                    + w01 * np.float32(rgb[0, y0, x0 + 1])
                    + w10 * np.float32(rgb[0, y0 + 1, x0])
                    + w11 * np.float32(rgb[0, y0 + 1, x0 + 1])
                )
                g = (
                    w00 * np.float32(rgb[1, y0, x0])
                    + w01 * np.float32(rgb[1, y0, x0 + 1])
                    + w10 * np.float32(rgb[1, y0 + 1, x0])
                    + w11 * np.float32(rgb[1, y0 + 1, x0 + 1])
                )
                b = (
                    w00 * np.float32(rgb[2, y0, x0])
                    + w01 * np.float32(rgb[2, y0, x0 + 1])
                    + w10 * np.float32(rgb[2, y0 + 1, x0])
                    + w11 * np.float32(rgb[2, y0 + 1, x0 + 1])
                )
            else:  # border band: taps off the image read 0 (grid_sample's zero padding)
                r = zero
                g = zero
                b = zero
                for ty in range(2):
                    y = y0 + ty
                    if y < 0 or y >= h:
                        continue
                    wy = fy if ty else one - fy
                    for tx in range(2):
                        x = x0 + tx
                        if x < 0 or x >= w:
                            continue
                        wt = wy * (fx if tx else one - fx)
                        r += wt * np.float32(rgb[0, y, x])
                        g += wt * np.float32(rgb[1, y, x])
                        b += wt * np.float32(rgb[2, y, x])
            rgb_out[0, i, j] = min(max(c00 * r + c01 * g + c02 * b + o0, zero), one)
            rgb_out[1, i, j] = min(max(c10 * r + c11 * g + c12 * b + o1, zero), one)
            rgb_out[2, i, j] = min(max(c20 * r + c21 * g + c22 * b + o2, zero), one)
