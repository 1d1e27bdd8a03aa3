"""``data.format=omni360``: AirSim360 / Omni360-X read from fixtures written in the dataset's exact layouts and
encodings (tests/helpers/omni360_fixture.py; sources: github:Insta360-Research-Team/AirSim360
``data/demo_sample/``)."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.io.benchmark_classes import BENCHMARK_ID
from airfisheye_bench.io.datasets import open_dataset
from airfisheye_bench.io.datasets.omni360 import OWN_SENSOR, Omni360Source
from airfisheye_bench.io.datasets.omni360_files import natural_key, read_depth
from airfisheye_bench.io.datasets.omni360_labels import OMNI360_TO_BENCHMARK, read_class_list
from airfisheye_bench.io.errors import DatasetFormatError
from tests.helpers.omni360_fixture import (
    CLASS_IDS,
    NAMES,
    SKY_DEPTH,
    render,
    scene_hit,
    write_exr_depth,
    write_h5_depth,
    write_omni360_fixture,
)

HEIGHT = 16
FRAMES = 5


@pytest.fixture(scope="module")
def fixture_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_omni360_fixture(tmp_path_factory.mktemp("omni360") / "root", height=HEIGHT, frames=FRAMES)


@pytest.fixture
def writable_root(fixture_root: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(fixture_root, tmp_path / "root"))


def source(root: Path, **options) -> Omni360Source:
    src = open_dataset(root, "omni360", options)
    assert isinstance(src, Omni360Source)
    return src


# ------------------------------------------------------------------------------------------------ reading
@pytest.mark.parametrize("scene", ["NYC", "Demo"])
def test_each_modality_reads_as_written(fixture_root: Path, scene: str) -> None:
    """RGB (an RGBA panorama loses its alpha), depth from HDF5 / EXR / npy (the far plane as 0), labels through the
    scene's own ids."""
    src = source(fixture_root)
    for n in (0, FRAMES - 1):  # Demo's last frame has .npy depth, its others EXR
        sid = f"{scene}/panorama_{n}"
        rgb, depth, label, _ = render(HEIGHT, 2 * HEIGHT, n)
        np.testing.assert_array_equal(src.equirect(sid, "rgb"), rgb)
        expected = np.where(depth >= SKY_DEPTH, 0.0, depth).astype(np.float32)
        np.testing.assert_array_equal(src.equirect(sid, "depth"), expected)
        names = src.spec.train_class_names
        seg = src.equirect(sid, "seg")
        for k, name in enumerate(NAMES):
            want = names.index(name) if name in CLASS_IDS[scene] else 255  # Demo: sky unlisted (alpha 0)
            assert (seg[label == k] == want).all(), (sid, name)


def test_instances_are_argb_tuples(fixture_root: Path) -> None:
    src = source(fixture_root)
    ids = src.instance("NYC/panorama_1")
    _, _, label, obj = render(HEIGHT, 2 * HEIGHT, 1)
    assert set(np.unique(ids >> 24)) == {
        CLASS_IDS["NYC"][n] for n in NAMES if (label == NAMES.index(n)).any()
    }
    walls = obj >= 2  # one object per wall: one id each
    for k in np.unique(obj[walls]):
        assert len(np.unique(ids[obj == k])) == 1
    assert len({int(ids[obj == k][0]) for k in np.unique(obj[walls])}) == len(np.unique(obj[walls]))


def test_depth_encodings(tmp_path: Path) -> None:
    """HDF5 float32 and the legacy uint16 with ``depth_range_m``; EXR's R channel; ``.npy``; the far plane and
    non-finite values as no depth; negative depth refused."""
    import h5py

    depth = np.array([[1.0, 2.5], [999.0, np.inf]], np.float32)
    write_h5_depth(tmp_path / "a.h5", depth)
    np.testing.assert_array_equal(read_depth(tmp_path / "a.h5"), [[1.0, 2.5], [999.0, 0.0]])
    with h5py.File(tmp_path / "legacy.h5", "w") as h5:
        h5.create_dataset("depth", data=np.array([[0, 65535], [32768, 13107]], np.uint16))
        h5["depth"].attrs["depth_range_m"] = 500.0
    np.testing.assert_allclose(
        read_depth(tmp_path / "legacy.h5"), [[0.0, 500.0], [32768 / 65535 * 500.0, 100.0]], rtol=1e-6
    )
    write_exr_depth(tmp_path / "d.exr", np.array([[3.0, 1000.0], [1500.0, 0.25]], np.float32))
    np.testing.assert_array_equal(read_depth(tmp_path / "d.exr"), [[3.0, 0.0], [0.0, 0.25]])
    np.save(tmp_path / "d.npy", np.array([[[4.0, 9.0]], [[np.nan, 9.0]]], np.float32))  # [H, W, C]: channel 0
    np.testing.assert_array_equal(read_depth(tmp_path / "d.npy"), [[4.0], [0.0]])
    np.save(tmp_path / "neg.npy", np.array([[-1.0]], np.float32))
    with pytest.raises(DatasetFormatError, match=r"neg.npy: negative depth"):
        read_depth(tmp_path / "neg.npy")
    with h5py.File(tmp_path / "key.h5", "w") as h5:
        h5.create_dataset("distance", data=depth)
    with pytest.raises(DatasetFormatError, match=r"key.h5: no dataset /depth \(it has \['distance'\]\)"):
        read_depth(tmp_path / "key.h5")
    with h5py.File(tmp_path / "norange.h5", "w") as h5:
        h5.create_dataset("depth", data=np.zeros((2, 2), np.uint16))
    with pytest.raises(
        DatasetFormatError, match=r"norange.h5: key '/depth': uint16 depth without its depth_range_m"
    ):
        read_depth(tmp_path / "norange.h5")
    (tmp_path / "bad.exr").write_bytes(b"not an exr")
    with pytest.raises(DatasetFormatError, match=r"bad.exr: unreadable EXR"):
        read_depth(tmp_path / "bad.exr")


