"""Perspective views of a fisheye (``geometry/perspective_views.py``): fields defined on the sphere, rendered into the
views and back, reproduce themselves; z along a view's axis becomes range exactly; the cube views agree with the
cube-map remap; sparse points are moved, never interpolated."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.cameras import ideal_camera
from airfisheye_bench.geometry.cubemap import CubemapToFisheye
from airfisheye_bench.geometry.perspective_views import PerspectiveViews, cube_views, parse_views

FISHEYE = ideal_camera(96, 96, 190.0)
CUBE = ideal_camera(48, 48, 90.0, "pinhole")


def range_field(d: torch.Tensor) -> torch.Tensor:
    """A smooth range (metres) over unit directions ``[..., 3]``."""
    return 20.0 + 6.0 * d[..., 0] - 4.0 * d[..., 1] + 3.0 * d[..., 2] * d[..., 0]


def label_field(d: torch.Tensor) -> torch.Tensor:
    """Piecewise-constant labels over directions: four sectors about the optical axis, and a cap around it."""
    sector = (d[..., 0] > 0.1).long() + 2 * (d[..., 1] > -0.2).long()
    return torch.where(d[..., 2] > math.cos(math.radians(25.0)), 4, sector)


def view_rays(views: PerspectiveViews) -> torch.Tensor:
    """``[K, h, w, 3]`` unit rays through every view pixel centre, in the fisheye frame."""
    rays = views.camera.ray_grid(torch.float64)
    return torch.stack([rays @ torch.from_numpy(v.rotation).T for v in views.views])


def render_views(views: PerspectiveViews, field, depth: str | None = None) -> torch.Tensor:
    """A field rendered into the views ``[K, 1, h, w]`` at their pixel centres (``depth="z"``: range * d_v.z)."""
    rays = view_rays(views)
    value = field(rays)
    if depth == "z":
        value = value * views.camera.ray_grid(torch.float64)[..., 2]
    return value[:, None].float() if value.is_floating_point() else value[:, None]


def fisheye_truth(field) -> tuple[torch.Tensor, torch.Tensor]:
    rays = FISHEYE.ray_grid(torch.float64).nan_to_num(0.0)
    return field(rays), FISHEYE.valid_mask()


def seam_distance_px(views: PerspectiveViews) -> torch.Tensor:
    """``[H, W]``: how far (view pixels) each fisheye pixel's ray lies inside the frame of the view it is deepest in."""
    rays = FISHEYE.ray_grid(torch.float64).nan_to_num(0.0).reshape(-1, 3)
    best = torch.full((len(rays),), -1.0, dtype=torch.float64)
    w, h = views.camera.width, views.camera.height
    for view in views.views:
        uv, ok = views.camera.project(rays @ torch.from_numpy(view.rotation))
        u, v = uv[:, 0], uv[:, 1]
        edge = torch.minimum(torch.minimum(u + 0.5, w - 0.5 - u), torch.minimum(v + 0.5, h - 0.5 - v))
        best = torch.maximum(best, torch.where(ok, edge, -1.0))
    return best.view(FISHEYE.height, FISHEYE.width)


# ---------------------------------------------------------------------------------------------- view sets
def test_cube_views_are_the_cube_faces_the_fisheye_sees() -> None:
    views = PerspectiveViews(FISHEYE, CUBE)
    assert views.names == ("front", "left", "right", "up", "down")
    assert views.coverage_fraction == 1.0 and torch.equal(views.coverage, FISHEYE.valid_mask())
    narrow = PerspectiveViews(ideal_camera(64, 64, 80.0), CUBE)  # within the front face
    assert narrow.names == ("front",) and narrow.coverage_fraction == 1.0
    record = views.describe()
    assert record["view_camera"]["model"] == "pinhole" and [v["name"] for v in record["views"]] == list(
        views.names
    )


def test_a_tiling_names_its_views_and_reports_what_it_leaves_uncovered() -> None:
    views = parse_views([[0, 0], [60, 0], [-60, 0]])
    assert [v.name for v in views] == ["yaw0_pitch0", "yaw60_pitch0", "yaw-60_pitch0"]
    np.testing.assert_allclose(views[1].rotation @ [0.0, 0.0, 1.0], [-math.sqrt(3) / 2, 0.0, 0.5], atol=1e-12)
    tiles = PerspectiveViews(FISHEYE, ideal_camera(48, 48, 100.0, "pinhole"), views)
    assert 0.4 < tiles.coverage_fraction < 1.0  # above and below the horizon's band, nothing sees the fisheye
    for bad in ("tiles", [], [[0]], [[0, "up"]], [[0, 0, 0, 0]], [[True, 0]]):
        with pytest.raises(ValueError, match="expected cube, or a list of views"):
            parse_views(bad)
    with pytest.raises(ValueError, match="no view sees"):
        PerspectiveViews(ideal_camera(64, 64, 60.0), CUBE, parse_views([[180, 0]]))


