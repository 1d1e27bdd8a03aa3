"""Flip test-time augmentation: the prediction is the mean of the model output and the mirrored output of the
mirrored input, for every task, and the evaluation records it."""

from __future__ import annotations

import pytest
import torch

from airfisheye_bench.evaluation.predictors import CheckpointPredictor, check_tta, flip_tta
from airfisheye_bench.tasks import CompletionTask, DepthTask, SegmentationTask
from tests.helpers.models import TINY


def make_task(task: str):
    torch.manual_seed(0)
    if task == "seg":
        return SegmentationTask(
            {"name": "deeplabv3plus", **TINY["deeplabv3plus"]}, class_names=["a", "b", "c"]
        )
    if task == "depth":
        return DepthTask({"name": "adabins", **TINY["adabins"]})
    return CompletionTask({"name": "nlspn", **TINY["nlspn"]})


def make_batch(task: str, size: int = 32) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(1)
    batch = {"image": torch.randn(2, 3, size, size, generator=g)}
    if task == "completion":
        batch["sparse_depth"] = (
            50 * torch.rand(2, 1, size, size, generator=g) * (torch.rand(2, 1, size, size) < 0.1)
        )
    return batch


@pytest.mark.parametrize("task", ["seg", "depth", "completion"])
def test_flip_tta_is_the_mean_of_the_two_predictions(task):
    module = make_task(task).eval()
    batch = make_batch(task)
    inputs = module.model_inputs(batch)
    with torch.no_grad():
        plain = module(*inputs)
        mirrored = module(*(t.flip(-1) for t in inputs)).flip(-1)
    assert not torch.allclose(plain, mirrored)  # the model is not symmetric, so TTA changes the prediction
    mean = 0.5 * (plain + mirrored)
    predicted = CheckpointPredictor(module, tta="flip")(batch)
    if task == "seg":  # the labels of the mean logits
        assert torch.equal(predicted, mean.argmax(1))
    else:
        torch.testing.assert_close(predicted, mean)
    assert torch.equal(CheckpointPredictor(module)(batch), plain.argmax(1) if task == "seg" else plain)


def test_flip_tta_mirrors_every_input():
    seen = []

    def run(inputs):
        seen.append([t.clone() for t in inputs])
        return inputs[0] + inputs[1]

    a, b = torch.randn(1, 1, 2, 5), torch.randn(1, 1, 2, 5)
    out = flip_tta(run, [a, b])
    assert torch.equal(seen[0][0], a.flip(-1)) and torch.equal(seen[0][1], b.flip(-1))
    torch.testing.assert_close(out, a + b)  # an equivariant model is unchanged by flip TTA


def test_tta_identity_and_bad_value():
    module = make_task("depth")
    assert CheckpointPredictor(module, tta="flip").identity()["tta"] == "flip"
    assert CheckpointPredictor(module).identity()["tta"] is None
    with pytest.raises(ValueError, match="tta must be null or 'flip'"):
        check_tta("hflip")
