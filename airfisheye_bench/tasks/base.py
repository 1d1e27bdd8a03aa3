"""The LightningModule shared by the benchmark tasks.

A task owns a zoo model (built by registry name, so a checkpoint alone rebuilds it), its loss (chosen by config,
``task.module.loss``, and recorded in the checkpoint the same way), one set of metrics per evaluation stage plus
their breakdown by incidence-angle ring, and qualitative panels written every validation epoch. The facts of the
task (which batch keys feed the model, the target, the primary output, the metric, the breakdowns) come from its
:class:`~airfisheye_bench.specs.TaskSpec`; a subclass names its spec (``task``), its default loss (the one of a
checkpoint written before losses were chosen by config) and says which metric options it evaluates with.
"""

from __future__ import annotations

import inspect
import math
import random
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, ClassVar

import lightning as L
import numpy as np
import torch
from torch import Tensor, nn
from torchmetrics import MeanMetric, Metric

from airfisheye_bench.metrics import DEFAULT_DEPTH_EDGES_M, DEFAULT_RING_EDGES_DEG
from airfisheye_bench.metrics.scorer import TaskScorer
from airfisheye_bench.specs import TaskSpec, get_task
from airfisheye_bench.tasks.loss_config import LossArg, build_loss, loss_config
from airfisheye_bench.viz import panel_row, save_png, spread_indices, task_panel
from models import create_model, model_task

STAGES = ("val", "test")


