"""LiDAR-to-fisheye projection and occlusion handling (paper, III-C), checked against analytic visibility."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry import CAM_FROM_FLU, euler_to_matrix, ideal_camera, make_transform
from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.lidar_layout import layout_from_angles
from airfisheye_bench.geometry.occlusion import (
    lidar_depth_map,
    occlusion_mask,
    ordering_mask,
    ordering_reference,
    project_lidar,
)
from airfisheye_bench.geometry.occlusion.ordering import layout_numba
from tests.helpers.occlusion_scenes import cast_scan, ray_box_entry, rig, seen_from

SPEC = LidarSpec(channels=32, points_per_channel=512)  # 270 x (-45..15) deg, a quarter of the paper's density
CAMERA = ideal_camera(512, 512, fov_deg=190.0)
# LiDAR frame (x forward, y left, z up): a wall 20 m ahead, a box 8-10 m ahead, the ground 5 m below.
BOX_AND_WALL = np.array(
    [
        [(20.0, -30.0, -10.0), (21.0, 30.0, 20.0)],
        [(8.0, -2.0, -3.0), (10.0, 2.0, 1.0)],
        [(-50.0, -50.0, -6.0), (50.0, 50.0, -5.0)],
    ]
)


def scene_truth(offset, pitch_deg=0.0, boxes=BOX_AND_WALL, spec=SPEC, camera=CAMERA):
    points = cast_scan(spec, boxes)
    centre, T = rig(offset, pitch_deg)
    projects = occlusion_mask(points, T, camera, spec, "none")
    return points, T, projects & seen_from(points, centre, boxes), projects


def structured_scene(seed: int) -> np.ndarray:
    """Ground, buildings, poles and a few near floating obstacles (the LiDAR 6 m above the ground)."""
    rng = np.random.default_rng(seed)
    boxes = [((-150.0, -150.0, -7.0), (150.0, 150.0, -6.0))]
    for _ in range(12):
        cx, cy = rng.uniform(12, 50), rng.uniform(-40, 40)
        sx, sy, h = rng.uniform(3, 12), rng.uniform(3, 12), rng.uniform(3, 25)
        boxes.append(((cx, cy, -6.0), (cx + sx, cy + sy, -6.0 + h)))
    for _ in range(15):
        cx, cy, w = rng.uniform(3, 25), rng.uniform(-15, 15), rng.uniform(0.2, 0.6)
        boxes.append(((cx, cy, -6.0), (cx + w, cy + w, -6.0 + rng.uniform(4, 12))))
    for _ in range(4):
        x, y, z = rng.uniform(2, 6), rng.uniform(-4, 4), rng.uniform(-3, 0)
        boxes.append(
            ((x, y, z), (x + rng.uniform(0.2, 1.0), y + rng.uniform(0.2, 2.0), z + rng.uniform(0.3, 1.5)))
        )
    return np.asarray(boxes)


# -------------------- box in front of a wall
@pytest.mark.parametrize("side", [0.5, -0.5])
def test_box_hides_wall_from_a_sideways_camera(side: float) -> None:
    points, T, visible, projects = scene_truth((0.0, side, 0.0))
    hidden = projects & ~visible
    behind_box = points[:, 0] > 10.0
    # wall and ground beside the box, seen only by the LiDAR
    assert hidden.sum() >= 30 and behind_box[hidden].all()
    mask = occlusion_mask(points, T, CAMERA, SPEC, "ordering")
    assert (mask & hidden).sum() <= 0.05 * hidden.sum()  # hidden wall points removed
    assert mask[visible].all()  # every visible point kept: the box, the rest of the wall, the ground
    # the strip is on the side the camera moved away from: the box shifts towards it in the camera's view
    assert np.all(np.sign(points[hidden, 1]) == -np.sign(side))


@pytest.mark.parametrize(("offset", "pitch"), [((0.0, 0.0, -0.5), 30.0), ((0.1, 0.3, -0.4), 20.0)])
def test_box_and_wall_precision_recall(offset, pitch) -> None:
    points, T, visible, projects = scene_truth(offset, pitch)
    hidden = projects & ~visible
    assert hidden.sum() >= 50
    kept_hidden, recall = {}, {}
    for method in ("none", "ordering", "zbuffer"):
        mask = occlusion_mask(points, T, CAMERA, SPEC, method)
        assert not (mask & ~projects).any()
        kept_hidden[method] = int((mask & hidden).sum())
        recall[method] = (mask & visible).sum() / visible.sum()
    assert kept_hidden["none"] == hidden.sum() and recall["none"] == 1.0
    assert kept_hidden["ordering"] <= 0.75 * kept_hidden["none"] and recall["ordering"] >= 0.999
    assert kept_hidden["zbuffer"] <= 0.35 * kept_hidden["none"] and recall["zbuffer"] >= 0.99


def test_structured_scene_precision_recall() -> None:
    boxes = structured_scene(3)
    points, T, visible, projects = scene_truth((0.1, 0.3, -0.4), 20.0, boxes=boxes)
    hidden = projects & ~visible
    assert hidden.sum() >= 200
    stats = {}
    for method in ("none", "ordering", "zbuffer"):
        mask = occlusion_mask(points, T, CAMERA, SPEC, method)
        stats[method] = ((mask & visible).sum() / mask.sum(), (mask & visible).sum() / visible.sum())
    precision = {m: s[0] for m, s in stats.items()}
    # ordering removes most of the hidden points ("none" keeps them all) at a recall above 99%
    assert 1 - precision["ordering"] <= 0.5 * (1 - precision["none"])
    assert stats["ordering"][1] >= 0.99 and stats["none"][1] == 1.0


def test_a_pure_rotation_hides_nothing() -> None:
    """The paper's second observation: with the camera at the LiDAR centre no point can be occluded."""
    rng = np.random.default_rng(0)
    dirs = SPEC.beam_directions(torch.float64).reshape(-1, 3).numpy()
    points = dirs * rng.uniform(0.5, 80.0, len(dirs))[:, None]  # random ranges: any flip would show
    R_cam_lidar = (euler_to_matrix(0.2, 0.4, -0.3) @ CAM_FROM_FLU.T).T  # rolled, pitched and yawed
    T = make_transform(R_cam_lidar, np.zeros(3))
    projects = occlusion_mask(points, T, CAMERA, SPEC, "none")
    assert projects.sum() > 1000
    np.testing.assert_array_equal(occlusion_mask(points, T, CAMERA, SPEC, "ordering"), projects)