# ---------------------------------------------------------------------------------------------- depth
def away_from_seams(views: PerspectiveViews) -> torch.Tensor:
    """``[H, W]``: valid fisheye pixels a view pixel or more inside some view's frame, and off the image circle's
    rim (where view pixels that saw nothing of the fisheye are left out of the taps)."""
    rim = FISHEYE.theta_grid() > math.radians(92.0)
    return FISHEYE.valid_mask() & ~rim & (seam_distance_px(views) >= 1.0)


@pytest.mark.parametrize("depth", ["range", "z"])
def test_a_depth_field_rendered_to_the_views_comes_back_as_range(depth: str) -> None:
    """Range over the sphere, rendered into the cube views as range or as z along each view's axis, back in the
    fisheye is the range field: to bilinear interpolation's error away from the seams, to the seams' (a tap off a
    face is its neighbour's nearest texel, as in the cube-map remap) on them."""
    views = PerspectiveViews(FISHEYE, CUBE)
    back = views.from_views(render_views(views, range_field, depth), depth=depth)[0]
    truth, valid = fisheye_truth(range_field)
    assert torch.equal(back != 0, valid)
    rel = (back - truth).abs() / truth
    away = away_from_seams(views)
    assert away.sum() > 0.8 * valid.sum()
    assert rel[away].max() < 1e-3 and rel[valid].median() < 3e-4 and rel[valid].max() < 1.5e-2


def test_overlapping_views_blend_into_the_same_field() -> None:
    """Five 110 deg views overlapping by 20 deg: the feathered blend of their z outputs is the range field."""
    views = PerspectiveViews(FISHEYE, ideal_camera(48, 48, 110.0, "pinhole"), cube_views())
    back = views.from_views(render_views(views, range_field, "z"), depth="z")[0]
    truth, valid = fisheye_truth(range_field)
    rel = (back - truth).abs() / truth
    inner = valid & (FISHEYE.theta_grid() < math.radians(92.0))
    assert views.coverage_fraction == 1.0 and rel[inner].max() < 2e-3 and rel[valid].max() < 1.5e-2


@pytest.mark.parametrize("mode", ["bilinear", "nearest"])
def test_z_becomes_range_exactly(mode: str) -> None:
    """A fisheye whose pixels are the front view's own (a pinhole of the same intrinsics): each pixel is a view
    pixel centre, so range = z / d_v.z is exact to float32, and splatting range as z and back is the identity."""
    fisheye = ideal_camera(48, 48, 90.0, "pinhole")
    views = PerspectiveViews(fisheye, CUBE, parse_views([[0, 0]]))
    z = render_views(views, range_field, "z")
    back = views.from_views(z, mode=mode, depth="z")[0]
    truth = range_field(fisheye.ray_grid(torch.float64)).float()
    torch.testing.assert_close(back, truth, rtol=2e-7, atol=0)
    sparse = torch.zeros(1, 1, 48, 48)
    sparse[0, 0, ::7, ::5] = truth[::7, ::5]
    splat = views.splat_to_views(sparse, depth="z")
    torch.testing.assert_close(views.from_views(splat, mode="nearest", depth="z"), sparse, rtol=2e-7, atol=0)


def test_sparse_points_are_moved_not_interpolated() -> None:
    """Each LiDAR pixel lands on the nearest pixel of every view that sees it, with its own value (z: times d_v.z);
    two on one view pixel keep the nearer; nothing else is filled."""
    views = PerspectiveViews(FISHEYE, CUBE)
    truth, valid = fisheye_truth(range_field)
    sparse = torch.zeros(FISHEYE.height, FISHEYE.width)
    pick = valid & (torch.rand(valid.shape, generator=torch.Generator().manual_seed(0)) < 0.05)
    sparse[pick] = truth[pick].float()
    out = views.splat_to_views(sparse[None, None])[0]
    assert out.shape == (5, 1, 48, 48)
    filled = out[out > 0]
    assert set(filled.tolist()) <= set(sparse[pick].tolist())  # values copied, none made up
    assert 0.9 * int(pick.sum()) <= len(filled) <= 2 * int(pick.sum())  # seams: a point on two faces
    z = views.splat_to_views(sparse[None, None], depth="z")[0]
    dz = views.camera.ray_grid(torch.float64)[..., 2].float()
    # each point's own direction makes it z: within a view pixel of the pixel centre's
    torch.testing.assert_close(z, out * dz, rtol=0.02, atol=0)
    # A 96^2 pinhole seen by the 48^2 front view: fisheye columns 10 and 11 land on view column 5.
    fine = PerspectiveViews(ideal_camera(96, 96, 90.0, "pinhole"), CUBE, parse_views([[0, 0]]))
    two = torch.zeros(1, 1, 96, 96)
    two[0, 0, 10, 10], two[0, 0, 10, 11] = 9.0, 7.0
    landed = fine.splat_to_views(two)[0, 0, 0]
    assert landed[5, 5] == 7.0 and int((landed > 0).sum()) == 1