class BenchmarkTask(L.LightningModule):
    """Base class of :class:`SegmentationTask`, :class:`DepthTask`, :class:`CompletionTask` and any new task.

    Subclasses set ``task`` (a registered spec name) and :meth:`default_loss` (or override :meth:`loss_terms`);
    they override :meth:`metric_options` when they evaluate with other than the default bounds.

    Args:
        model: Registry name and keyword arguments, e.g. ``{"name": "deeplabv3plus", "encoder_name": "resnet50"}``.
        loss: The training loss, chosen by config (``task.module.loss``): ``{"_target_": "models.losses.X",
            **settings}`` or the partial Hydra makes of it (``_partial_: true``, as the configs write it); the task
            builds it and records the config in its hyperparameters, so a checkpoint rebuilds the same loss. A
            built ``nn.Module`` is used as given but not recorded (a checkpoint then rebuilds the default). None:
            :meth:`default_loss`. It is called as :meth:`loss_terms` says.
        optimizer: Partial optimizer (Hydra ``_partial_: true``) called with the parameter groups.
        scheduler: Optional partial LR scheduler called with the optimizer.
        scheduler_interval: ``epoch`` or ``step``.
        lr_multipliers: ``{submodule: factor}``: the parameters under that submodule of the model (e.g.
            ``encoder``) train at ``factor`` x the optimizer's ``lr`` (and a scheduler's ``max_lr``); the rest at
            the ``lr``. AdaBins trains its encoder at lr / 10 (see :meth:`parameter_groups`).
        weights: What the model's weights started from (``models.weights.weights_identity``); recorded from the
            model when ``None``, and kept from the checkpoint when a trained task is rebuilt.
        ring_edges_deg: Incidence-angle ring edges of the fisheye breakdown (degrees).
        num_panels: Validation frames drawn into the qualitative panel each epoch (0 disables panels), spread
            evenly over the split (:func:`~airfisheye_bench.viz.spread_indices`), the same frames every epoch.
        warmup_epochs: Linear learning-rate warm-up over the first ``warmup_epochs`` epochs (0: none), as upstream
            NLSPN's ``--warm_up`` does over its first epoch: step ``s`` of the ``S`` warm-up steps runs at
            ``(s + 1) / (S + 1)`` x the scheduled lr of every group. The factor is applied to the step alone
            (:meth:`optimizer_step`), so checkpoints hold the scheduled lr and a resume needs no extra state.
        source_names: The sources of a run on several datasets (``data.sources``): each is also scored on its
            own frames (a batch's ``source`` key says whose each frame is), logged as ``<stage>/<source>/<metric>``
            next to the pooled ``<stage>/<metric>``.
        **legacy_loss: Deprecated: the settings of the default loss that the task took as its own arguments
            before ``loss`` chose it (:attr:`legacy_loss_args`, e.g. ``w_chamfer``); old checkpoints and run configs
            hold them. They configure :meth:`default_loss` and are recorded as its config.
    """

    task: ClassVar[str]
    #: The deprecated ``**legacy_loss`` arguments this task accepts (an old checkpoint's hyperparameters hold them).
    legacy_loss_args: ClassVar[tuple[str, ...]] = ()
    #: Class colours ``uint8 [256, 3]`` of the panels (tasks whose spec ``uses_classes``).
    palette: np.ndarray | None = None
    #: Far end of the depth colour map of the panels, metres.
    max_depth: float = 120.0

    def __init__(
        self,
        model: dict[str, Any],
        optimizer: Callable[..., torch.optim.Optimizer] | None = None,
        scheduler: Callable[..., Any] | None = None,
        scheduler_interval: str = "epoch",
        ring_edges_deg: tuple[float, ...] = DEFAULT_RING_EDGES_DEG,
        num_panels: int = 4,
        lr_multipliers: dict[str, float] | None = None,
        weights: dict[str, Any] | None = None,
        warmup_epochs: int = 0,
        source_names: list[str] | None = None,
        loss: LossArg = None,
        **legacy_loss: Any,
    ) -> None:
        super().__init__()
        self._check_legacy_loss(legacy_loss, loss)
        self.save_hyperparameters(ignore=["optimizer", "scheduler", "loss"], logger=False)
        spec = get_task(self.task)
        model = dict(model)
        name = model.pop("name", None)
        if name is None:
            raise ValueError("model must name a registered model: {'name': ..., **kwargs}")
        if model_task(name) != self.task:
            raise ValueError(
                f"model {name!r} solves task {model_task(name)!r}, not {self.task!r}; pick a {self.task} model "
                f"(python -c 'import models; print(models.list_models(\"{self.task}\"))')"
            )
        if scheduler_interval not in ("epoch", "step"):
            raise ValueError(f"scheduler_interval must be 'epoch' or 'step', got {scheduler_interval!r}")
        if isinstance(warmup_epochs, bool) or not isinstance(warmup_epochs, int) or warmup_epochs < 0:
            raise ValueError(f"warmup_epochs must be a whole number >= 0, got {warmup_epochs!r}")
        self.net = create_model(name, **model)
        # Saved with the hyperparameters, so results.json and the ONNX metadata say which weights a run started from.
        self.hparams["weights"] = (
            weights if weights is not None else getattr(self.net, "weights_identity", None)
        )
        self.optimizer_factory = optimizer
        self.scheduler_factory = scheduler
        self.loss, self.hparams["loss"] = self._make_loss(loss)
        for key in legacy_loss:  # recorded as the loss config instead
            self.hparams.pop(key, None)
        # Label targets carry no depth: their breakdown is by incidence angle only.
        depth_edges = DEFAULT_DEPTH_EDGES_M if spec.depth_breakdown else None
        self.scorers = nn.ModuleDict(
            {stage: TaskScorer(self.make_metric, ring_edges_deg, depth_edges) for stage in STAGES}
        )
        # Frame-weighted mean loss as summed metric states: under DDP the synced value is the one-process value
        # whatever the shard sizes (a rank with no frame adds nothing), unlike a mean of per-rank means.
        # nan_strategy="disable": a NaN loss must show in the logged mean, not be dropped with a warning.
        self.eval_losses = nn.ModuleDict({stage: MeanMetric(nan_strategy="disable") for stage in STAGES})
        names = list(source_names or [])
        self.source_scorers = nn.ModuleDict(
            {
                stage: nn.ModuleDict(
                    {name: TaskScorer(self.make_metric, ring_edges_deg, depth_edges) for name in names}
                )
                for stage in STAGES
            }
        )
        # The pooled scores of a mixture are the sum of its sources' (metric states are sums): each frame is scored
        # once, into its source's scorer, and the sources are added up at the epoch's end.
        self._pool_by_adding = bool(names) and self.scorers["val"].can_add()
        self._thetas: dict[str | None, Tensor] = {}
        self._panel_rows: list[list[np.ndarray]] = []
        self._panel_ids: set[str] | None = None

    # ------------------------------------------------------------------------------------------------------ loss
    @classmethod
    def default_loss(cls, hparams: Mapping[str, Any]) -> dict[str, Any] | None:
        """The loss config of a task given no ``loss``, from the task's arguments ``hparams``: the loss the task
        trained with before losses were chosen by config, set by :attr:`legacy_loss_args` where ``hparams`` holds
        them (an old checkpoint). None (the base): a subclass without one overrides :meth:`loss_terms`."""
        return None

    @classmethod
    def upgrade_hparams(cls, hparams: Mapping[str, Any]) -> dict[str, Any]:
        """A checkpoint's hyperparameters in today's form: the loss settings of an old one
        (:attr:`legacy_loss_args`) become the config of the loss they built (:meth:`default_loss`).

        Example:
            >>> from airfisheye_bench.tasks import DepthTask
            >>> old = {"model": {"name": "adabins"}, "min_depth": 1e-3, "max_depth": 80.0, "w_chamfer": 0.1,
            ...        "chamfer_reference_range": None}
            >>> DepthTask.upgrade_hparams(old)["loss"]["w_chamfer"], "w_chamfer" in DepthTask.upgrade_hparams(old)
            (0.1, False)
        """
        if hparams.get("loss") is not None or not any(k in hparams for k in cls.legacy_loss_args):
            return dict(hparams)
        kept = {k: v for k, v in hparams.items() if k not in cls.legacy_loss_args}
        return {**kept, "loss": cls.default_loss(hparams)}

    def _check_legacy_loss(self, legacy: Mapping[str, Any], loss: LossArg) -> None:
        unknown = sorted(set(legacy) - set(self.legacy_loss_args))
        if unknown:  # Python's own words for it
            raise TypeError(
                f"{type(self).__name__}.__init__() got an unexpected keyword argument '{unknown[0]}'"
            )
        if not legacy:
            return
        if loss is not None:
            raise ValueError(
                f"{type(self).__name__}: {sorted(legacy)} set the default loss, and loss is given too; "
                f"give them in loss (task.module.loss.{sorted(legacy)[0]})"
            )
        warnings.warn(
            f"{type(self).__name__}({', '.join(f'{k}=...' for k in sorted(legacy))}) is deprecated: the loss is "
            f"chosen by loss={{'_target_': ..., {', '.join(f'{k!r}: ...' for k in sorted(legacy))}}} "
            "(task.module.loss in the config)",
            DeprecationWarning,
            stacklevel=4,  # the caller of the subclass's __init__, which hands its kwargs on to this one's
        )

    def _make_loss(self, loss: LossArg) -> tuple[nn.Module | None, dict[str, Any] | None]:
        """The loss module and the config the hyperparameters record (None: not recordable, or no loss)."""
        if isinstance(loss, nn.Module):
            return loss, None
        config = loss_config(loss) if loss is not None else self.default_loss(self.hparams)
        return (build_loss(config), config) if config is not None else (None, None)

    # ------------------------------------------------------------------------------------------ hooks for subclasses
    def loss_terms(self, outputs: dict[str, Tensor], batch: dict) -> dict[str, Tensor]:
        """``{"loss": total, ...parts}`` from ``forward_with_aux`` outputs: the loss called with the primary output
        (the spec's ``output``), or the whole mapping when its class sets ``takes_model_outputs``, and the
        target; its ``terms`` method (same arguments, the parts logged too) when it has one."""
        if self.loss is None:
            raise NotImplementedError(
                f"{type(self).__name__} has no loss: pass loss=... (task.module.loss) or override loss_terms"
            )
        pred = outputs if getattr(self.loss, "takes_model_outputs", False) else outputs[self.spec.output]
        target = self.target(batch)
        terms = getattr(self.loss, "terms", None)
        return terms(pred, target) if callable(terms) else {"loss": self.loss(pred, target)}

    def metric_options(self) -> dict[str, Any]:
        """The :class:`~airfisheye_bench.specs.MetricOptions` this module evaluates with (default: the spec's)."""
        return {}

    # ------------------------------------------------------------------------------------- facts from the spec
    @property
    def spec(self) -> TaskSpec:
        """The task's spec (inputs, target, output, metric, breakdowns)."""
        return get_task(self.task)

    def make_metric(self) -> Metric:
        """A fresh task metric with this module's options."""
        return self.spec.make_metric(**self.metric_options())

    @property
    def camera_input(self) -> str:
        """What the model takes of the camera besides the image (``model.camera_input``): ``none`` or ``rays``."""
        return getattr(self.net, "camera_input", "none")

    def model_inputs(self, batch: dict) -> tuple[Tensor, ...]:
        """The model's positional inputs: the spec's, then the batch's ray map when the model takes it (a batch
        without one passes ``None``, which the model refuses naming ``data.camera_input``)."""
        inputs = tuple(batch[key] for key in self.spec.inputs)
        return (*inputs, batch.get("rays")) if self.camera_input == "rays" else inputs

    def target(self, batch: dict) -> Tensor:
        return batch[self.spec.target]

    def prediction(self, outputs: dict[str, Tensor]) -> Tensor:
        """The metric input from ``forward_with_aux`` outputs (labels from logits, or the range map)."""
        return self.spec.prediction.from_output(outputs[self.spec.output])

    def panel_row(self, batch: dict, prediction: Tensor, index: int) -> list[np.ndarray]:
        return panel_row(self.task, batch, prediction, index, palette=self.palette, max_depth=self.max_depth)

    def render_panel(self, rows: list[list[np.ndarray]]) -> np.ndarray:
        """The panel image of :meth:`panel_row` rows: column titles and the task's colour bars."""
        names = getattr(self, "class_names", None) or []  # segmentation: the key of the label colours
        classes = list(zip(names, self.palette[: len(names)].tolist(), strict=True)) if names else []
        return task_panel(
            self.task, rows, max_depth=float(getattr(self, "max_depth", 120.0)), classes=classes
        )

    # ------------------------------------------------------------------------------------------ reproducibility
    def on_train_epoch_start(self) -> None:
        datamodule = getattr(self.trainer, "datamodule", None)
        if hasattr(datamodule, "set_epoch"):
            datamodule.set_epoch(self.current_epoch)

    def on_save_checkpoint(self, checkpoint: dict[str, Any]) -> None:
        # Global RNG states (dropout, ...), so a resumed run continues exactly where the killed one stopped.
        # Stored as tensors and plain numbers: checkpoints are loaded with ``weights_only=True``.
        kind, keys, pos, has_gauss, cached = np.random.get_state()  # noqa: NPY002 - the state libraries draw from
        version, py_state, gauss_next = random.getstate()
        checkpoint["rng_states"] = {
            "torch": torch.get_rng_state(),
            "numpy": (kind, torch.from_numpy(keys.astype(np.int64)), pos, has_gauss, cached),
            "python": (version, torch.tensor(py_state, dtype=torch.int64), gauss_next),
        }
        if torch.cuda.is_initialized():  # dropout on a GPU draws from the CUDA generators
            checkpoint["rng_states"]["cuda"] = torch.cuda.get_rng_state_all()

    def on_load_checkpoint(self, checkpoint: dict[str, Any]) -> None:
        states = checkpoint.get("rng_states")
        if not states:
            return
        torch.set_rng_state(states["torch"])
        kind, keys, pos, has_gauss, cached = states["numpy"]
        np.random.set_state((kind, keys.numpy().astype(np.uint32), pos, has_gauss, cached))  # noqa: NPY002
        version, py_state, gauss_next = states["python"]
        random.setstate((version, tuple(py_state.tolist()), gauss_next))
        if (
            "cuda" in states
            and torch.cuda.is_available()
            and len(states["cuda"]) == torch.cuda.device_count()
        ):
            torch.cuda.set_rng_state_all(states["cuda"])

    # ----------------------------------------------------------------------------------------------------- model
    def forward(self, *inputs: Tensor) -> Tensor:
        """The primary output (logits or depth), as exported."""
        return self.net(*inputs)

    def training_step(self, batch: dict, batch_idx: int) -> Tensor | None:
        if "image" not in batch:  # every frame of the batch was skipped (skip_bad_frames)
            return None
        terms = self.loss_terms(self.net.forward_with_aux(*self.model_inputs(batch)), batch)
        size = batch["image"].shape[0]
        parts = {f"train/{k}": v.detach() for k, v in terms.items() if k != "loss"}
        self.log_dict(parts, batch_size=size)
        self.log("train/loss", terms["loss"].detach(), prog_bar=True, batch_size=size)
        self._log_skipped(batch, "train")
        return terms["loss"]

    def validation_step(self, batch: dict, batch_idx: int) -> None:
        self._evaluate(batch, batch_idx, "val")

    def test_step(self, batch: dict, batch_idx: int) -> None:
        self._evaluate(batch, batch_idx, "test")

    def _evaluate(self, batch: dict, batch_idx: int, stage: str) -> None:
        if "image" not in batch:
            return
        outputs = self.net.forward_with_aux(*self.model_inputs(batch))
        terms = self.loss_terms(outputs, batch)
        pred = self.prediction(outputs)
        target = self.target(batch)
        mask = batch["valid_mask"]
        self._score(stage, pred, target, mask, batch.get("source"))
        self.eval_losses[stage].update(terms["loss"].detach(), weight=batch["image"].shape[0])
        self._log_skipped(batch, stage)
        if stage == "val" and len(self._panel_rows) < self.hparams.num_panels:
            wanted = self._panel_frames() if "sample_id" in batch else None
            for i in range(batch["image"].shape[0]):
                if len(self._panel_rows) < self.hparams.num_panels and (
                    wanted is None or batch["sample_id"][i] in wanted
                ):
                    self._panel_rows.append(self.panel_row(batch, pred, i))

    def _score(
        self, stage: str, pred: Tensor, target: Tensor, mask: Tensor, sources: list[str] | None
    ) -> None:
        """Add a batch to the pooled scores and, in a run of several sources, to each frame's source's scores
        (each source's frames with the incidence angles of its own served lens)."""
        scorers = self.source_scorers[stage]
        if not sources or not len(scorers):
            self.scorers[stage].update(pred, target, theta=self._theta_deg(mask), mask=mask)
            return
        for name in dict.fromkeys(sources):
            rows = torch.tensor([i for i, s in enumerate(sources) if s == name], device=pred.device)
            part = (pred[rows], target[rows], mask[rows])
            theta = self._theta_deg(mask, name if name in scorers else None)
            if name in scorers:
                scorers[name].update(*part[:2], theta=theta, mask=part[2])
            if name not in scorers or not self._pool_by_adding:
                self.scorers[stage].update(*part[:2], theta=theta, mask=part[2])

    def _panel_frames(self) -> set[str] | None:
        """Sample ids of the panel frames, spread over the validated frames (``None``: the first frames).

        The validated frames are the split's, or its first ``limit_val_batches`` batches; chosen once per
        validation run. Under DDP a rank sees its shard only, so rank 0's panel holds the chosen frames that fall
        in its shard.
        """
        if self._panel_ids is None:
            datamodule = getattr(self.trainer, "datamodule", None)
            if not hasattr(datamodule, "split_dataset"):
                return None
            ids = list(datamodule.split_dataset("val").sample_ids)
            batches = (getattr(self.trainer, "num_val_batches", None) or [math.inf])[0]
            batch_size = getattr(datamodule, "eval_batch_size", None)
            seen = (
                len(ids) if batch_size is None or math.isinf(batches) else min(len(ids), batches * batch_size)
            )
            self._panel_ids = {ids[i] for i in spread_indices(int(seen), self.hparams.num_panels)}
        return self._panel_ids

    def on_validation_epoch_end(self) -> None:
        self._log_stage("val")
        if self._panel_rows and not self.trainer.sanity_checking and self.trainer.is_global_zero:
            self.write_panel(
                self.render_panel(self._panel_rows), f"panels/epoch_{self.current_epoch:03d}.png"
            )
        self._panel_rows = []
        self._panel_ids = None  # chosen again for the next run (its number of validated batches may differ)

    def on_test_epoch_end(self) -> None:
        self.test_results = self._log_stage("test")

    def _log_stage(self, stage: str) -> dict[str, dict[str, float]]:
        """Log ``<stage>/<metric>`` and ``<stage>/<ring or range>/<metric>``; return the plain values."""
        if self._pool_by_adding:
            for scorer in self.source_scorers[stage].values():
                self.scorers[stage].add(scorer)
        scores = self.scorers[stage].compute()
        self.scorers[stage].reset()
        loss = self.eval_losses[stage].compute()
        self.eval_losses[stage].reset()
        metrics, breakdown = scores["metrics"], scores["breakdown"]
        # The values are already synced across processes (torchmetrics); sync_dist averages identical numbers.
        # NaN (e.g. a class absent from the split) is logged as is; monitors use the primary metric only.
        self.log(f"{stage}/loss", loss, sync_dist=True)
        self.log_dict({f"{stage}/{k}": v for k, v in metrics.items()}, sync_dist=True)
        self.log_dict({f"{stage}/{k}": v for k, v in breakdown.items() if math.isfinite(v)}, sync_dist=True)
        if len(self.source_scorers[stage]):
            scores["sources"] = {}
            for name, scorer in self.source_scorers[stage].items():
                scores["sources"][name] = scorer.compute()
                scorer.reset()
                part = scores["sources"][name]["metrics"]
                self.log_dict({f"{stage}/{name}/{k}": v for k, v in part.items()}, sync_dist=True)
        return scores

    def write_panel(self, panel: np.ndarray, relative_path: str) -> None:
        """Save a panel PNG under the run directory and hand it to TensorBoard when that logger is used."""
        # Not trainer.log_dir: it broadcasts, and this runs on rank 0 only (a collective there would deadlock DDP).
        root = Path(self.trainer.default_root_dir)
        save_png(root / relative_path, panel)
        for logger in self.loggers:
            experiment = getattr(logger, "experiment", None)
            if hasattr(experiment, "add_image"):
                experiment.add_image("val/panel", panel, self.current_epoch, dataformats="HWC")

    def _theta_deg(self, mask: Tensor, source: str | None = None) -> Tensor:
        """Incidence angle (degrees) of every pixel of the served camera (of ``source``'s, in a run of several
        sources), cached on the right device."""
        theta = self._thetas.get(source)
        if theta is None or theta.shape != mask.shape[-2:] or theta.device != mask.device:
            datamodule = self.trainer.datamodule
            camera = datamodule.camera_of(source) if source is not None else datamodule.camera
            theta = self._thetas[source] = torch.rad2deg(camera.theta_grid()).to(mask.device)
        return theta

    def _log_skipped(self, batch: dict, stage: str) -> None:
        if batch.get("num_skipped"):
            self.log(
                f"{stage}/skipped_frames",
                float(batch["num_skipped"]),
                reduce_fx="sum",
                on_epoch=True,
                on_step=False,
            )

    # ------------------------------------------------------------------------------------------------ optimiser
    def parameter_groups(self, lr: float | None) -> list[dict[str, Any]]:
        """The trainable parameters as optimizer groups: one per ``lr_multipliers`` entry, then the rest.

        Each group carries its ``name`` (the submodule, or ``"default"``) and ``lr_factor``; with a base ``lr``
        it also gets ``lr = lr * lr_factor``.

        Raises:
            ValueError: a multiplier names no submodule with trainable parameters, or a multiplier is set but
                the optimizer has no ``lr`` to scale.
        """
        factors = {str(k): float(v) for k, v in (self.hparams.get("lr_multipliers") or {}).items()}
        if factors and lr is None:
            raise ValueError("lr_multipliers needs the optimizer's lr (optimizer.lr) to scale")
        members: dict[str, list[nn.Parameter]] = {key: [] for key in (*factors, "default")}
        for name, param in self.named_parameters():
            if not param.requires_grad:
                continue
            name = name.removeprefix("net.").removeprefix(
                "_orig_mod."
            )  # the model's names (torch.compile wraps)
            # The most specific entry wins (``encoder`` and ``encoder.layer4`` may both be given).
            key = max(
                (k for k in factors if name == k or name.startswith(k + ".")), key=len, default="default"
            )
            members[key].append(param)
        empty = [k for k in factors if not members[k]]
        if empty:
            children = sorted(n for n, _ in self.net.named_children())
            raise ValueError(
                f"lr_multipliers {empty} match no trainable parameter of {type(self.net).__name__}; "
                f"use submodule names such as {children}"
            )
        groups = []
        for key, params in members.items():
            if not params:
                continue
            factor = factors.get(key, 1.0)
            group: dict[str, Any] = {"params": params, "name": key, "lr_factor": factor}
            if lr is not None:
                group["lr"] = lr * factor
            groups.append(group)
        return groups

    def warmup_factor(self, epoch: int, batch_idx: int) -> float:
        """The warm-up multiplier of the learning rate at ``(epoch, batch_idx)`` (1.0 once warmed up).

        Upstream NLSPN (``main.py``) counts the batches of its first epoch and sets ``lr = initial_lr * count /
        (len(loader) + 1)``; over ``warmup_epochs`` epochs of ``N`` batches this is ``(s + 1) / (E N + 1)`` at
        warm-up step ``s``.
        """
        epochs = int(self.hparams.get("warmup_epochs", 0))
        if epoch >= epochs:
            return 1.0
        per_epoch = int(self.trainer.num_training_batches)
        return (epoch * per_epoch + batch_idx + 1) / (epochs * per_epoch + 1)

    def optimizer_step(
        self, epoch: int, batch_idx: int, optimizer: Any, optimizer_closure: Any = None
    ) -> None:
        factor = self.warmup_factor(epoch, batch_idx)
        if factor == 1.0:
            optimizer.step(closure=optimizer_closure)
            return
        # Scale this step only: the groups keep the scheduled lr, which the LR scheduler and checkpoints read.
        scheduled = [group["lr"] for group in optimizer.param_groups]
        for group in optimizer.param_groups:
            group["lr"] = group["lr"] * factor
        try:
            optimizer.step(closure=optimizer_closure)
        finally:
            for group, lr in zip(optimizer.param_groups, scheduled, strict=True):
                group["lr"] = lr

    def configure_optimizers(self) -> Any:
        if self.optimizer_factory is None:
            raise ValueError("no optimizer configured: pass optimizer=partial(torch.optim.X, lr=...)")
        lr = getattr(self.optimizer_factory, "keywords", {}).get("lr")
        groups = self.parameter_groups(lr)
        optimizer = self.optimizer_factory(params=groups)
        if self.scheduler_factory is None:
            return optimizer
        kwargs: dict[str, Any] = {"optimizer": optimizer}
        keywords = getattr(self.scheduler_factory, "keywords", {})
        # Step-based schedules (OneCycleLR) need the run length, known only once the trainer has the data.
        if (
            "total_steps" in inspect.signature(self.scheduler_factory).parameters
            and "total_steps" not in keywords
        ):
            kwargs["total_steps"] = int(self.trainer.estimated_stepping_batches)
        # OneCycleLR sets every group's lr from max_lr: a single value would undo the multipliers.
        if isinstance(keywords.get("max_lr"), (int, float)):
            kwargs["max_lr"] = [keywords["max_lr"] * g["lr_factor"] for g in groups]
        scheduler = self.scheduler_factory(**kwargs)
        return {
            "optimizer": optimizer,
            "lr_scheduler": {"scheduler": scheduler, "interval": self.hparams.scheduler_interval},
        }
