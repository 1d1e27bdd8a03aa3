"""Hydra configs compose (compose API, no subprocess), every experiment instantiates, bad configs fail early."""

from __future__ import annotations

from pathlib import Path

import hydra
import pytest
from omegaconf import OmegaConf

from airfisheye_bench.config_checks import check_train_config
from models.weights import pretrained_weights_disabled
from tests.helpers.configs import CONFIG_DIR, compose_train

EXPERIMENTS = sorted(
    str(p.relative_to(Path(CONFIG_DIR) / "experiment").with_suffix(""))
    for p in (Path(CONFIG_DIR) / "experiment").rglob("*.yaml")
)


@pytest.mark.parametrize(
    ("task", "model"), [("seg", "deeplabv3plus"), ("depth", "adabins"), ("completion", "nlspn")]
)
def test_each_task_picks_its_model(task: str, model: str) -> None:
    cfg = compose_train([f"task={task}"])
    assert cfg.task.name == task and cfg.model.name == model
    assert cfg.data.task == task
    check_train_config(cfg)


@pytest.mark.parametrize("task", ["seg", "depth", "completion"])
def test_the_trainer_group_sets_the_epochs_over_the_task(task: str) -> None:
    """A task sets its quick-start length; trainer=debug (after it in the defaults list) and experiments win."""
    quick_start = OmegaConf.load(Path(CONFIG_DIR) / "task" / f"{task}.yaml").trainer.max_epochs
    debug = OmegaConf.load(Path(CONFIG_DIR) / "trainer" / "debug.yaml").max_epochs
    assert quick_start != debug  # otherwise the test could not tell which group won
    assert compose_train([f"task={task}"]).trainer.max_epochs == quick_start
    assert compose_train([f"task={task}", "trainer=gpu"]).trainer.max_epochs == quick_start
    assert compose_train([f"task={task}", "trainer=debug"]).trainer.max_epochs == debug
    paper = compose_train([f"experiment=paper/{task}"]).trainer.max_epochs
    assert compose_train([f"experiment=paper/{task}", "trainer=debug"]).trainer.max_epochs == paper
    assert compose_train([f"task={task}", "trainer=debug", "trainer.max_epochs=3"]).trainer.max_epochs == 3


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_every_experiment_composes_and_instantiates(experiment: str) -> None:
    cfg = compose_train([f"experiment={experiment}"])
    check_train_config(cfg)
    assert cfg.data.camera.size == 512 and cfg.trainer.max_epochs == 25  # the paper's recipe
    trainer = hydra.utils.instantiate(cfg.trainer, logger=False, enable_checkpointing=False)
    assert trainer.max_epochs == 25
    with pretrained_weights_disabled():  # the paper recipes start from ImageNet weights: no download in tests
        module = hydra.utils.instantiate(
            cfg.task.module,
            model=dict(cfg.model),
            **({"class_names": [f"c{i}" for i in range(13)]} if cfg.task.name == "seg" else {}),
            _convert_="partial",
        )
    assert module.task == cfg.task.name


def test_paper_recipes_follow_the_paper() -> None:
    seg = compose_train(["experiment=paper/seg"])
    assert seg.model.encoder_name == "resnet50" and "SGD" in seg.task.module.optimizer._target_
    depth = compose_train(["experiment=paper/depth"])
    assert (depth.model.encoder_name, depth.model.n_bins, depth.data.batch_size) == ("resnet50", 256, 16)
    assert "AdamW" in depth.task.module.optimizer._target_ and depth.data.max_depth == 120.0
    comp = compose_train(["experiment=paper/completion"])
    assert (comp.model.encoder_name, comp.model.prop_steps, comp.model.affinity) == ("resnet34", 18, "TGASS")
    assert (
        comp.model.prop_kernel**2 - 1 == 8 and comp.data.batch_size == 6 and comp.data.occlusion == "ordering"
    )
    for cfg in (seg, depth, comp):
        assert cfg.data.augment.hflip > 0 and cfg.data.augment.color_jitter is not None
        assert cfg.model.encoder_weights == "imagenet"  # fine-tuned from ImageNet, as the paper and upstream


def test_paper_recipes_follow_upstream() -> None:
    seg = compose_train(["experiment=paper/seg"])
    assert seg.model.encoder_output_stride == 16 and list(seg.model.decoder_atrous_rates) == [6, 12, 18]
    depth = compose_train(["experiment=paper/depth"])
    assert depth.trainer.gradient_clip_val == 0.1 and dict(depth.task.module.lr_multipliers) == {
        "encoder": 0.1
    }
    module = depth.task.module
    assert module.optimizer.lr == 3.57e-4 and module.optimizer.weight_decay == 0.1
    assert (module.scheduler.div_factor, module.scheduler.final_div_factor) == (25, 100)
    comp = compose_train(["experiment=paper/completion"])
    assert comp.model.preserve_input is False and comp.model.confidence_sampling == "offset"
    assert comp.task.module.warmup_epochs == 1  # upstream's --warm_up (on by default): lr ramps over epoch 1
    assert (
        compose_train(["task=completion"]).task.module.get("warmup_epochs", 0) == 0
    )  # not in the quick start


def test_quick_start_downloads_nothing() -> None:
    for task in ("seg", "depth", "completion"):
        assert compose_train([f"task={task}"]).model.encoder_weights is None


def test_incompatible_task_and_model_stop_early_with_advice() -> None:
    cfg = compose_train(["task=seg", "model=adabins"])
    with pytest.raises(ValueError, match="model=deeplabv3plus"):
        check_train_config(cfg)


def test_unknown_group_option_is_rejected() -> None:
    with pytest.raises(Exception, match="nlspnn"):
        compose_train(["model=nlspnn"])


def test_real_data_needs_a_root() -> None:
    cfg = compose_train(["data=airfisheye"])
    with pytest.raises(ValueError, match=r"data\.root=/path"):
        check_train_config(cfg)
    with pytest.raises(Exception, match=r"data\.root"):  # Hydra wraps the datamodule's ValueError
        hydra.utils.instantiate(cfg.data)