# ---------------------------------------------------------------------------------------------- labels, images
def test_labels_come_back_away_from_their_boundaries() -> None:
    """Labels rendered into the views and back by the nearest texel of the most central view are the field's,
    wherever no boundary passes within a view pixel of the ray."""
    views = PerspectiveViews(FISHEYE, CUBE)
    back = views.from_views(render_views(views, label_field).to(torch.uint8), mode="nearest", fill=255)[0]
    truth, valid = fisheye_truth(label_field)
    assert back.dtype == torch.uint8 and (back[~valid] == 255).all()
    wrong = (back.long() != truth) & valid
    # a pixel whose 3x3 fisheye neighbourhood holds one label is at least a fisheye pixel (> a view pixel here)
    # from a boundary
    t = torch.nn.functional.pad(truth[None, None].float(), (1, 1, 1, 1), mode="replicate")
    uniform = (torch.nn.functional.max_pool2d(t, 3, 1) == -torch.nn.functional.max_pool2d(-t, 3, 1))[0, 0]
    assert not (wrong & uniform).any() and wrong.float().sum() < 0.02 * valid.sum()


def test_an_image_to_the_views_and_back_is_itself() -> None:
    """A smooth image on the fisheye, rendered into the views (bilinear) and back (feathered blend), is itself
    except near the rim of the image circle, where the bilinear taps leave the valid region."""
    views = PerspectiveViews(FISHEYE, CUBE)
    rays = FISHEYE.ray_grid(torch.float64).nan_to_num(0.0)
    image = torch.stack([range_field(rays) / 30.0, rays[..., 0], rays[..., 1] ** 2]).float()
    tiles = views.to_views(image)
    assert tiles.shape == (5, 3, 48, 48) and views.view_valid.shape == (5, 48, 48)
    assert (tiles[~views.view_valid[:, None].expand_as(tiles)] == 0).all()
    back = views.from_views(tiles)
    theta = FISHEYE.theta_grid()
    inner = FISHEYE.valid_mask() & (theta < math.radians(90.0))
    assert (back - image).abs().amax(0)[inner].max() < 0.02
    uint8 = views.to_views((image * 100).clamp(0, 255).to(torch.uint8)[None])
    assert uint8.dtype == torch.uint8 and uint8.shape == (1, 5, 3, 48, 48)


def test_the_cube_views_agree_with_the_cube_map_remap() -> None:
    """At 90 deg the views are the cube's faces: faces back to the fisheye match ``CubemapToFisheye`` (nearest: the
    same texel except on a seam's half-pixel ties; bilinear: to interpolation across the seams), and the fisheye
    into the views gives back the faces where the fisheye is finer."""
    views = PerspectiveViews(FISHEYE, CUBE)
    faces = render_views(views, range_field)  # [5, 1, 48, 48], the cube's faces
    cube = CubemapToFisheye(FISHEYE, face_size=48)
    nearest = views.from_views(faces, mode="nearest")
    assert (nearest == cube.remap(faces, mode="nearest")).float().mean() > 0.99
    bilinear = views.from_views(faces)[0]
    rel = (bilinear - cube.remap(faces)[0]).abs() / range_field(FISHEYE.ray_grid(torch.float64)).float()
    assert rel[away_from_seams(views)].max() < 1e-6 and rel[FISHEYE.valid_mask()].max() < 1.5e-2
    fine = ideal_camera(192, 192, 190.0)
    again = PerspectiveViews(fine, CUBE).to_views(CubemapToFisheye(fine, face_size=48).remap(faces))
    seen = PerspectiveViews(fine, CUBE).view_valid[:, None]
    assert ((again - faces).abs() / faces)[seen].median() < 1e-3


def test_bad_shapes_are_named() -> None:
    views = PerspectiveViews(FISHEYE, CUBE)
    with pytest.raises(ValueError, match="the camera 96x96"):
        views.to_views(torch.zeros(3, 64, 64))
    with pytest.raises(ValueError, match=r"views must be \[K, C, h, w\].*front, left, right, up, down"):
        views.from_views(torch.zeros(4, 1, 48, 48))
    with pytest.raises(ValueError, match="depth must be"):
        views.from_views(torch.zeros(5, 1, 48, 48), depth="disparity")
    with pytest.raises(ValueError, match="camera must be a CameraModel"):
        PerspectiveViews(FISHEYE, "pinhole")  # type: ignore[arg-type]