def test_an_exr_without_the_package_is_one_line(fixture_root: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "OpenEXR", None)  # import OpenEXR now raises ImportError
    src = source(fixture_root)
    with pytest.raises(
        DatasetFormatError, match=r"Depth_0.exr: reading EXR needs the Python package OpenEXR"
    ) as err:
        src.equirect("Demo/panorama_0", "depth")
    assert 'pip install -e ".[omni360]"' in str(err.value) and "\n" not in str(err.value)


# ---------------------------------------------------------------------------------------- stems and layout
def test_stems_match_across_folders_in_both_namings(fixture_root: Path) -> None:
    src = source(fixture_root)
    assert src.scenes() == ["Demo", "NYC"]
    assert src.erp_size == (HEIGHT, 2 * HEIGHT) and src.spec.equirect_size == (HEIGHT, 2 * HEIGHT)
    paths = {m: src.path_of("NYC/panorama_4", m, "equirect") for m in ("rgb", "depth", "seg")}
    assert paths["rgb"].parent.name == "nyc_Raw_Part2" and paths["rgb"].name == "panorama_4.png"
    assert paths["depth"].relative_to(fixture_root).as_posix() == "NYC/nyc_Depth/Depth_4.h5"
    assert paths["seg"].relative_to(fixture_root).as_posix() == "NYC/nyc_seg_panorama/panorama_4.png"
    assert src.path_of("Demo/panorama_0", "depth", "equirect").name == "Depth_0.exr"
    assert src.path_of("Demo/panorama_4", "depth", "equirect").name == "panorama_4.npy"


def test_frames_are_in_natural_order_and_a_scene_folder_is_a_root(writable_root: Path) -> None:
    assert sorted(["p_10", "p_9", "p_1"], key=natural_key) == ["p_1", "p_9", "p_10"]
    demo = writable_root / "Demo"
    for name in ("panorama", "semantic", "instance"):
        shutil.copy(demo / name / "panorama_1.png", demo / name / "panorama_10.png")
    shutil.copy(demo / "depth" / "Depth_1.exr", demo / "depth" / "Depth_10.exr")
    src = source(demo, split_period=100)  # one scene: the root itself
    assert src.scenes() == ["Demo"]
    frames = [s.split("/")[1] for s in src.split("train") + src.split("val") + src.split("test")]
    assert frames == [f"panorama_{n}" for n in (0, 1, 2, 3, 4, 10)]


def test_scenes_are_selected(fixture_root: Path) -> None:
    src = source(fixture_root, scenes=["NYC"])
    assert src.scenes() == ["NYC"] and all(s.startswith("NYC/") for s in src.split("train"))
    with pytest.raises(ConfigError, match=r"scenes: no scene \['Atlantis'\] .*\['Demo', 'NYC'\]"):
        source(fixture_root, scenes=["Atlantis"])


# ------------------------------------------------------------------------------------------------ classes
def test_class_lists_are_read_as_the_demo_reader_reads_them(tmp_path: Path) -> None:
    path = tmp_path / "semantic_lists_x.txt"
    path.write_text("# comment\nSky 1\n\nRoad   asphalt road   2\nheader\n", encoding="utf-8")
    assert read_class_list(path).names == {1: "Sky", 2: "Road"}
    path.write_text("Sky 1\nRoad two\n", encoding="utf-8")
    with pytest.raises(
        DatasetFormatError, match=r"semantic_lists_x.txt: key 'line 2': expected '<name> ... <id>'"
    ):
        read_class_list(path)
    path.write_text("Sky 1\nRoad 1\n", encoding="utf-8")
    with pytest.raises(DatasetFormatError, match=r"key 'line 2': id 1 is listed twice"):
        read_class_list(path)


