"""``airfisheye-generate camera.calibration=<file>``: the fisheye is rendered through the calibrated lens.

The lens is KITTI-360's ``image_02`` (MEI), written in its own file format; the checks compare the generator's
output with the camera :func:`~airfisheye_bench.io.calibration_files.load_camera` reads from that file, never with
the generator's own record of it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry import CubemapToFisheye, ideal_camera
from airfisheye_bench.io import DatasetReader
from airfisheye_bench.io.calibration_files import load_camera
from airfisheye_bench.synth import cli
from airfisheye_bench.synth.presets import get_preset
from tests.helpers import calibration_fixtures as fx


@pytest.fixture(scope="module")
def kitti_dataset(tmp_path_factory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("kitti360_lens")
    calibration = fx.write_kitti360(tmp / "image_02.yaml")
    assert cli.generate("tiny", {"camera.calibration": str(calibration)}, tmp / "data", progress=False) == 0
    return tmp / "data", calibration


def _remap_vs_raycast(reader: DatasetReader, camera, sample_ids) -> tuple[float, float]:
    """Median relative depth difference and label agreement between the ray-cast fisheye files and the cube
    faces remapped through ``camera``."""
    depth_err, agree = [], []
    remap = CubemapToFisheye(camera, get_preset("tiny").face_size)
    for sid in sample_ids:
        depth = remap.remap(reader.cubemap(sid, "depth")[:, None], mode="nearest", fill=0)[0]
        seg = remap.remap(reader.cubemap(sid, "seg")[:, None], mode="nearest", fill=255)[0]
        fdepth, fseg = reader.fisheye(sid, "depth"), reader.fisheye(sid, "seg")
        both = (depth > 0) & (fdepth > 0)
        depth_err.append(np.abs(depth[both] - fdepth[both]) / fdepth[both])
        inside = (fseg != 255) & (seg != 255)
        agree.append(seg[inside] == fseg[inside])
    return float(np.median(np.concatenate(depth_err))), float(np.concatenate(agree).mean())


def test_generated_fisheye_looks_along_the_calibrated_rays(kitti_dataset) -> None:
    root, calibration = kitti_dataset
    lens = load_camera(calibration).resized(64, 64)  # KITTI-360's 1400 x 1400 lens at the preset's 64 x 64
    reader = DatasetReader(root)
    sample_ids = reader.split("val")
    recorded = reader.calib(sample_ids[0]).fisheye_camera()
    recorded_params, lens_params = recorded.to_dict(), lens.to_dict()
    assert recorded.model == lens.model == "unified" and recorded_params.keys() == lens_params.keys()
    numbers = [k for k, v in lens_params.items() if isinstance(v, float)]
    assert [recorded_params[k] for k in numbers] == pytest.approx(
        [lens_params[k] for k in numbers], rel=1e-12
    )
    assert {k: v for k, v in recorded_params.items() if k not in numbers} == {
        k: v for k, v in lens_params.items() if k not in numbers
    }
    # The generator's rays are the lens's rays through the pixel centres.
    rays = recorded.ray_grid(torch.float64)
    expected = lens.unproject(lens.pixel_grid())
    finite = torch.isfinite(expected).all(-1)
    assert finite.float().mean() > 0.7 and torch.allclose(rays[finite], expected[finite], atol=1e-12)
    # What the ray caster rendered is what the cube faces show along those rays...
    err, agree = _remap_vs_raycast(reader, lens, sample_ids)
    assert err < 0.02 and agree > 0.85
    # ...and not what another lens (the preset's own 190-degree equidistant fisheye) would show.
    other_err, other_agree = _remap_vs_raycast(reader, ideal_camera(64, 64, fov_deg=190.0), sample_ids)
    assert other_err > 2 * err and other_agree < agree - 0.05


def test_generator_camera_options_are_checked(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"camera.calibration: .*nope.yaml: no such calibration file"):
        cli.build_config("tiny", {"camera.calibration": str(tmp_path / "nope.yaml")})
    with pytest.raises(ConfigError, match=r"unknown option camera.lens; camera options: calibration, camera"):
        cli.build_config("tiny", {"camera.lens": "x"})
    camchain = fx.write_kalibr_camchain(tmp_path / "camchain.yaml", "ds")
    with pytest.raises(ConfigError, match=r"holds 2 cameras \(cam0, cam1\); choose one with camera.camera="):
        cli.build_config("tiny", {"camera.calibration": str(camchain)})
    cfg = cli.build_config(
        "tiny", {"camera.calibration": str(camchain), "camera.camera": "cam1", "camera.size": 96}
    )
    assert cfg.fisheye_size == 96 and cfg.fisheye_camera() == load_camera(camchain, "cam1").resized(96, 96)
    # A calibrated fisheye is part of the dataset's identity; the presets keep theirs (no new key).
    assert cfg.to_dict()["fisheye_calibration"]["model"] == "double_sphere"
    assert "fisheye_calibration" not in get_preset("tiny").to_dict()
