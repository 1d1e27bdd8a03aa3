"""Hidden Point Removal (Katz, Tal, Basri 2007, "Direct visibility of point sets") on the in-image points.

The points are flipped about a sphere centred on the camera, ``p -> p + 2 (R - |p|) p / |p|``, and a point is
visible iff its image is a vertex of the convex hull of the flipped points and the camera centre
(``scipy.spatial.ConvexHull``); docs/design.md, "LiDAR and occlusion", gives the default radius and its source.
"""

from __future__ import annotations

import numpy as np

from airfisheye_bench.geometry.occlusion.projection import Projection


def hpr_mask(points: np.ndarray, T: np.ndarray, proj: Projection, radius: float) -> np.ndarray:
    """Hidden Point Removal (Katz, Tal, Basri 2007) on the points that project into the image."""
    from scipy.spatial import ConvexHull, QhullError  # imported here: only this method needs scipy

    ids = np.flatnonzero(proj.valid & (proj.range > 0))
    mask = np.zeros(len(points), dtype=bool)
    if len(ids) < 4:  # no 3-D hull: nothing can hide anything
        mask[ids] = True
        return mask
    p = np.take(points, ids, axis=0) - (-T[:3, :3].T @ T[:3, 3])  # relative to the camera centre
    norm = proj.range[ids, None]
    # Spherical flipping about a sphere of radius R around the viewpoint: p -> p + 2 (R - |p|) p / |p|.
    flipped = p * ((2.0 * radius * norm.max()) / norm - 1.0)
    try:
        hull = ConvexHull(np.concatenate([flipped, np.zeros((1, 3))]))
    except QhullError:  # degenerate (coplanar) input: no point is behind another
        mask[ids] = True
        return mask
    vertices = hull.vertices[hull.vertices < len(ids)]
    mask[ids[vertices]] = True
    return mask


__all__ = ["hpr_mask"]
