"""The weights a task started from travel with its checkpoint; rebuilding it reads no weight file again."""

from __future__ import annotations

import hashlib

import lightning as L
import torch
import torchvision

from airfisheye_bench.tasks import CompletionTask
from airfisheye_bench.tasks.checkpoint import load_task
from tests.helpers.models import TINY


def test_checkpoint_keeps_the_initial_weights_record_without_the_file(tmp_path):
    weights = tmp_path / "resnet18.pth"
    torch.save(torchvision.models.resnet18(weights=None).state_dict(), weights)
    task = CompletionTask({"name": "nlspn", **TINY["nlspn"], "encoder_weights": str(weights)})
    record = task.hparams["weights"]["encoder_weights"]
    assert record["sha256"] == hashlib.sha256(weights.read_bytes()).hexdigest()
    trainer = L.Trainer(logger=False, enable_progress_bar=False, enable_model_summary=False)
    trainer.strategy.connect(task)
    trainer.save_checkpoint(tmp_path / "model.ckpt")
    weights.unlink()  # the checkpoint holds every weight: the encoder file is not needed any more
    loaded = load_task(tmp_path / "model.ckpt")
    assert loaded.hparams["weights"] == task.hparams["weights"]
    for (name, a), b in zip(task.state_dict().items(), loaded.state_dict().values(), strict=True):
        assert torch.equal(a, b), name


def test_checkpoint_from_before_the_weights_record_keeps_its_nlspn_defaults(tmp_path):
    # Such a checkpoint did not name confidence_sampling: it was trained with the default of its time.
    task = CompletionTask({"name": "nlspn", **TINY["nlspn"]})
    trainer = L.Trainer(logger=False, enable_progress_bar=False, enable_model_summary=False)
    trainer.strategy.connect(task)
    trainer.save_checkpoint(tmp_path / "new.ckpt")
    state = torch.load(tmp_path / "new.ckpt", weights_only=True)
    assert load_task(tmp_path / "new.ckpt").net.prop_layer.confidence_sampling == "offset"
    del state["hyper_parameters"]["weights"]
    for key in ("confidence_sampling", "preserve_input"):
        state["hyper_parameters"]["model"].pop(key, None)
    torch.save(state, tmp_path / "old.ckpt")
    old = load_task(tmp_path / "old.ckpt").net.prop_layer
    assert (old.confidence_sampling, old.preserve_input) == ("neighbour", True)
