"""Each task's loss is chosen by config (``task.module.loss``), recorded in the checkpoint, and rebuilt from it; old
checkpoints and run configs, which named the loss's settings as task arguments, still build the same loss."""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from pathlib import Path

import hydra
import lightning as L
import pytest
import torch
from omegaconf import DictConfig, OmegaConf, open_dict
from torch import Tensor, nn

import models.registry
from airfisheye_bench.cli.overrides import MOVED_KEYS, check_overrides
from airfisheye_bench.config_checks import check_train_config
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.runs import check_resume, config_differences, resume_config
from airfisheye_bench.tasks import CompletionTask, DepthTask, SegmentationTask
from airfisheye_bench.tasks.checkpoint import load_task
from airfisheye_bench.training import train
from models.losses import AdaBinsLoss, L1L2Loss, SegmentationCELoss, SILogLoss
from tests.helpers.configs import compose_train
from tests.helpers.models import TINY
from tests.helpers.runs import tiny_run_overrides

#: The loss each task's module built before losses were chosen by config, from the task arguments of its
#: ``configs/task/<task>.yaml`` at that time.
OLD_LOSSES = {
    "seg": lambda: SegmentationCELoss(ignore_index=255),
    "depth": lambda: AdaBinsLoss(
        w_chamfer=0.0, min_depth=1e-3, max_depth=120.0, chamfer_reference_range=None
    ),
    "completion": lambda: L1L2Loss(max_depth=120.0, l1_weight=1.0, l2_weight=1.0),
}


class BinlessDepthNet(nn.Module):
    """A depth model without bins (only ``"depth"`` in ``forward_with_aux``), in the zoo's calling convention."""

    def __init__(self) -> None:
        super().__init__()
        self.conv = nn.Conv2d(3, 1, 3, padding=1)

    def forward_with_aux(self, image: Tensor) -> dict[str, Tensor]:
        return {"depth": nn.functional.softplus(self.conv(image)) * 10.0 + 0.1}

    def forward(self, image: Tensor) -> Tensor:
        return self.forward_with_aux(image)["depth"]