def test_dataset_classes_are_every_scenes_names_through_each_scenes_ids(fixture_root: Path) -> None:
    src = source(fixture_root)
    # Demo's list first (scenes sorted, each by id), then the names only NYC has.
    assert src.spec.train_class_names == ["Building", "Road", "Grass", "Fence", "Tree_01", "Statue", "Sky"]
    assert src.spec.label_lut()[:7].tolist() == list(range(7))  # the source maps the ids itself


def test_benchmark_classes_through_the_table_and_the_option(fixture_root: Path) -> None:
    with pytest.raises(
        DatasetFormatError, match=r"semantic_lists_demo.txt: class names \['Statue'\] have no benchmark"
    ):
        source(fixture_root, classes="benchmark")
    src = source(fixture_root, classes="benchmark", benchmark_map={"Statue": None, "Grass": "ground"})
    assert src.spec.train_class_names[:3] == ["sky", "road", "sidewalk"]
    _, _, label, _ = render(HEIGHT, 2 * HEIGHT, 0)
    seg = src.equirect("NYC/panorama_0", "seg")
    expected = {"Sky": "sky", "Road": "road", "Grass": "ground", "Fence": "barrier", "Tree_01": "tree"}
    for name, target in expected.items():
        assert (seg[label == NAMES.index(name)] == BENCHMARK_ID[target]).all(), name
    assert (seg[label == NAMES.index("Statue")] == 255).all()
    assert OMNI360_TO_BENCHMARK["building"] == "building"
    with pytest.raises(ConfigError, match=r"benchmark_map.Statu: no scene's class list names 'Statu'"):
        source(fixture_root, classes="benchmark", benchmark_map={"Statu": None})
    with pytest.raises(ConfigError, match=r"benchmark_map.Statue='person': expected a benchmark class"):
        source(fixture_root, classes="benchmark", benchmark_map={"Statue": "person"})
    with pytest.raises(
        ConfigError, match=r"benchmark_map maps names onto the benchmark's classes: set classes=benchmark"
    ):
        source(fixture_root, benchmark_map={"Statue": None})


def test_a_label_id_missing_from_the_list_names_the_file(writable_root: Path) -> None:
    png = writable_root / "NYC" / "nyc_seg_panorama" / "panorama_2.png"
    rgba = np.asarray(Image.open(png)).copy()
    rgba[0, :3, 3] = 99
    Image.fromarray(rgba, "RGBA").save(png)
    with pytest.raises(
        DatasetFormatError,
        match=r"panorama_2.png: class ids \[99\] in the alpha channel are not in nyc_semantic_list.txt",
    ):
        source(writable_root).equirect("NYC/panorama_2", "seg")
    Image.fromarray(rgba[..., :3], "RGB").save(png)
    with pytest.raises(
        DatasetFormatError,
        match=r"panorama_2.png: expected a PNG with an alpha channel \(the class id\), got mode RGB",
    ):
        source(writable_root).equirect("NYC/panorama_2", "seg")


def test_labels_come_from_the_instance_pngs_without_a_semantic_folder(writable_root: Path) -> None:
    shutil.rmtree(writable_root / "NYC" / "nyc_seg_panorama")
    src = source(writable_root, scenes=["NYC"])
    assert src.path_of("NYC/panorama_0", "seg", "equirect").parent.name == "nyc_instance_panorama"
    _, _, label, _ = render(HEIGHT, 2 * HEIGHT, 0)
    seg = src.equirect("NYC/panorama_0", "seg")
    assert (seg[label == NAMES.index("Fence")] == src.spec.train_class_names.index("Fence")).all()


# ------------------------------------------------------------------------------------------------- splits
def test_splits_are_frame_blocks_per_scene(fixture_root: Path) -> None:
    src = source(fixture_root)
    assert src.split("train") == [f"{s}/panorama_{n}" for s in ("Demo", "NYC") for n in (0, 1, 2)]
    assert src.split("val") == ["Demo/panorama_3", "NYC/panorama_3"]
    assert src.split("test") == ["Demo/panorama_4", "NYC/panorama_4"]
    assert src.spec.splits.by == "frame_blocks"
    strided = source(fixture_root, frame_stride=2)  # frames 0, 2, 4 of each scene
    assert strided.split("val") == ["Demo/panorama_2", "NYC/panorama_2"]
    assert "split_period=10" in src.split_rule("val") and "at least 3 frames" in src.split_rule("val")


