"""Segmentation models: the shared model tests plus smp-specific behaviour."""

from __future__ import annotations

from typing import ClassVar

import pytest
import torch

import models
from tests.helpers.model_tester import BaseModelTester


class TestDeepLabV3Plus(BaseModelTester):
    model_name = "deeplabv3plus"
    task = "seg"
    model_kwargs: ClassVar[dict] = {"encoder_name": "resnet18", "num_classes": 5, "decoder_channels": 32}
    input_sizes = ((64, 64), (64, 96), (96, 48))
    output_stride = 16
    paper_kwargs: ClassVar[dict] = {"num_classes": 13}


class TestSmpGeneric(BaseModelTester):
    model_name = "smp"
    task = "seg"
    model_kwargs: ClassVar[dict] = {
        "arch": "fpn",
        "encoder_name": "resnet18",
        "num_classes": 3,
        "decoder_segmentation_channels": 32,
        "decoder_pyramid_channels": 32,
    }
    input_sizes = ((64, 64), (64, 128))
    output_stride = 32


class TestDeepLabV3PlusRays(TestDeepLabV3Plus):
    """The ray map at the encoder's input and at the decoder's fusion of the ASPP and stride-4 features."""

    model_kwargs: ClassVar[dict] = {**TestDeepLabV3Plus.model_kwargs, "camera_input": "rays"}
    paper_kwargs = None


class TestSmpGenericRays(TestSmpGeneric):
    """Any other smp architecture: the ray map at the encoder's input."""

    model_kwargs: ClassVar[dict] = {**TestSmpGeneric.model_kwargs, "camera_input": "rays"}


def test_deeplabv3plus_paper_defaults():
    net = models.create_model("deeplabv3plus")
    assert net.arch == "deeplabv3plus"
    assert net.output_stride == 16
    assert net.num_classes == 13
    assert type(net.net.encoder).__name__ == "ResNetEncoder"
    assert net.net.encoder.out_channels[-1] == 2048  # ResNet50 (ResNet18/34 end with 512)
    # smp's DeepLabV3+ with 13 classes and ResNet50 (torchvision ResNet50 without fc: 23.5M) is ~26.7M params.
    n_params = sum(p.numel() for p in net.parameters())
    assert 25e6 < n_params < 28e6, n_params


def test_unknown_arch_lists_choices():
    with pytest.raises(ValueError, match="deeplabv3plus"):
        models.create_model("smp", arch="not-an-arch")


def test_weights_path_round_trip(tmp_path):
    kwargs = {"encoder_name": "resnet18", "num_classes": 4, "decoder_channels": 32}
    source = models.create_model("deeplabv3plus", **kwargs)
    # A Lightning-style checkpoint whose keys carry the task module's attribute prefix.
    torch.save({"state_dict": {f"model.{k}": v for k, v in source.state_dict().items()}}, tmp_path / "w.ckpt")
    torch.manual_seed(123)
    loaded = models.create_model("deeplabv3plus", weights_path=tmp_path / "w.ckpt", **kwargs)
    for (name, a), b in zip(source.state_dict().items(), loaded.state_dict().values(), strict=True):
        assert torch.equal(a, b), name


def test_encoder_weights_file_accepts_torchvision_resnet(tmp_path):
    import torchvision

    resnet = torchvision.models.resnet18(weights=None)  # random weights; the fc.* keys must be dropped
    torch.save(resnet.state_dict(), tmp_path / "resnet18.pth")
    net = models.create_model(
        "deeplabv3plus",
        encoder_name="resnet18",
        num_classes=4,
        encoder_weights=str(tmp_path / "resnet18.pth"),
    )
    assert torch.equal(net.net.encoder.conv1.weight, resnet.conv1.weight)
    assert torch.equal(net.net.encoder.layer4[1].bn2.running_var, resnet.layer4[1].bn2.running_var)


def test_missing_weights_file_raises(tmp_path):
    with pytest.raises(ValueError, match="weights_path"):
        models.create_model("deeplabv3plus", encoder_name="resnet18", weights_path=tmp_path / "nope.pt")
