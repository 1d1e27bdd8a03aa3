"""ONNX export helpers: names, metadata, dynamic batch, atomic writes, parity reporting and errors."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from airfisheye_bench.export import OnnxParityError, export_onnx, verify_onnx
from airfisheye_bench.runs.deployment import read_onnx_metadata

pytestmark = pytest.mark.integration  # ONNX exports: seconds each


class TwoInputNet(nn.Module):
    """A miniature completion-style model: image + sparse depth -> depth."""

    def __init__(self) -> None:
        super().__init__()
        self.rgb = nn.Conv2d(3, 4, 3, padding=1)
        self.dep = nn.Conv2d(1, 4, 3, padding=1)
        self.head = nn.Conv2d(4, 1, 1)

    def forward(self, image: torch.Tensor, sparse_depth: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.head(torch.relu(self.rgb(image) + self.dep(sparse_depth)))) + 1.0


def _inputs(batch, h=16, w=24, seed=0):
    g = torch.Generator().manual_seed(seed)
    return {
        "image": torch.randn(batch, 3, h, w, generator=g),
        "sparse_depth": torch.rand(batch, 1, h, w, generator=g),
    }


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    torch.manual_seed(0)
    net = TwoInputNet().eval()
    path = export_onnx(
        net,
        _inputs(2),
        tmp_path_factory.mktemp("onnx") / "sub" / "net.onnx",
        output_name="depth",
        metadata={"task": "completion", "max_depth": "120"},
    )
    return net, path


def test_names_metadata_and_single_file(exported):
    import onnx

    _, path = exported
    model = onnx.load(str(path))
    assert [i.name for i in model.graph.input] == ["image", "sparse_depth"]
    assert [o.name for o in model.graph.output] == ["depth"]
    assert read_onnx_metadata(path) == {"task": "completion", "max_depth": "120"}
    assert sorted(p.name for p in path.parent.iterdir()) == ["net.onnx"]  # no external data, no temporaries


@pytest.mark.parametrize("batch", [1, 2, 5])
def test_dynamic_batch_parity(exported, batch):
    net, path = exported
    report = verify_onnx(path, net, _inputs(batch, seed=batch), atol=1e-5, rtol=1e-5)
    assert report.output_shape == (batch, 1, 16, 24)
    assert report.max_abs_diff <= 1e-5
    assert report.ort_ms > 0 and report.torch_ms > 0
    assert report.latency_ratio == pytest.approx(report.ort_ms / report.torch_ms)


def test_static_spatial_size_is_enforced(exported):
    net, path = exported
    with pytest.raises(Exception, match=r"(?i)dimension|shape"):
        verify_onnx(path, net, _inputs(2, h=32), measure_latency=False)


def test_parity_error_reports_differences(exported):
    _, path = exported
    torch.manual_seed(1)
    other = TwoInputNet().eval()  # different weights
    with pytest.raises(OnnxParityError, match="max abs diff"):
        verify_onnx(path, other, _inputs(2), measure_latency=False)


def test_verify_rejects_wrong_input_names(exported):
    net, path = exported
    with pytest.raises(ValueError, match="sparse_depth"):
        verify_onnx(path, net, {"image": _inputs(2)["image"]}, measure_latency=False)


def test_export_rejects_bad_arguments(tmp_path):
    net = TwoInputNet()
    with pytest.raises(ValueError, match="batch size 1"):
        export_onnx(net, _inputs(1), tmp_path / "a.onnx", output_name="depth")
    with pytest.raises(ValueError, match="forward"):
        export_onnx(net, {"rgb": torch.zeros(2, 3, 8, 8)}, tmp_path / "a.onnx", output_name="depth")
    with pytest.raises(ValueError, match="metadata"):
        export_onnx(net, _inputs(2), tmp_path / "a.onnx", output_name="depth", metadata={"n": 3})
    with pytest.raises(ValueError, match="one batch size"):
        bad = _inputs(2)
        bad["sparse_depth"] = bad["sparse_depth"][:1]
        export_onnx(net, bad, tmp_path / "a.onnx", output_name="depth")
    assert not list(tmp_path.iterdir())


def test_failed_write_keeps_previous_file(tmp_path, monkeypatch):
    target = tmp_path / "net.onnx"
    target.write_bytes(b"previous")

    def save_half_then_fail(self, destination, **kwargs):
        with open(destination, "wb") as f:
            f.write(b"half-written")
        raise OSError("disk full")

    monkeypatch.setattr(torch.onnx.ONNXProgram, "save", save_half_then_fail)
    with pytest.raises(OSError, match="disk full"):
        export_onnx(TwoInputNet(), _inputs(2), target, output_name="depth")
    assert target.read_bytes() == b"previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["net.onnx"]  # the temporary is removed


def test_training_flag_is_restored(tmp_path):
    net = TwoInputNet().train()
    export_onnx(net, _inputs(2), tmp_path / "n.onnx", output_name="depth", dynamic_batch=False)
    assert net.training