def test_splits_by_scene(fixture_root: Path) -> None:
    src = source(fixture_root, split_scenes={"train": ["NYC"], "val": ["Demo"], "test": ["Demo"]})
    assert src.split("train") == [f"NYC/panorama_{n}" for n in range(FRAMES)]
    assert src.split("test") == src.split("val") == [f"Demo/panorama_{n}" for n in range(FRAMES)]
    assert src.spec.splits.by == "scene"
    with pytest.raises(ConfigError, match=r"split_scenes: scene 'NYC' is in train and val"):
        source(fixture_root, split_scenes={"train": ["NYC"], "val": ["NYC"]})
    with pytest.raises(ConfigError, match=r"split_scenes.test: no scene 'Mars'"):
        source(fixture_root, split_scenes={"test": ["Mars"]})


# ------------------------------------------------------------------------------------------------- errors
def test_missing_folders_and_files_name_them(writable_root: Path, tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetFormatError, match=r"empty: no Omni360 scene: expected <scene>/panorama/"):
        source(tmp_path / "empty")
    (writable_root / "NYC" / "nyc_Depth" / "Depth_2.h5").unlink()
    src = source(writable_root)
    with pytest.raises(
        DatasetFormatError,
        match=r"nyc_Depth: no depth file for panorama_2.png \(looked for panorama_2.h5, .*Depth_2.npy\)",
    ):
        src.equirect("NYC/panorama_2", "depth")
    shutil.rmtree(writable_root / "Demo" / "depth")
    (writable_root / "NYC" / "nyc_semantic_list.txt").unlink()
    src = source(writable_root)
    assert src.modalities == ("rgb",)
    assert "Demo: no depth folder (depth/ or <prefix>_Depth/)" in src.missing_reason("depth")
    assert "NYC: no class list" in src.missing_reason("seg")
    assert "equirectangular panoramas (no fisheye)" in src.missing_reason("fisheye")
    with pytest.raises(DatasetFormatError, match=r"use data\.source=equirect"):
        src.fisheye("NYC/panorama_0", "rgb")
    Image.new("RGB", (10, 5)).save(writable_root / "NYC" / "nyc_Raw_Part1" / "panorama_1.png")
    with pytest.raises(DatasetFormatError, match=r"panorama_1.png: rgb is 10x5, the panoramas are 32x16"):
        source(writable_root).equirect("NYC/panorama_1", "rgb")


def test_ambiguous_layouts_are_refused(writable_root: Path) -> None:
    shutil.copytree(writable_root / "NYC" / "nyc_Depth", writable_root / "NYC" / "nyc2_Depth")
    with pytest.raises(DatasetFormatError, match=r"NYC: two depth folders \(nyc2_Depth, nyc_Depth\)"):
        source(writable_root)
    shutil.rmtree(writable_root / "NYC" / "nyc2_Depth")
    shutil.copy(
        writable_root / "NYC" / "nyc_Raw_Part1" / "panorama_0.png", writable_root / "NYC" / "nyc_Raw_Part2"
    )
    with pytest.raises(DatasetFormatError, match=r"panorama_0.png: frame panorama_0 is stored twice"):
        source(writable_root)


def test_bad_options(fixture_root: Path) -> None:
    for options, message in (
        ({"classes": "cityscapes"}, r"classes='cityscapes': expected one of dataset, benchmark"),
        ({"split_period": 2}, r"split_period=2: expected an integer >= 3"),
        ({"frame_stride": 0}, r"frame_stride=0: expected an integer >= 1"),
        ({"lidar": "vlp17"}, r"lidar='vlp17': expected one of"),
        ({"pitch_deg": 30}, r"unknown keys \['pitch_deg'\]"),  # data.gimbal turns the camera
        ({"camera": "front"}, r"unknown keys \['camera'\]"),
    ):
        with pytest.raises(ConfigError, match=message):
            source(fixture_root, **options)