def test_order_flip_in_a_row_removes_the_farther_point() -> None:
    """Hand-computed: camera 1 m to the LiDAR's left. A near point straight ahead appears at -26.6 deg azimuth
    from the camera, right of a far point that the LiDAR sees at -10 deg (-12.8 deg from the camera): the row
    order flips and the farther point goes, whatever order the points are listed in."""
    spec = LidarSpec(channels=2, points_per_channel=27, hfov_deg=270.0, vfov_deg=(0.0, 10.0))
    near = np.array([2.0, 0.0, 0.0])  # azimuth 0: column 13
    a = math.radians(-10.0)
    far = 20.0 * np.array([math.cos(a), math.sin(a), 0.0])  # column 12
    a = math.radians(-40.0)
    aside = 20.0 * np.array([math.cos(a), math.sin(a), 0.0])  # column 9: -42.1 deg from the camera, in order
    _, T = rig((0.0, 1.0, 0.0))
    for points, expected in (
        (np.array([near, far, aside]), [True, False, True]),
        (np.array([aside, far, near]), [True, False, True]),
    ):
        for method_mask in (
            occlusion_mask(points, T, CAMERA, spec, "ordering"),
            ordering_reference(points, T, CAMERA, spec),
        ):
            np.testing.assert_array_equal(method_mask, expected)


