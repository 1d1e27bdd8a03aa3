"""Initial weights: local ResNet files reach the encoders, bad files are refused, ImageNet weights come from the
library caches and fail offline with one clear message (no test touches the network)."""

from __future__ import annotations

import hashlib
import pickle
import socket
import urllib.error
from pathlib import Path

import pytest
import timm
import torch
import torchvision

import models
from models.weights import WeightsUnavailableError, pretrained_weights_disabled, read_state_dict
from tests.helpers.models import TINY


def encoder_tensors(name: str, model: torch.nn.Module) -> dict[str, torch.Tensor]:
    """The model's encoder tensors under torchvision ResNet names (``layer1.0.conv1.weight``, ...)."""
    if name == "nlspn":  # the stages only, as conv2..conv5
        stages = {"conv2": "layer1", "conv3": "layer2", "conv4": "layer3", "conv5": "layer4"}
        return {
            stages[k.split(".")[0]] + k[5:]: v
            for k, v in model.state_dict().items()
            if k.split(".")[0] in stages
        }
    encoder = model.net.encoder if name == "deeplabv3plus" else model.encoder
    return dict(encoder.state_dict())


@pytest.fixture(scope="module")
def resnet_files(tmp_path_factory) -> dict[str, tuple[Path, dict[str, torch.Tensor]]]:
    """Randomly initialised torchvision and timm ResNet18 state dicts written to files."""
    folder = tmp_path_factory.mktemp("weights")
    torch.manual_seed(7)
    files = {}
    for kind, net in (
        ("torchvision", torchvision.models.resnet18(weights=None)),
        ("timm", timm.create_model("resnet18", pretrained=False)),
    ):
        with torch.no_grad():  # non-default running statistics, so buffers are compared too
            for module in net.modules():
                if isinstance(module, torch.nn.BatchNorm2d):
                    module.running_var.uniform_(0.5, 2.0)
        state = net.state_dict()
        torch.save(state, folder / f"{kind}.pth")
        files[kind] = (folder / f"{kind}.pth", state)
    return files