def test_the_calibration_is_the_default_lens_at_the_panoramas_centre(fixture_root: Path) -> None:
    from airfisheye_bench.geometry.transforms import CAM_FROM_FLU

    src = source(fixture_root)
    calib = src.calib("NYC/panorama_0")
    assert (
        calib.camera["model"] == "equidistant" and calib.camera["width"] == calib.camera["height"] == HEIGHT
    )
    assert calib.camera["fov_deg"] == 190.0 and calib.face_size is None
    # The recorded camera looks at the middle column on the horizon: the body's (the panorama's FLU) forward.
    np.testing.assert_array_equal(src.pano_rotation, np.eye(3))
    np.testing.assert_allclose(calib.T_body_cam[:3, :3] @ [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(calib.T_cam_lidar_static, src.T_cam_lidar("NYC/panorama_0"), atol=1e-12)
    np.testing.assert_allclose(src.T_cam_lidar("NYC/panorama_0")[:3, :3], CAM_FROM_FLU)


# -------------------------------------------------------------------------------------------------- LiDAR
def test_the_lidar_texel_is_the_remaps_nearest_texel() -> None:
    """:func:`erp_texel` (the LiDAR's look-up) takes the texel ``EquirectToFisheye``'s nearest mode takes, for rays
    all over the sphere (a 250 deg lens looking up and to the side reaches both poles and the seam)."""
    from airfisheye_bench.geometry.cameras.ideal import ideal_camera
    from airfisheye_bench.geometry.equirect import EquirectToFisheye
    from airfisheye_bench.geometry.equirect_lidar import erp_texel
    from airfisheye_bench.geometry.transforms import gimbal_rotation

    h, w = 24, 48
    camera = ideal_camera(96, 96, fov_deg=250.0)
    rotation = gimbal_rotation(yaw_deg=150.0, pitch_deg=-60.0)
    index = np.arange(h * w, dtype=np.float64).reshape(1, h, w)
    remapped = EquirectToFisheye(camera, (h, w), rotation=rotation)(index, mode="nearest", fill=-1)[0]
    valid = camera.valid_mask().numpy()
    rays = camera.ray_grid(torch.float64).numpy()[valid]
    row, col = erp_texel(rays @ rotation.T, h, w)
    np.testing.assert_array_equal(remapped[valid], row * w + col)


def _texels(directions: np.ndarray, h: int, w: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The texel a panorama-frame direction falls in, from the ERP convention written out (:func:`erp_ray`'s
    inverse), not through the project's code; and whether the direction is clear of a texel edge (a beam on one,
    as VLP-16's at 67.5 deg azimuth on a 32-column panorama, goes either way by rounding)."""
    lon = np.arctan2(directions[:, 0], directions[:, 2])
    lat = np.arctan2(-directions[:, 1], np.hypot(directions[:, 0], directions[:, 2]))
    u, v = w * (lon + np.pi) / (2 * np.pi), h * (np.pi / 2 - lat) / np.pi
    clear = (np.abs(u - np.rint(u)) > 1e-9) & (np.abs(v - np.rint(v)) > 1e-9)
    return np.clip(np.floor(v).astype(int), 0, h - 1), np.floor(u).astype(int) % w, clear


@pytest.mark.parametrize("preset", ["paper", "vlp16"])
def test_the_cast_scan_takes_the_range_of_the_texel_each_beam_falls_in(
    fixture_root: Path, preset: str
) -> None:
    """Every point of the cast scan (FLU, x along the recorded camera's axis: the panorama's middle column) lies
    along its beam at the range the depth panorama holds in the texel its direction falls in; its rings are the
    spec's channels; a LiDAR turned in the panorama (here 30 deg left, 20 deg down) casts along its own beams. The
    source's own sensor is the paper's; ``data.lidar.preset`` names another (``cast_scan``)."""
    from airfisheye_bench.geometry.equirect_lidar import lidar_from_equirect
    from airfisheye_bench.geometry.lidar import LidarSpec
    from airfisheye_bench.geometry.transforms import CAM_FROM_FLU, gimbal_rotation

    src = source(fixture_root)
    spec = LidarSpec.from_preset(preset)
    scan = src.lidar_scan("NYC/panorama_1") if preset == OWN_SENSOR else src.cast_scan("NYC/panorama_1", spec)
    beams = spec.channels * spec.points_per_channel
    assert scan.rings is not None and scan.rings.max() < spec.channels and len(scan.points) > beams // 2
    assert scan.no_returns == beams - len(scan.points)
    depth = src.equirect("NYC/panorama_1", "depth")
    row, col, clear = _texels(scan.points @ CAM_FROM_FLU.T, HEIGHT, 2 * HEIGHT)
    assert clear.mean() > 0.95  # the paper sensor's lowest ring, -45 deg, lies on a texel edge
    ranges = np.linalg.norm(scan.points, axis=1)
    np.testing.assert_allclose(ranges[clear], depth[row, col][clear], rtol=1e-6)
    R_pano_lidar = gimbal_rotation(yaw_deg=30.0, pitch_deg=20.0) @ CAM_FROM_FLU
    points, rings = lidar_from_equirect(depth, spec, R_pano_lidar)
    row, col, clear = _texels(points @ R_pano_lidar.T, HEIGHT, 2 * HEIGHT)
    np.testing.assert_allclose(np.linalg.norm(points, axis=1)[clear], depth[row, col][clear], rtol=1e-6)
    ahead = R_pano_lidar @ np.array([1.0, 0.0, 0.0])  # the LiDAR's x axis, 30 deg left of the middle column
    assert np.degrees(np.arctan2(ahead[0], ahead[2])) == pytest.approx(-30.0)
    assert len(points) != len(scan.points) and rings.max() < spec.channels
    # data.lidar.preset's sensor is cast instead of the source's own (the datamodule asks for it).
    other = src.cast_scan("NYC/panorama_1", LidarSpec.from_preset("hdl32e"))
    assert other.rings.max() < 32 and len(other.points) != len(scan.points)


def test_the_deprecated_lidar_option_casts_its_preset_as_before_and_says_so(fixture_root: Path) -> None:
    """``format_options.lidar=<preset>`` keeps working for one release: the source's own sensor becomes that preset
    (the scan ``data.lidar.preset`` casts), with a warning naming the new key; a datamodule refuses it beside a
    different ``data.lidar.preset``, naming both keys."""
    from airfisheye_bench.geometry.lidar import LidarSpec
    from datamodules import AirFisheyeDataModule

    with pytest.warns(
        DeprecationWarning, match=r"format_options\.lidar=vlp16 .*use data\.lidar\.preset=vlp16"
    ):
        legacy = source(fixture_root, lidar="vlp16")
    cast = source(fixture_root).cast_scan("NYC/panorama_1", LidarSpec.from_preset("vlp16"))
    np.testing.assert_array_equal(legacy.lidar_scan("NYC/panorama_1").points, cast.points)
    assert legacy.lidar_spec().name == "vlp16" and source(fixture_root).lidar_spec().name == OWN_SENSOR

    def datamodule(lidar: str, preset: str) -> AirFisheyeDataModule:
        return AirFisheyeDataModule(
            "completion",
            root=fixture_root,
            format="omni360",
            format_options={"lidar": lidar},
            lidar={"preset": preset},
        )

    with pytest.raises(
        ConfigError, match=r"data\.format_options\.lidar='paper' and data\.lidar\.preset='vlp16'"
    ):
        datamodule("paper", "vlp16")
    assert datamodule("vlp16", "vlp16").lidar.spec.name == "vlp16"


# ------------------------------------------------------------------------------------------------- serving
@pytest.fixture(scope="module")
def fine_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """64 x 128 panoramas: texels of 2.8 deg, fine enough to compare the served maps with the analytic scene."""
    return write_omni360_fixture(tmp_path_factory.mktemp("omni360_fine") / "root", height=64, frames=3)


def _dataset(root: Path, task: str, size: int = 48, view: list[float] | None = None, **options):
    """One split (``train``) of the NYC scene through a ``size``^2 fisheye, the camera turned to ``view``."""
    from airfisheye_bench.geometry.gimbal import Gimbal
    from datamodules import AirFisheyeDataset, CameraConfig

    kwargs = {k: options.pop(k) for k in ("occlusion", "source", "source_fallback") if k in options}
    if view is not None:
        kwargs["gimbal"] = Gimbal.parse(view).for_split(training=False)
    return AirFisheyeDataset.from_root(
        root,
        "train",
        task,
        camera=CameraConfig(size=size),
        format="omni360",
        format_options={"scenes": ["NYC"], **options},
        **{"source": "equirect", **kwargs},
    )


def test_the_served_fisheye_sees_the_scene_through_the_gimbal(fine_root: Path) -> None:
    """Depth and labels of the served 190 deg fisheye, turned by ``data.gimbal=[-40, 30]`` (40 deg right, 30 deg
    down), agree with the analytic scene along each pixel's ray (turned into the panorama by gimbal_rotation)."""
    from airfisheye_bench.geometry.transforms import gimbal_rotation

    ds = _dataset(fine_root, "depth", view=[-40.0, 30.0])
    seg = _dataset(fine_root, "seg", view=[-40.0, 30.0])
    sample, labels = ds[0], seg[0]["label"].numpy()
    valid = sample["valid_mask"].numpy()
    assert valid.sum() > 0.7 * valid.size and ds.camera.model == "equidistant" and ds.camera.fov_deg == 190.0
    rays = ds.camera.ray_grid(torch.float64).numpy()[valid] @ gimbal_rotation(yaw_deg=-40.0, pitch_deg=30.0).T
    truth, name, _ = scene_hit(rays, frame=0)
    served = sample["depth"][0].numpy()[valid]
    near = np.isfinite(truth) & (truth <= ds.max_depth)
    rel = np.abs(served[near] - truth[near]) / truth[near]
    assert np.median(rel) < 0.02 and np.mean(rel < 0.1) > 0.9
    assert np.mean(served[~np.isfinite(truth)] == 0) > 0.9  # the sky: no depth
    classes = ds.spec.train_class_names
    expected = np.array([classes.index(n) for n in NAMES])[name]
    assert np.mean(labels[valid] == expected) > 0.93


@pytest.mark.parametrize("view", [None, [25.0, 35.0]])
def test_sparse_depth_lands_on_the_dense_depth_and_needs_no_occlusion_correction(
    fixture_root: Path, view: list[float] | None
) -> None:
    """The whole chain (cast beams, T_cam_lidar, a gimbal view turning the camera and the LiDAR with it,
    projection): LiDAR ranges agree with the remapped depth where they land; with no parallax every occlusion method
    serves the same map (none is applied)."""
    maps = {}
    for method in ("ordering", "zbuffer", "none", "oracle"):
        sample = _dataset(fixture_root, "completion", size=64, view=view, occlusion=method)[0]
        maps[method] = sample["sparse_depth"][0]
    sparse, dense = maps["ordering"], sample["depth"][0]
    hit = (sparse > 0) & (dense > 0)
    assert hit.sum() > 200
    rel = ((sparse[hit] - dense[hit]).abs() / dense[hit]).numpy()
    assert np.median(rel) < 0.02 and np.mean(rel < 0.1) > 0.9
    for method in ("zbuffer", "none", "oracle"):
        assert torch.equal(maps[method], sparse), method


def test_the_image_source_and_the_contents_a_task_needs(writable_root: Path) -> None:
    with pytest.raises(
        ConfigError, match=r"equirectangular panoramas \(no cubemap\).*; use data\.source=equirect"
    ):
        _dataset(writable_root, "seg", source="cubemap")
    # A source of a mixture that data.source does not fit remaps the raw recording it has.
    assert _dataset(writable_root, "seg", source="cubemap", source_fallback=True).source == "equirect"
    shutil.rmtree(writable_root / "NYC" / "nyc_Depth")
    with pytest.raises(ConfigError, match=r"NYC: no depth folder .*; task=depth needs it"):
        _dataset(writable_root, "depth")
    assert _dataset(writable_root, "seg").spec.contents == ("equirect",)  # no depth: no LiDAR either
    with pytest.raises(
        ConfigError, match=r"NYC: no depth folder .* \(the LiDAR is cast from it\); task=completion"
    ):
        _dataset(writable_root, "completion")


def test_inspect_checks_every_file_through_the_source(
    writable_root: Path, capsys: pytest.CaptureFixture
) -> None:
    """``airfisheye-inspect root=<root> format=omni360 [deep=true]``."""
    from airfisheye_bench.cli import inspect
    from airfisheye_bench.dataset_tools.inspect_source import inspect_source

    for deep in (False, True):
        report = inspect_source(writable_root, "omni360", deep=deep)
        assert report.ok, report.summary()
        assert report.splits == {"train": 6, "val": 2, "test": 2} and report.samples == 10
    assert (
        inspect([f"root={writable_root}", "format=omni360", "format_options={scenes:[NYC]}", "deep=true"])
        == 0
    )
    assert "splits: train 3, val 1, test 1" in capsys.readouterr().out
    (writable_root / "NYC" / "nyc_Depth" / "Depth_3.h5").unlink()
    label = writable_root / "Demo" / "semantic" / "panorama_1.png"
    rgba = np.asarray(Image.open(label)).copy()
    rgba[2, 2, 3] = 77
    Image.fromarray(rgba, "RGBA").save(label)
    shallow = inspect_source(writable_root, "omni360")
    deep = inspect_source(writable_root, "omni360", deep=True)
    assert dict(shallow.problems)[str(writable_root / "NYC" / "nyc_Depth" / "panorama_3.h5")] == "missing"
    problems = dict(deep.problems)
    assert "no depth file for panorama_3.png" in problems[str(writable_root / "NYC" / "nyc_Depth")]
    assert "class ids [77] in the alpha channel are not in semantic_lists_demo.txt" in problems[str(label)]


# ------------------------------------------------------------------------------------------- end to end
@pytest.fixture(scope="module")
def train_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """32 x 64 panoramas, 5 frames per scene: 6 training frames, 2 val, 2 test."""
    return write_omni360_fixture(tmp_path_factory.mktemp("omni360_train") / "root", height=32, frames=5)


# depth reads what completion reads (the image, the dense depth) and trains AdaBins, which the tiny runs cover: slow
@pytest.mark.integration
@pytest.mark.parametrize("task", ["seg", pytest.param("depth", marks=pytest.mark.slow), "completion"])
def test_train_runs_every_task_on_omni360(task: str, train_root: Path, tmp_path: Path) -> None:
    """``python train.py task=<task> data=omni360 data.root=<fixture> trainer=debug ...`` writes its metrics."""
    import json

    from omegaconf import open_dict

    from airfisheye_bench.training import train
    from tests.helpers.configs import compose_train
    from tests.helpers.runs import tiny_run_overrides

    overrides = tiny_run_overrides(task, train_root, size=64 if task == "depth" else 32)  # AdaBins needs 64
    cfg = compose_train([*overrides, "data=omni360", "data.gimbal=[0,20]", "logger=csv"])
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    results = train(cfg)
    record = json.loads((tmp_path / "results.json").read_text())
    primary = cfg.task.primary_metric
    assert record["task"] == task and record["split"] == "test"
    assert np.isfinite(record["metrics"][primary])
    assert record["metrics"][primary] == pytest.approx(results["metrics"][primary])
    assert record["config"]["data"]["source"] == "equirect"


@pytest.mark.integration
def test_the_synthetic_preset_and_omni360_in_one_run(train_root: Path, tmp_path: Path) -> None:
    """``data=omni360 data.root=<fixture> data.sources=[synthetic,omni360]``: the synthetic preset's cube faces
    and the panoramas are remapped to one lens, each source scored apart (depth: no class map needed)."""
    import json

    from omegaconf import open_dict

    from airfisheye_bench.training import train
    from tests.helpers.configs import compose_train
    from tests.helpers.runs import tiny_run_overrides

    base = [o for o in tiny_run_overrides("depth", train_root, size=64) if not o.startswith("data.root=")]
    cfg = compose_train(
        [
            *base,
            "data=omni360",
            f"data.root={train_root}",
            "data.sources=[synthetic,omni360]",
            "data.source_options={synthetic:{preset:tiny}}",
            "logger=csv",
        ]
    )
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    train(cfg)
    record = json.loads((tmp_path / "results.json").read_text())
    tiny, omni = record["sources"]["synthetic"], record["sources"]["omni360"]
    assert omni["dataset"]["format"] == "omni360" and omni["dataset"]["root"] == str(train_root)
    assert tiny["dataset"]["preset"] == "tiny"
    assert omni["dataset"]["camera"]["width"] == tiny["dataset"]["camera"]["width"] == 64
    for part in (tiny, omni):
        assert np.isfinite(part["metrics"]["rmse"]) and part["dataset"]["frames"] > 0


@pytest.mark.integration
def test_bad_inputs_on_the_command_line_are_one_line(writable_root: Path, tmp_path: Path) -> None:
    """A missing depth folder for task=depth, a missing depth file, names the benchmark table does not know."""
    from tests.helpers.commands import TRAIN, assert_one_line_error, run_in_process

    def run(*args: str):
        base = [
            "data=omni360",
            f"data.root={writable_root}",
            "trainer=debug",
            "data.camera.size=32",
            "data.batch_size=2",
            "data.num_workers=0",
            "data.persistent_workers=false",
        ]
        return run_in_process(
            TRAIN, [*base, *args, f"hydra.run.dir={tmp_path / str(len(list(tmp_path.iterdir())))}"]
        )

    outcome = run("task=seg", "data.format_options.classes=benchmark")
    assert_one_line_error(
        outcome, "semantic_lists_demo.txt", "['Statue']", "data.format_options.benchmark_map"
    )
    outcome = run(
        "task=seg", "data.format_options.classes=benchmark", "data.format_options.benchmark_map={Statu:null}"
    )
    assert_one_line_error(
        outcome, "data.format_options.benchmark_map.Statu", "no scene's class list names 'Statu'"
    )
    shutil.rmtree(writable_root / "Demo" / "depth")
    outcome = run("task=depth")
    assert_one_line_error(outcome, str(writable_root / "Demo"), "no depth folder", "task=depth needs it")
    (writable_root / "NYC" / "nyc_Depth" / "Depth_4.h5").unlink()  # the test frame: every run loads it
    outcome = run("task=completion", "data.format_options.scenes=[NYC]", "model.encoder_name=resnet18")
    assert_one_line_error(
        outcome, str(writable_root / "NYC" / "nyc_Depth"), "no depth file for panorama_4.png"
    )


def test_the_config_lists_every_option_with_its_default() -> None:
    from tests.helpers.configs import compose_train

    cfg = compose_train(["task=seg", "data=omni360"])
    assert cfg.data.format == "omni360" and cfg.data.source == "equirect" and cfg.data.root is None
    assert dict(cfg.data.format_options) == Omni360Source.OPTIONS


def test_design_md_prints_the_class_table_of_the_code() -> None:
    from airfisheye_bench.io.benchmark_classes import BENCHMARK_CLASSES

    text = (Path(__file__).resolve().parents[3] / "docs" / "design.md").read_text(encoding="utf-8")
    section = text.split("### AirSim360 / Omni360-X", 1)[1].split("\n### ", 1)[0]
    for c in BENCHMARK_CLASSES:
        names = ", ".join(f"`{n}`" for n, t in OMNI360_TO_BENCHMARK.items() if t == c.name)
        assert f"| {c.id} | {c.name} | {names} |" in section, c.name
    ignored = ", ".join(f"`{n}`" for n, t in OMNI360_TO_BENCHMARK.items() if t is None)
    assert f"| 255 | ignored | {ignored} |" in section
