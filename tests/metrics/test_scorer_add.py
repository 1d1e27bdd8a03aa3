"""``TaskScorer.add``: the scores of a run on several sources pool by adding the sources' metric states."""

from __future__ import annotations

import math

import pytest
import torch

from airfisheye_bench.metrics import DEFAULT_DEPTH_EDGES_M, DEFAULT_RING_EDGES_DEG
from airfisheye_bench.metrics.scorer import TaskScorer
from airfisheye_bench.specs import get_task


def _batch(task: str, generator: torch.Generator, n: int = 4, size: int = 24):
    if task == "seg":
        pred = torch.randint(0, 5, (n, size, size), generator=generator)
        target = torch.randint(0, 5, (n, size, size), generator=generator)
        target[:, :2] = 255  # ignored pixels
    else:
        target = torch.rand(n, 1, size, size, generator=generator) * 100
        target[..., :3, :] = 0  # invalid ground truth
        pred = target * (1 + 0.2 * torch.randn(n, 1, size, size, generator=generator)).clamp(min=0.1)
    mask = torch.rand(n, size, size, generator=generator) > 0.1
    return pred, target, mask


@pytest.mark.parametrize("task", ["seg", "depth", "completion"])
def test_added_sources_score_as_one_scorer_of_all_frames(task: str) -> None:
    spec = get_task(task)
    options = {"class_names": ["a", "b", "c", "d", "e"]} if spec.uses_classes else {}
    edges = DEFAULT_DEPTH_EDGES_M if spec.depth_breakdown else None

    def scorer() -> TaskScorer:
        return TaskScorer(lambda: spec.make_metric(**options), DEFAULT_RING_EDGES_DEG, edges)

    generator = torch.Generator().manual_seed(1)
    theta_a = torch.linspace(0, 95, 24 * 24).view(24, 24)
    theta_b = theta_a.flip(0)  # the other source's lens: other angles at the same pixels
    whole, a, b, pooled = scorer(), scorer(), scorer(), scorer()
    assert pooled.can_add()
    for _ in range(3):
        for part, theta in ((a, theta_a), (b, theta_b)):
            pred, target, mask = _batch(task, generator)
            part.update(pred, target, theta=theta, mask=mask)
            whole.update(pred, target, theta=theta, mask=mask)
    pooled.add(a)
    pooled.add(b)
    expected, got = whole.compute(), pooled.compute()
    assert a.compute() != got  # a source's own scores are not the pooled ones
    for group in ("metrics", "breakdown"):
        assert expected[group].keys() == got[group].keys()
        for key, value in expected[group].items():
            assert got[group][key] == pytest.approx(value, rel=1e-6, abs=1e-9) or (
                math.isnan(value) and math.isnan(got[group][key])
            ), key