@pytest.mark.parametrize("kind", ["torchvision", "timm"])
@pytest.mark.parametrize("name", sorted(TINY))
def test_local_resnet_file_reaches_the_encoder(resnet_files, name, kind):
    path, state = resnet_files[kind]
    model = models.create_model(name, encoder_weights=str(path), **TINY[name])
    loaded = encoder_tensors(name, model)
    assert len(loaded) > 50
    for key, value in loaded.items():
        assert torch.equal(value, state[key]), key
    record = model.weights_identity["encoder_weights"]
    assert record["file"] == str(path.resolve())
    assert record["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert model.weights_identity["weights_path"] is None


def test_random_init_records_no_weights():
    model = models.create_model("deeplabv3plus", **TINY["deeplabv3plus"])
    assert model.weights_identity == {"encoder_weights": None, "weights_path": None}


class Arbitrary:
    """A class a weights file must not be able to instantiate."""


@pytest.mark.parametrize("content", ["garbage", "pickled_object", "not_tensors"])
def test_bad_weights_file_is_refused_naming_it(tmp_path, content):
    path = tmp_path / f"{content}.pth"
    if content == "garbage":
        path.write_bytes(b"\x00\x01 definitely not a checkpoint")
    elif content == "pickled_object":
        path.write_bytes(pickle.dumps({"conv1.weight": Arbitrary()}, protocol=2))
    else:
        torch.save({"conv1.weight": [1, 2, 3]}, path)
    for name in sorted(TINY):
        with pytest.raises(ValueError) as err:
            models.create_model(name, encoder_weights=str(path), **TINY[name])
        message = str(err.value)
        assert str(path) in message and "encoder_weights" in message, message
        assert "weights_only" not in message, message  # never advice to disable safe loading
        assert err.value.__suppress_context__ or err.value.__cause__ is None


def test_read_state_dict_unwraps_checkpoints(tmp_path):
    state = {"a": torch.ones(2)}
    torch.save({"state_dict": state, "epoch": 3}, tmp_path / "c.ckpt")
    assert torch.equal(read_state_dict(tmp_path / "c.ckpt")["a"], state["a"])


@pytest.fixture
def offline(monkeypatch, tmp_path) -> Path:
    """Empty library caches under ``tmp_path`` and no way to reach the network."""
    from huggingface_hub import constants

    def refuse(*args, **kwargs):
        raise OSError("network disabled in tests")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(constants, "HF_HUB_CACHE", str(tmp_path / "hf"))
    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", True)

    def no_download(url, dst, *args, **kwargs):
        raise urllib.error.URLError("network disabled in tests")

    monkeypatch.setattr(torch.hub, "download_url_to_file", no_download)
    previous = torch.hub.get_dir()
    torch.hub.set_dir(str(tmp_path / "torch"))
    yield tmp_path
    torch.hub.set_dir(previous)


@pytest.mark.parametrize("name", ["deeplabv3plus", "adabins"])
def test_imagenet_offline_names_the_hugging_face_cache(offline, name):
    with pytest.raises(WeightsUnavailableError) as err:
        models.create_model(name, encoder_weights="imagenet", **TINY[name])
    message = str(err.value)
    assert str(offline / "hf") in message and "smp-hub/resnet18.imagenet" in message, message
    assert "HF_HOME" in message and "encoder_weights" in message


def test_imagenet_offline_names_the_torch_hub_file(offline):
    with pytest.raises(WeightsUnavailableError) as err:
        models.create_model("nlspn", encoder_weights="imagenet", **TINY["nlspn"])
    expected = offline / "torch" / "checkpoints" / "resnet18-f37072fd.pth"
    assert str(expected) in str(err.value) and "TORCH_HOME" in str(err.value), str(err.value)


def test_imagenet_reads_a_placed_torch_hub_file_offline(offline, resnet_files):
    """The fix the offline message gives works: a file placed in the torch hub cache is used, and recorded."""
    path, state = resnet_files["torchvision"]
    placed = offline / "torch" / "checkpoints" / "resnet18-f37072fd.pth"
    placed.parent.mkdir(parents=True)
    placed.write_bytes(path.read_bytes())
    model = models.create_model("nlspn", encoder_weights="imagenet", **TINY["nlspn"])
    assert torch.equal(model.conv3[0].conv1.weight, state["layer2.0.conv1.weight"])
    record = model.weights_identity["encoder_weights"]
    assert record["encoder_weights"] == "imagenet" and record["source"].startswith("torchvision:")
    assert record["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()


def test_disabled_pretrained_weights_fetch_nothing(offline):
    with pretrained_weights_disabled():
        for name in sorted(TINY):
            model = models.create_model(name, encoder_weights="imagenet", **TINY[name])
            assert model.weights_identity["encoder_weights"] is None


@pytest.mark.parametrize("name", ["deeplabv3plus", "adabins"])
def test_imagenet_reads_the_hugging_face_cache_offline(offline, resnet_files, name):
    """smp's ImageNet weights come from the Hugging Face cache when they are there, with no network."""
    from safetensors.torch import save_file
    from segmentation_models_pytorch.encoders import encoders

    settings = encoders["resnet18"]["pretrained_settings"]["imagenet"]
    snapshot = offline / "hf" / "models--smp-hub--resnet18.imagenet" / "snapshots" / settings["revision"]
    snapshot.mkdir(parents=True)
    _, state = resnet_files["torchvision"]
    save_file(
        {k: v.contiguous() for k, v in state.items() if not k.startswith("fc.")},
        snapshot / "model.safetensors",
    )
    (snapshot / "config.json").write_text("{}")
    model = models.create_model(name, encoder_weights="imagenet", **TINY[name])
    for key, value in encoder_tensors(name, model).items():
        assert torch.equal(value, state[key]), key
    record = model.weights_identity["encoder_weights"]
    assert record["source"] == f"hf:smp-hub/resnet18.imagenet@{settings['revision']}"
    assert record["sha256"] == hashlib.sha256((snapshot / "model.safetensors").read_bytes()).hexdigest()