@pytest.fixture
def binless_depth(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """``binless_depth`` registered as a depth model for one test: what a new model's folder adds."""
    monkeypatch.setattr(models.registry, "_MODELS", dict(models.registry._MODELS))
    monkeypatch.setattr(models.registry, "_MODEL_TASKS", dict(models.registry._MODEL_TASKS))
    models.registry.register_model("binless_depth", task="depth")(BinlessDepthNet)
    yield "binless_depth"


def _module(task: str, overrides: list[str] = (), **extra):
    """The task module of ``task=<task>`` as training builds it (the tiny model of the task)."""
    cfg = compose_train([f"task={task}", *overrides])
    model = {"name": cfg.model.name, **TINY[cfg.model.name]}
    if task == "seg":
        extra["class_names"] = ["a", "b", "c"]
    return hydra.utils.instantiate(cfg.task.module, model=model, **extra, _convert_="partial")


def _batch(task: str) -> dict[str, Tensor]:
    g = torch.Generator().manual_seed(0)
    depth = torch.rand(2, 1, 64, 64, generator=g) * 100
    depth[:, :, :8] = 0  # no ground truth
    batch = {"image": torch.randn(2, 3, 64, 64, generator=g), "depth": depth, "valid_mask": depth > 0}
    if task == "seg":
        batch["label"] = torch.randint(0, 3, (2, 64, 64), generator=g)
        batch["label"][:, :8] = 255
    if task == "completion":
        batch["sparse_depth"] = depth * (torch.rand(depth.shape, generator=g) < 0.05)
    return batch


@pytest.mark.parametrize("task", ["seg", "depth", "completion"])
def test_each_task_config_states_the_loss_it_trained_with_before(task: str) -> None:
    module = _module(task)
    assert type(module.loss) is type(OLD_LOSSES[task]())
    batch = _batch(task)
    with torch.no_grad():
        outputs = module.net.forward_with_aux(*module.model_inputs(batch))
        terms = module.loss_terms(outputs, batch)
        old = OLD_LOSSES[task]()
        if task == "seg":
            expected = {"loss": old(outputs["logits"], batch["label"])}
        elif task == "depth":
            expected = old.terms(outputs, batch["depth"])
        else:
            expected = old.terms(outputs["depth"], batch["depth"])
    assert terms.keys() == expected.keys()
    for key, value in expected.items():
        torch.testing.assert_close(terms[key], value, rtol=0, atol=0)


def test_the_paper_recipe_keeps_upstreams_chamfer_weight() -> None:
    cfg = compose_train(["experiment=paper/depth"])
    assert (
        cfg.task.module.loss.w_chamfer == 0.1 and cfg.task.module.loss._target_ == "models.losses.AdaBinsLoss"
    )


def test_another_loss_is_one_group_option() -> None:
    module = _module("depth", ["loss=silog", "task.module.loss.lambd=1.0"])
    assert isinstance(module.loss, SILogLoss) and module.loss.lambd == 1.0
    assert module.hparams["loss"] == {
        "_target_": "models.losses.SILogLoss",
        "lambd": 1.0,
        "min_depth": 1e-3,
        "max_depth": 120.0,
    }
    with pytest.raises(
        ConfigError, match=r"task.module.loss.w_chamfer: models.losses.SILogLoss takes no argument"
    ):
        check_train_config(compose_train(["experiment=paper/depth", "loss=silog"]))  # AdaBins' settings
    with pytest.raises(ConfigError, match=r"task.module.loss._target_=models.losses.Nope: no such class"):
        check_train_config(compose_train(["task=depth", "task.module.loss._target_=models.losses.Nope"]))


@pytest.mark.integration
@pytest.mark.parametrize("loss", ["adabins", "silog"])
def test_a_depth_model_without_bins_trains_with_its_config_loss(
    binless_depth: str, loss: str, tiny_dataset: Path, tmp_path: Path
) -> None:
    """A new depth model adds only its folder (registered here) and its config (``model``); the task's code and
    the depth task config are untouched (``loss=adabins`` is its default), and the run's checkpoint rebuilds the
    loss it trained with."""
    cfg = compose_train([*tiny_run_overrides("depth", tiny_dataset), f"loss={loss}"])
    with open_dict(cfg):
        cfg.model = {"name": binless_depth}  # what configs/model/binless_depth.yaml would hold
        cfg.paths.output_dir = str(tmp_path / "run")
    returned = train(cfg)
    assert torch.isfinite(torch.tensor(returned["metrics"]["rmse"]))
    module = load_task(tmp_path / "run")
    expected = OmegaConf.to_container(cfg.task.module.loss, resolve=True)
    expected.pop("_partial_")
    assert module.hparams["loss"] == expected
    assert type(module.loss) is {"adabins": AdaBinsLoss, "silog": SILogLoss}[loss]
    batch = _batch("depth")
    assert torch.isfinite(module.loss_terms(module.net.forward_with_aux(batch["image"]), batch)["loss"])


def _saved(task: L.LightningModule, path: Path) -> dict:
    trainer = L.Trainer(logger=False, enable_progress_bar=False, enable_model_summary=False)
    trainer.strategy.connect(task)
    trainer.save_checkpoint(path)
    return torch.load(path, weights_only=True)


def test_an_old_depth_checkpoint_rebuilds_its_loss(tmp_path: Path) -> None:
    """A checkpoint written before ``loss`` existed holds ``w_chamfer`` and ``chamfer_reference_range`` among the
    task's hyperparameters, and no ``loss``."""
    state = _saved(DepthTask({"name": "adabins", **TINY["adabins"]}, max_depth=80.0), tmp_path / "new.ckpt")
    hparams = state["hyper_parameters"]
    del hparams["loss"]
    hparams |= {"w_chamfer": 0.3, "chamfer_reference_range": 10.0}
    torch.save(state, tmp_path / "old.ckpt")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)  # nothing the user could change
        module = load_task(tmp_path / "old.ckpt")
    assert isinstance(module.loss, AdaBinsLoss) and module.loss.w_chamfer == 0.3
    assert module.loss.silog.max_depth == 80.0 and module.loss.chamfer.scale == pytest.approx(
        (10.0 / 80.0) ** 2
    )
    assert module.hparams["loss"]["w_chamfer"] == 0.3 and "w_chamfer" not in module.hparams
    edges = torch.linspace(0, 80, 9).expand(2, 9)
    batch = _batch("depth")
    outputs = {"depth": batch["depth"] + 1.0, "bin_edges": edges}
    old = AdaBinsLoss(w_chamfer=0.3, max_depth=80.0, chamfer_reference_range=10.0).terms(
        outputs, batch["depth"]
    )
    terms = module.loss_terms(outputs, batch)
    assert terms.keys() == old.keys()
    for key, value in old.items():
        torch.testing.assert_close(terms[key], value, rtol=0, atol=0)