def test_order_flip_in_a_column() -> None:
    """Camera 1 m below the LiDAR: a near point 2 m ahead at channel 0 (elevation 0) appears 26.6 deg up,
    above a far point of channel 1 (10 deg up, 12.8 deg from the camera): the column order flips."""
    spec = LidarSpec(channels=2, points_per_channel=27, hfov_deg=270.0, vfov_deg=(0.0, 10.0))
    a = math.radians(10.0)
    points = np.array([[20.0 * math.cos(a), 0.0, 20.0 * math.sin(a)], [2.0, 0.0, 0.0]])
    _, T = rig((0.0, 0.0, -1.0))
    np.testing.assert_array_equal(occlusion_mask(points, T, CAMERA, spec, "ordering"), [False, True])
    # a tolerance of 2 vertical resolutions (20 deg) accepts the 13.8 deg flip
    assert occlusion_mask(points, T, CAMERA, spec, "ordering", elevation_tolerance=2.0).all()


# -------------------- reference == fast
def random_scan(spec: LidarSpec, rng: np.random.Generator, collisions: bool) -> np.ndarray:
    dirs = spec.beam_directions(torch.float64).reshape(-1, 3).numpy()
    points = dirs * rng.uniform(0.5, 30.0, len(dirs))[:, None]
    points = points[rng.random(len(points)) < 0.8]  # dropped returns
    if collisions:  # extra points near occupied cells, some winning their cell
        extra = points[: len(points) // 4] * 1.3 + rng.normal(0.0, 0.01, (len(points) // 4, 3))
        points = np.concatenate([points, extra])
    return points


def with_strays(points: np.ndarray, spec: LidarSpec, rng: np.random.Generator) -> np.ndarray:
    """Add points no ordering test may keep: outside the sensor's vertical FOV and at the LiDAR origin."""
    n = max(len(points) // 20, 4)
    az = rng.uniform(-math.pi, math.pi, n)
    el = np.radians(rng.choice([spec.vfov_deg[0] - 10.0, spec.vfov_deg[1] + 10.0], n))
    r = rng.uniform(1.0, 20.0, n)
    outside = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1) * r[:, None]
    strays = np.concatenate([outside, np.zeros((2, 3))])
    return rng.permutation(np.concatenate([points, strays]))


OPTION_SETS = [
    {},
    {"azimuth_window": 3, "elevation_window": 2},
    {"elevation_tolerance": 1.0},
    {"elevation_tolerance": -0.25},
    {"azimuth_window": 0, "elevation_window": 0, "elevation_tolerance": 0.5},
]
# The compiled kernels (what ``method="ordering"`` runs) and the vectorised numpy solver (the previous one).
FAST = ("numba", "vectorised")


def assert_fast_equals_reference(points, T, camera, spec, options) -> np.ndarray:
    expected = ordering_reference(points, T, camera, spec, **options)
    np.testing.assert_array_equal(occlusion_mask(points, T, camera, spec, "ordering", **options), expected)
    for implementation in FAST:
        np.testing.assert_array_equal(
            ordering_mask(points, T, camera, spec, implementation, **options),
            expected,
            err_msg=implementation,
        )
    return expected


@pytest.mark.parametrize("seed", range(6))
def test_fast_equals_reference_on_random_scans(seed: int) -> None:
    rng = np.random.default_rng(seed)
    spec = LidarSpec(
        channels=int(rng.integers(2, 16)),
        points_per_channel=int(rng.integers(8, 128)),
        hfov_deg=float(rng.choice([120.0, 270.0, 360.0])),
        vfov_deg=(-30.0, 20.0),
    )
    camera = ideal_camera(96, 96, fov_deg=float(rng.choice([150.0, 190.0, 240.0])))
    points = with_strays(random_scan(spec, rng, collisions=seed % 2 == 0), spec, rng)
    _, T = rig(rng.normal(0.0, 0.5, 3), float(rng.uniform(-30.0, 30.0)))
    for options in OPTION_SETS:
        assert_fast_equals_reference(points, T, camera, spec, options)
    literal = occlusion_mask(points, T, camera, spec, "ordering")
    assert 0 < literal.sum() < 0.9 * occlusion_mask(points, T, camera, spec, "none").sum()  # non-trivial


@pytest.mark.parametrize("hfov", [270.0, 360.0])
def test_fast_equals_reference_across_bitset_words(hfov: float) -> None:
    """Lines longer than one 64-bit word (200 columns, 70 channels), windows that cross word boundaries."""
    rng = np.random.default_rng(7)
    spec = LidarSpec(channels=70, points_per_channel=200, hfov_deg=hfov, vfov_deg=(-40.0, 25.0))
    points = with_strays(random_scan(spec, rng, collisions=True), spec, rng)
    _, T = rig((0.2, -0.4, 0.3), 10.0)
    for options in (OPTION_SETS[0], {"azimuth_window": 70, "elevation_window": 66}, OPTION_SETS[2]):
        expected = assert_fast_equals_reference(points, T, CAMERA, spec, options)
        assert 0 < expected.sum() < len(points)


@pytest.mark.parametrize(("offset", "pitch"), [((0.0, 0.5, 0.0), 0.0), ((0.1, 0.3, -0.4), 20.0)])
def test_fast_equals_reference_on_structured_scans(offset, pitch) -> None:
    spec = LidarSpec(channels=24, points_per_channel=256)
    points = cast_scan(spec, structured_scene(1))
    rng = np.random.default_rng(2)
    _, T = rig(offset, pitch)
    for scan in (points, points[rng.random(len(points)) < 0.7]):  # full, then with dropped returns
        for options in [*OPTION_SETS[:3], OPTION_SETS[3]]:
            assert_fast_equals_reference(scan, T, CAMERA, spec, options)


def test_numba_equals_vectorised_on_a_paper_size_scan() -> None:
    """The full 64 x 2048 scan (32-word rows); a narrow image, so that most points fall outside it.

    The two fast implementations are compared here (the Python reference takes seconds at this size); each
    equals the reference on the smaller scans above.
    """
    spec = LidarSpec()
    points = cast_scan(spec, structured_scene(4))
    points = points[np.random.default_rng(3).random(len(points)) < 0.9]  # dropped returns
    _, T = rig((0.1, 0.3, -0.4), 20.0)
    camera = ideal_camera(256, 256, fov_deg=100.0)
    for options in (OPTION_SETS[2], OPTION_SETS[3], OPTION_SETS[0]):  # the literal reading last
        expected = ordering_mask(points, T, camera, spec, "vectorised", **options)
        np.testing.assert_array_equal(
            occlusion_mask(points, T, camera, spec, "ordering", **options), expected
        )
    projects = occlusion_mask(points, T, camera, spec, "none")
    assert 0 < expected.sum() < projects.sum() < 0.6 * len(points)


@pytest.mark.parametrize("hfov", [90.0, 270.0, 360.0])
def test_numba_layout_equals_numpy_layout(hfov: float) -> None:
    """Step 1 (ring, place along the ring, sector) of the compiled path is bit-identical to the numpy one."""
    rng = np.random.default_rng(int(hfov))
    spec = LidarSpec(channels=16, points_per_channel=100, hfov_deg=hfov, vfov_deg=(-20.0, 10.0))
    beams = spec.beam_directions(torch.float64).reshape(-1, 3).numpy()
    beams = beams[rng.random(len(beams)) < 0.9]  # dropped returns
    jitter = rng.normal(0.0, 0.004, beams.shape)  # ~ a cell size: shared sectors, points outside the FOV
    points = np.concatenate([beams + jitter, beams[:50], beams[:50] * 2.0, np.zeros((3, 3))])  # ties, origin
    r, az, el = spherical_coordinates(points * rng.uniform(1.0, 50.0, (len(points), 1)))
    # angles exactly half a channel off the beams (rounding ties), at +-180 deg and at the sector edges
    half_v = spec.vertical_resolution / 2
    el = np.concatenate([el, spec.channel_elevations()[[0, -1]] + [-half_v, half_v], [0.0, 0.0]])
    az = np.concatenate(
        [az, spec.column_azimuths()[[0, -1]] - spec.horizontal_resolution / 2, [-np.pi, np.pi]]
    )
    r = np.concatenate([r, [5.0, 5.0, 5.0, 5.0]])
    expected = layout_from_angles(r, az, el, spec)
    layout = layout_numba(r, az, el, spec)
    for got, want in zip(layout, expected, strict=True):
        np.testing.assert_array_equal(got, want)
    ring, _, column = layout
    assert (ring == -1).sum() >= 3 and (column < 0).any() == (hfov < 360.0)
    assert (np.unique(ring * 10**6 + column, return_counts=True)[1] > 1).any()  # shared sectors


def test_unknown_implementation_raises() -> None:
    with pytest.raises(ValueError, match="implementation"):
        ordering_mask(np.ones((1, 3)), np.eye(4), CAMERA, SPEC, "gpu")


def test_result_does_not_depend_on_the_order_of_the_points() -> None:
    spec = LidarSpec(channels=8, points_per_channel=64)
    points = cast_scan(spec, BOX_AND_WALL)
    _, T = rig((0.0, 0.0, -0.4), 10.0)  # on the scene's mirror plane: many (near-)equal camera ranges
    mask = occlusion_mask(points, T, CAMERA, spec, "ordering")
    assert 0 < mask.sum() < len(points)
    perm = np.random.default_rng(0).permutation(len(points))
    np.testing.assert_array_equal(occlusion_mask(points[perm], T, CAMERA, spec, "ordering"), mask[perm])
    np.testing.assert_array_equal(ordering_reference(points, T, CAMERA, spec), mask)


# -------------------- z-buffer
def points_on_rays(pixels: list[tuple[float, float]], ranges: list[float], camera=CAMERA) -> np.ndarray:
    """LiDAR-frame points (camera at the LiDAR, looking along x) that project to the given (u, v) pixels."""
    rays = camera.unproject(np.asarray(pixels, dtype=np.float64)) * np.asarray(ranges)[:, None]
    return rays @ CAM_FROM_FLU  # camera frame -> LiDAR frame (CAM_FROM_FLU is R_cam_lidar here)


def test_zbuffer_known_answers() -> None:
    T = make_transform(CAM_FROM_FLU, np.zeros(3))
    pts = points_on_rays(
        [(200, 200), (200, 200), (202, 201), (204, 200), (200, 300), (201, 300), (300, 100), (301, 100)],
        [5.0, 10.0, 10.0, 10.0, 8.0, 8.9, 10.0, 10.5],
    )
    fixed = {"kernel": 5, "threshold": 1.0, "relative": False}
    mask = occlusion_mask(pts, T, CAMERA, None, "zbuffer", **fixed)  # kernel 5 (radius 2 px), 1 m
    # same pixel and 2 px away: hidden; 4 px away: outside the kernel; within 1 m: same surface
    np.testing.assert_array_equal(mask, [True, False, False, True, True, True, True, True])
    mask = occlusion_mask(pts, T, CAMERA, None, "zbuffer", kernel=9, threshold=0.2, relative=False)
    np.testing.assert_array_equal(mask, [True, False, False, False, True, False, True, False])
    # relative: 10% of the local minimum
    mask = occlusion_mask(pts, T, CAMERA, None, "zbuffer", kernel=5, threshold=0.1, relative=True)
    np.testing.assert_array_equal(mask, [True, False, False, True, True, False, True, True])


def test_zbuffer_derived_window_and_margin() -> None:
    """Defaults: window radius = half the LiDAR's vertical spacing in pixels at the point's pixel, relative
    margin = tan(87 deg) x the window's half-angle. Hand-computed for a 512^2 190 deg equidistant camera
    (focal 154.4 px/rad on the axis) and a 2 deg vertical spacing: radius rint(2.69) = 3 px, margin 43 %."""
    spec = LidarSpec(channels=2, points_per_channel=2048, vfov_deg=(0.0, 2.0))  # columns 0.13 deg apart
    T = make_transform(CAM_FROM_FLU, np.zeros(3))
    c = CAMERA.width // 2  # whole pixels: no rounding ties
    pixels = [(c, c), (c + 3, c), (c, c - 4), (c - 3, c + 3), (c - 2, c - 1)]
    pts = points_on_rays(pixels, [5.0, 10.0, 10.0, 6.0, 8.0])
    mask = occlusion_mask(pts, T, CAMERA, spec, "zbuffer")
    # 3 px away and twice as far: hidden; 4 px away: outside the first point's window (but 10 m is within 43 %
    # of the 8 m point's range); 6 m is within 43 % of 5 m, 8 m is not
    np.testing.assert_array_equal(mask, [True, False, True, True, False])
    scale = CAMERA.focal  # px/rad on the axis
    assert round(0.5 * math.radians(2.0) * scale) == 3
    assert 6.0 < 5.0 * (1 + math.tan(math.radians(87.0)) * 3.5 / scale) < 8.0
    # a gentler surface limit (45 deg: margin 2.3 %) keeps only the nearest point
    mask = occlusion_mask(pts, T, CAMERA, spec, "zbuffer", max_incidence_deg=45.0)
    np.testing.assert_array_equal(mask, [True, False, False, False, False])


# -------------------- depth map
def test_depth_map_nearest_wins_and_is_camera_range() -> None:
    rng = np.random.default_rng(0)
    pixel = (100.0, 400.0)
    ranges = rng.permutation(np.array([7.0, 3.5, 9.0, 12.0, 4.25, 3.75]))
    _, T = rig((0.3, -0.2, 0.1))
    # points on one camera ray, expressed in the LiDAR frame (the camera is offset from the LiDAR)
    p_cam = points_on_rays([pixel] * len(ranges), list(ranges)) @ CAM_FROM_FLU.T
    points = (p_cam @ T[:3, :3]) - T[:3, :3].T @ T[:3, 3]
    for order in (np.arange(len(points)), np.arange(len(points))[::-1]):
        depth = lidar_depth_map(points[order], T, CAMERA, method="none")
        assert depth.dtype == np.float32 and depth.shape == (512, 512)
        assert depth[400, 100] == np.float32(3.5)  # range from the camera centre, nearest of the six
        assert (depth > 0).sum() == 1
    assert lidar_depth_map(points, T, CAMERA, method="none", max_depth=3.0).max() == 0.0


def test_depth_map_is_min_reduction_over_many_collisions() -> None:
    rng = np.random.default_rng(1)
    n = 5000
    pix = rng.integers(200, 216, (n, 2)).astype(np.float64)  # 256 pixels, ~20 points each
    ranges = rng.uniform(1.0, 100.0, n)
    T = make_transform(CAM_FROM_FLU, np.zeros(3))
    depth = lidar_depth_map(points_on_rays(list(map(tuple, pix)), list(ranges)), T, CAMERA, method="none")
    expected = np.zeros((512, 512), dtype=np.float32)
    for (u, v), r in zip(pix.astype(int), ranges.astype(np.float32), strict=True):
        expected[v, u] = r if expected[v, u] == 0 else min(expected[v, u], r)
    np.testing.assert_allclose(depth, expected, rtol=1e-6)


def test_depth_map_matches_the_ordering_mask() -> None:
    points, T, _, _ = scene_truth((0.0, 0.5, 0.0))
    uv, rng, mask = project_lidar(points, T, CAMERA, SPEC, "ordering")
    depth = lidar_depth_map(points, T, CAMERA, SPEC, "ordering")
    assert (depth > 0).sum() <= mask.sum() and (depth > 0).sum() > 0.5 * mask.sum()
    u, v = np.rint(uv[mask]).astype(int).T
    # every visible point is at or behind its pixel's depth
    assert np.all(depth[v, u] <= rng[mask].astype(np.float32))
    assert np.all(depth[v, u] > 0)


# -------------------- kinds, empties, errors
def test_torch_input_gives_torch_output() -> None:
    points, T, _, _ = scene_truth((0.0, 0.5, 0.0))
    expected = occlusion_mask(points, T, CAMERA, SPEC, "ordering")
    pts_t, T_t = torch.from_numpy(points).float(), torch.from_numpy(T).float()
    mask = occlusion_mask(pts_t, T_t, CAMERA, SPEC, "ordering")
    assert isinstance(mask, torch.Tensor) and mask.dtype == torch.bool
    assert (mask.numpy() != expected).sum() <= 3  # float32 rounding may move a borderline point
    uv, rng, m = project_lidar(pts_t, T_t, CAMERA, SPEC, "none")
    assert uv.dtype == rng.dtype == torch.float32 and uv.shape == (len(points), 2) and m.dtype == torch.bool
    depth = lidar_depth_map(pts_t, T_t, CAMERA, SPEC)
    assert isinstance(depth, torch.Tensor) and depth.dtype == torch.float32 and depth.shape == (512, 512)


@pytest.mark.parametrize("method", ["ordering", "zbuffer", "hpr", "none"])
def test_empty_scan(method: str) -> None:
    _, T = rig((0.0, 0.5, 0.0))
    empty = np.zeros((0, 3), dtype=np.float32)
    mask = occlusion_mask(empty, T, CAMERA, SPEC, method)
    assert mask.shape == (0,) and mask.dtype == bool
    depth = lidar_depth_map(empty, T, CAMERA, SPEC, method)
    assert depth.shape == (512, 512) and not depth.any()
    nothing_in_view = np.array([[-10.0, 0.0, 0.0]])  # behind the camera
    assert not occlusion_mask(nothing_in_view, T, CAMERA, SPEC, method).any()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"points_lidar": np.array([[1.0, np.inf, 0.0]])}, "points_lidar"),
        ({"points_lidar": np.zeros((4, 4))}, "points_lidar"),
        ({"points_lidar": np.zeros((4, 3), dtype=np.int32)}, "points_lidar"),
        ({"T_cam_lidar": np.zeros((4, 4))}, "T_cam_lidar"),
        ({"T_cam_lidar": np.eye(4)[:3]}, "T_cam_lidar"),
        ({"T_cam_lidar": np.diag([1.0, 1.0, -1.0, 1.0])}, "T_cam_lidar"),
        ({"T_cam_lidar": [[1.0, 0, 0, 0]] * 4}, "T_cam_lidar"),
        ({"camera": "fisheye"}, "camera"),
        ({"spec": {"channels": 64}}, "spec"),
        ({"method": "raycast"}, "method"),
        ({"method": "hpr", "radius": 0.5}, "radius"),
        ({"method": "zbuffer", "max_incidence_deg": 90.0}, "max_incidence_deg"),
        ({"method": "zbuffer", "kernel": None, "threshold": "1"}, "threshold"),
        ({"method": "zbuffer", "relative": False}, "needs a threshold"),
        ({"azimuth_window": -1}, "azimuth_window"),
        ({"elevation_window": 1.5}, "elevation_window"),
        ({"elevation_tolerance": float("nan")}, "elevation_tolerance"),
        ({"kernel": 4, "method": "zbuffer"}, "kernel"),
        ({"threshold": -1.0, "method": "zbuffer"}, "threshold"),
        ({"kernel": 5}, "unknown option"),
        ({"max_depth": 0.0}, "max_depth"),
    ],
)
def test_bad_input_raises(kwargs: dict, match: str) -> None:
    args = {
        "points_lidar": np.array([[5.0, 0.0, 0.0]]),
        "T_cam_lidar": rig((0.0, 0.5, 0.0))[1],
        "camera": CAMERA,
        "spec": SPEC,
        "method": "ordering",
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        lidar_depth_map(**args)


def test_a_360_degree_scan_gives_the_same_mask_wherever_its_seam_falls() -> None:
    # A box inside a 10 m sphere at the LiDAR's front, and the same scene turned by 180 deg about z (the camera
    # too): then the +-180 deg seam of the rows runs through the middle of the image, with the box and the
    # points it hides on both sides of it. The ordering test must still compare them and keep the same points.
    spec = LidarSpec(channels=32, points_per_channel=1024, hfov_deg=360.0, vfov_deg=(-20.0, 20.0))
    el = spec.channel_elevations()[:, None]
    az = spec.column_azimuths()[None, :] + 0.3 * spec.horizontal_resolution  # the scan's azimuth phase
    beams = np.stack(np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)), -1)
    turn = np.diag([-1.0, -1.0, 1.0])  # 180 deg about z: beam j goes to beam j + 512, the same grid
    cases = [  # box centre, half size, camera centre (LiDAR frame)
        ((3.21, 0.24, 0.19), (0.2, 0.17, 0.17), (0.0, 0.27, 0.02)),
        ((1.81, 0.27, 0.15), (0.2, 0.25, 0.29), (0.0, 0.6, 0.38)),
        ((3.32, -0.52, 0.36), (0.2, 0.23, 0.25), (0.0, -0.09, -0.38)),
    ]
    for centre, half, camera in cases:
        lo, hi = np.subtract(centre, half), np.add(centre, half)
        masks = []
        for R in (np.eye(3), turn):
            dirs = beams.reshape(-1, 3) @ R.T
            box = np.array([[np.minimum(R @ lo, R @ hi), np.maximum(R @ lo, R @ hi)]])
            t = np.minimum(ray_box_entry(np.zeros(3), dirs, box), 10.0)
            R_cam = CAM_FROM_FLU @ R.T
            T = make_transform(R_cam, -R_cam @ (R @ np.asarray(camera)))
            masks.append(occlusion_mask(dirs * t[:, None], T, ideal_camera(512, 512), spec))
        assert (masks[0] == masks[1]).all(), (centre, half, camera)


