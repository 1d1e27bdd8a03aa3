"""Optimiser set-up of the tasks: parameter groups with their own learning rates, scaled schedules."""

from __future__ import annotations

from functools import partial
from unittest.mock import PropertyMock, patch

import pytest
import torch

from airfisheye_bench.tasks import DepthTask
from tests.helpers.models import TINY

LR = 3.57e-4


def adabins_task(**kwargs) -> DepthTask:
    return DepthTask(
        {"name": "adabins", **TINY["adabins"]},
        optimizer=partial(torch.optim.AdamW, lr=LR, weight_decay=0.1),
        scheduler_interval="step",
        **kwargs,
    )


def ids(params) -> set[int]:
    return {id(p) for p in params}


def test_adabins_encoder_trains_at_a_tenth_of_the_lr_through_the_one_cycle():
    schedule = partial(
        torch.optim.lr_scheduler.OneCycleLR, max_lr=LR, div_factor=25, final_div_factor=100, total_steps=20
    )
    task = adabins_task(scheduler=schedule, lr_multipliers={"encoder": 0.1})
    config = task.configure_optimizers()
    optimizer, scheduler = config["optimizer"], config["lr_scheduler"]["scheduler"]
    groups = {g["name"]: g for g in optimizer.param_groups}
    assert set(groups) == {"encoder", "default"}
    # The groups are upstream's get_1x_lr_params (encoder) and get_10x_lr_params (everything else).
    assert ids(groups["encoder"]["params"]) == ids(task.net.get_1x_lr_params())
    assert ids(groups["default"]["params"]) == ids(task.net.get_10x_lr_params())
    assert groups["encoder"]["max_lr"] == pytest.approx(LR / 10)
    assert groups["default"]["max_lr"] == pytest.approx(LR)
    lrs = []
    for _ in range(20):
        lrs.append((groups["encoder"]["lr"], groups["default"]["lr"]))
        optimizer.step()
        scheduler.step()
    assert lrs[0][1] == pytest.approx(LR / 25)  # div_factor
    assert max(d for _, d in lrs) == pytest.approx(LR, rel=1e-3)
    assert lrs[-1][1] == pytest.approx(LR / 25 / 100, rel=1e-2)  # final_div_factor
    for encoder_lr, default_lr in lrs:
        assert encoder_lr == pytest.approx(default_lr / 10)


def test_without_multipliers_one_group_at_the_lr():
    task = adabins_task()
    optimizer = task.configure_optimizers()
    assert len(optimizer.param_groups) == 1 and optimizer.param_groups[0]["lr"] == LR
    assert ids(optimizer.param_groups[0]["params"]) == ids(task.net.parameters())


def test_unknown_multiplier_names_the_submodules():
    task = adabins_task(lr_multipliers={"backbone": 0.1})
    with pytest.raises(ValueError, match=r"backbone.*encoder"):
        task.configure_optimizers()


def test_the_most_specific_multiplier_wins():
    task = adabins_task(lr_multipliers={"encoder": 0.1, "encoder.layer4": 0.5})
    optimizer = task.configure_optimizers()  # no scheduler: the optimizer itself
    groups = {g["name"]: g for g in optimizer.param_groups}
    assert ids(groups["encoder.layer4"]["params"]) == ids(task.net.encoder.layer4.parameters())
    assert groups["encoder.layer4"]["lr"] == pytest.approx(0.5 * LR)
    assert ids(groups["encoder"]["params"]) == ids(task.net.get_1x_lr_params()) - ids(
        task.net.encoder.layer4.parameters()
    )


def test_warmup_scales_each_first_epoch_step_like_upstream_nlspn():
    """Upstream NLSPN (src/main.py): ``lr = initial_lr * warm_up_cnt / (len(loader_train) + 1)`` in epoch 1."""
    schedule = partial(torch.optim.lr_scheduler.MultiStepLR, milestones=[1], gamma=0.2)
    task = adabins_task(scheduler=schedule, lr_multipliers={"encoder": 0.1}, warmup_epochs=1)
    config = task.configure_optimizers()
    optimizer, scheduler = config["optimizer"], config["lr_scheduler"]["scheduler"]
    seen: list[list[float]] = []
    optimizer.register_step_pre_hook(
        lambda opt, args, kwargs: seen.append([g["lr"] for g in opt.param_groups])
    )
    batches = 4
    with patch.object(type(task), "trainer", new_callable=PropertyMock) as trainer:
        trainer.return_value.num_training_batches = batches
        for epoch, gamma in ((0, 1.0), (1, 0.2)):
            for batch_idx in range(batches):
                task.optimizer_step(epoch, batch_idx, optimizer, optimizer_closure=None)
                # The step alone is scaled: the groups (and so checkpoints and the scheduler) keep the schedule.
                assert [g["lr"] for g in optimizer.param_groups] == pytest.approx(
                    [LR / 10 * gamma, LR * gamma]
                )
            scheduler.step()
    for batch_idx in range(batches):
        factor = (batch_idx + 1) / (batches + 1)
        assert seen[batch_idx] == pytest.approx([LR / 10 * factor, LR * factor])
    for step in seen[batches:]:  # warmed up: the schedule as it is (x0.2 after the milestone)
        assert step == pytest.approx([LR / 10 * 0.2, LR * 0.2])


def test_warmup_epochs_must_be_a_whole_number():
    with pytest.raises(ValueError, match="warmup_epochs"):
        adabins_task(warmup_epochs=0.5)