def test_old_completion_and_seg_checkpoints_rebuild_their_losses(tmp_path: Path) -> None:
    state = _saved(CompletionTask({"name": "nlspn", **TINY["nlspn"]}), tmp_path / "c.ckpt")
    del state["hyper_parameters"]["loss"]
    state["hyper_parameters"] |= {"l1_weight": 1.0, "l2_weight": 0.25}
    torch.save(state, tmp_path / "c.ckpt")
    loss = load_task(tmp_path / "c.ckpt").loss
    assert isinstance(loss, L1L2Loss) and (loss.l1_weight, loss.l2_weight, loss.max_depth) == (
        1.0,
        0.25,
        120.0,
    )
    seg = SegmentationTask(
        {"name": "deeplabv3plus", **TINY["deeplabv3plus"]}, ["a", "b", "c"], ignore_index=254
    )
    state = _saved(seg, tmp_path / "s.ckpt")
    del state["hyper_parameters"]["loss"]  # the seg task had no loss arguments: its default rebuilds it
    torch.save(state, tmp_path / "s.ckpt")
    loss = load_task(tmp_path / "s.ckpt").loss
    assert isinstance(loss, SegmentationCELoss) and loss.ignore_index == 254


def _old_run(tmp_path: Path) -> DictConfig:
    """A depth run directory whose ``config.yaml`` was written before ``task.module.loss``: the loss's settings
    among the task's arguments."""
    run = compose_train(["task=depth"])
    with open_dict(run):
        run.paths.output_dir = str(tmp_path)
        del run.task.module.loss
        run.task.module.w_chamfer = 0.0
        run.task.module.chamfer_reference_range = None
    check_resume(run, tmp_path, write=True)
    return run


def _resumed(tmp_path: Path, overrides: list[str]) -> DictConfig:
    composed = compose_train(["ckpt_path=last", *overrides])
    with open_dict(composed):
        composed.paths.output_dir = str(tmp_path)
    return resume_config(composed, ["ckpt_path=last", *overrides])


def test_an_old_run_resumes_with_the_same_loss(tmp_path: Path) -> None:
    """A resume builds the task from the run's own ``config.yaml``: its old task arguments still build the loss
    (with a DeprecationWarning for a library caller), and nothing counts as changed."""
    run = _old_run(tmp_path)
    resumed = _resumed(tmp_path, [])
    assert config_differences(run, resumed) == []
    model = {"name": "adabins", **TINY["adabins"]}
    with pytest.warns(DeprecationWarning, match=r"DepthTask\(chamfer_reference_range=..., w_chamfer=...\)"):
        module = hydra.utils.instantiate(resumed.task.module, model=model, _convert_="partial")
    expected = _module("depth").hparams["loss"]
    assert module.hparams["loss"] == {k: v for k, v in expected.items() if k != "lambd"}  # lambd: the default
    assert "w_chamfer" not in module.hparams


def test_a_resume_cannot_change_the_loss(tmp_path: Path) -> None:
    _old_run(tmp_path)
    with pytest.raises(ConfigError, match=r"cannot change task.module.loss"):
        check_resume(_resumed(tmp_path, ["loss=silog"]), tmp_path, write=False)


def test_loss_arguments_are_checked() -> None:
    model = {"name": "adabins", **TINY["adabins"]}
    with pytest.raises(ValueError, match=r"give them in loss \(task.module.loss.w_chamfer\)"):
        DepthTask(model, w_chamfer=0.1, loss={"_target_": "models.losses.SILogLoss"})
    with pytest.raises(TypeError, match="unexpected keyword argument 'l2_weight'"):
        DepthTask(model, l2_weight=1.0)
    with pytest.raises(ValueError, match="_target_"):
        DepthTask(model, loss={"lambd": 1.0})
    with pytest.raises(ValueError, match=r"not a torch\.nn\.Module"):
        DepthTask(model, loss={"_target_": "builtins.dict"})
    seg = {"name": "deeplabv3plus", **TINY["deeplabv3plus"]}
    with pytest.raises(ValueError, match="the loss ignores label 255 but the task ignores 254"):
        SegmentationTask(
            seg, ["a", "b", "c"], ignore_index=254, loss={"_target_": "models.losses.SegmentationCELoss"}
        )


def test_a_loss_module_is_used_but_not_recorded() -> None:
    loss = SILogLoss(lambd=0.5)
    module = DepthTask({"name": "adabins", **TINY["adabins"]}, loss=loss)
    assert module.loss is loss and module.hparams["loss"] is None


def test_a_config_loss_without_partial_is_refused_before_the_run() -> None:
    cfg = compose_train(["task=depth", "task.module.loss._partial_=false"])
    with pytest.raises(ConfigError, match=r"task.module.loss=.*add _partial_: true"):
        check_train_config(cfg)


@pytest.mark.parametrize("old", sorted(MOVED_KEYS))
def test_an_old_override_of_a_loss_setting_names_its_new_key(old: str) -> None:
    with pytest.raises(ConfigError, match=f"^{old}=0.5: .* write {MOVED_KEYS[old]}=0.5$"):
        check_overrides("train", ["task=depth", f"{old}=0.5"])
    check_overrides("train", ["task=depth", "task.module.loss.w_chamfer=0.5"])  # the new key