@pytest.mark.parametrize("cx", [31.5, 27.0, 36.3])
def test_mirrored_depth_map_is_the_mirrored_scene_seen_by_the_camera(cx: float) -> None:
    """``mirror=True`` writes each point where the camera would see its mirror image (x -> -x in the camera
    frame), for a centred, an integer and an arbitrary off-centre principal point."""
    camera = ideal_camera(64, 64, cx=cx)
    T = make_transform(CAM_FROM_FLU, np.array([0.1, -0.2, 0.05]))
    rng = np.random.default_rng(4)
    points = rng.normal(size=(3000, 3)) * np.array([20.0, 20.0, 5.0])
    cam = points @ T[:3, :3].T + T[:3, 3]
    cam[:, 0] *= -1.0
    mirrored_points = (cam - T[:3, 3]) @ T[:3, :3]  # back to the LiDAR frame
    direct = lidar_depth_map(points, T, camera, method="none", mirror=True)
    reference = lidar_depth_map(mirrored_points, T, camera, method="none")
    # Columns whose mirror image lies outside the frame show what the unmirrored camera never saw: the mirrored
    # map leaves them empty (as the mirrored image is), the mirrored scene fills them.
    # A pixel column j covers [j - 0.5, j + 0.5]; its mirror covers [2 cx - j - 0.5, 2 cx - j + 0.5].
    near, far = 2 * cx - np.arange(64) - 0.5, 2 * cx - np.arange(64) + 0.5
    unseen, seen = (far < -0.5) | (near > 63.5), (near >= -0.5) & (far <= 63.5)
    assert unseen.any() == (cx != 31.5) and (direct[:, unseen] == 0).all()
    # Elsewhere identical, up to points that round to a pixel centre differently in the last bit.
    assert (direct > 0).sum() > 100
    assert (direct[:, seen] != reference[:, seen]).sum() <= 2
