"""``airfisheye-export`` of a camera-aware model (``model.camera_input=rays``): the ONNX file takes the ray map as a
second named input ``rays``, or, with ``bake_camera=true``, holds the data's camera's map as a constant and takes the
image alone; both match PyTorch in ONNX Runtime, and the metadata says which."""

from __future__ import annotations

import json
from pathlib import Path

import onnx
import onnxruntime as ort
import pytest
import torch
from omegaconf import OmegaConf

from airfisheye_bench.cli import export as export_command
from airfisheye_bench.export import verify_onnx
from airfisheye_bench.export.camera import BakedRays
from airfisheye_bench.runs.deployment import (
    KEY_CAMERA_INPUT,
    KEY_RAYS_BAKED,
    read_deployment_metadata,
    read_onnx_metadata,
)
from airfisheye_bench.tasks.checkpoint import load_task
from datamodules.config import instantiate_datamodule
from tests.helpers.commands import exit_status
from tests.helpers.model_tester import fisheye_rays

pytestmark = pytest.mark.integration  # trains and exports: seconds per test

SIZE = 64  # the shared runs' size


@pytest.fixture(scope="module")
def depth_rays(tiny_rays_runs) -> Path:
    return tiny_rays_runs("depth")


@pytest.fixture(scope="module")
def exports(tiny_rays_exports) -> dict[str, Path]:
    """The session's exports of the camera-aware depth run: ``input`` (rays an input, int8 too) and ``baked``."""
    paths = {}
    for kind, baked in (("input", False), ("baked", True)):
        path, code, printed = tiny_rays_exports("depth", baked)
        assert code == 0, printed
        assert ": OK" in printed  # the parity verdict
        paths[kind] = path
    inputs_line = "inputs ['image', 'rays'] -> depth"
    assert inputs_line in tiny_rays_exports("depth")[2] and "int8 (dynamic)" in tiny_rays_exports("depth")[2]
    assert "inputs ['image'] (ray map baked in) -> depth" in tiny_rays_exports("depth", True)[2]
    return paths


def _frames(run: Path) -> tuple[dict[str, torch.Tensor], torch.Tensor]:
    """Two validation frames of the run's data with their ray maps, and the data's camera's ray map."""
    datamodule = instantiate_datamodule(OmegaConf.load(run / "config.yaml").data, "validate")
    batch = next(iter(datamodule.val_dataloader()))
    return {"image": batch["image"][:2], "rays": batch["rays"][:2]}, datamodule.ray_map()


def test_the_ray_map_is_a_second_named_input(exports: dict[str, Path], depth_rays: Path) -> None:
    graph = onnx.load(str(exports["input"]), load_external_data=False).graph
    assert [i.name for i in graph.input] == ["image", "rays"]
    dims = graph.input[1].type.tensor_type.shape.dim
    assert dims[0].dim_param and [d.dim_value for d in dims[1:]] == [4, SIZE, SIZE]
    meta = read_deployment_metadata(exports["input"])
    assert meta["camera_input"] == "rays" and meta["rays_baked"] is False
    assert meta["inputs"] == ["image", "rays"] and meta["model_config"]["camera_input"] == "rays"
    assert read_onnx_metadata(exports["input"].with_name("depth.int8.onnx"))[KEY_CAMERA_INPUT] == "rays"
    net = load_task(depth_rays).net
    inputs, _ = _frames(depth_rays)
    for batch in (1, 3):  # any batch, any ray map: the file computes what PyTorch does
        image = torch.randn(batch, 3, SIZE, SIZE, generator=torch.Generator().manual_seed(batch))
        feed = {"image": image, "rays": fisheye_rays(batch, (SIZE, SIZE))}
        verify_onnx(exports["input"], net, feed, atol=1e-4, rtol=1e-3, measure_latency=False)
    verify_onnx(exports["input"], net, inputs, atol=1e-4, rtol=1e-3, measure_latency=False)


def test_a_baked_camera_takes_the_image_alone(exports: dict[str, Path], depth_rays: Path) -> None:
    graph = onnx.load(str(exports["baked"]), load_external_data=False).graph
    assert [i.name for i in graph.input] == ["image"]
    props = read_onnx_metadata(exports["baked"])
    assert props[KEY_CAMERA_INPUT] == "rays" and json.loads(props[KEY_RAYS_BAKED]) is True
    assert read_deployment_metadata(exports["baked"])["inputs"] == ["image"]
    inputs, camera_rays = _frames(depth_rays)
    net = load_task(depth_rays).net
    verify_onnx(
        exports["baked"],
        BakedRays(net, camera_rays),
        {"image": inputs["image"]},
        atol=1e-4,
        rtol=1e-3,
        measure_latency=False,
    )
    # The constant is the served camera's map: the baked file gives what the other gives with the frames' rays.
    baked = ort.InferenceSession(str(exports["baked"]), providers=["CPUExecutionProvider"])
    given = ort.InferenceSession(str(exports["input"]), providers=["CPUExecutionProvider"])
    feed = {k: v.numpy() for k, v in inputs.items()}
    torch.testing.assert_close(
        torch.from_numpy(baked.run(None, {"image": feed["image"]})[0]),
        torch.from_numpy(given.run(None, feed)[0]),
        atol=1e-4,
        rtol=1e-4,
    )


def test_baking_what_cannot_be_baked_is_refused(tiny_runs, depth_rays: Path, tmp_path: Path, capsys) -> None:
    cases = [
        ([f"ckpt_path={tiny_runs('depth')}", "bake_camera=true"], "this model takes none"),
        (
            [f"ckpt_path={depth_rays}", "bake_camera=true", "dynamic_spatial=true"],
            "drop dynamic_spatial=true",
        ),
    ]
    for args, message in cases:
        assert exit_status(export_command, [*args, f"out={tmp_path / 'x.onnx'}"]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []
