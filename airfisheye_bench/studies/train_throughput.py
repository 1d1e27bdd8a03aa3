"""Training steps of a task module on one device, timed: fed by a loader, or on one batch kept on the device.

A step is what Lightning's precision plugin runs for ``training_step`` (``Stepper``): the forward pass and the
task's loss under autocast (the recipe's ``trainer.precision``: ``16-mixed`` is float16 with a gradient scaler,
``bf16-mixed`` bfloat16, ``32-true`` none), backward, gradient-norm clipping where the recipe clips, the optimizer
step, ``zero_grad``. No LR scheduler and no logging (the Trainer's own cost per step is measured by
``bench_lightning``).

Fed by a loader (:func:`fed_steps`), each step's time splits into the host's wait in ``next(loader)`` and the rest
(the transfer, :class:`~datamodules.device_remap.DeviceRemap` under ``remap_on=device``, the step). The host does not
wait for the device between steps (as in training); on a GPU, CUDA events mark where each step starts and ends on
the device's own timeline, so the **GPU idle share** is measured, not inferred: the gaps between one step's end and
the next one's start, over the device time of the steps. On a CPU (the smoke mode) the device is the host, and
the idle share is the host's wait share.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable, Iterator
from typing import Any

import torch
from torch import Tensor

from airfisheye_bench.studies.campaign_record import Phase
from airfisheye_bench.tasks import BenchmarkTask

#: ``trainer.precision`` -> (autocast dtype or None, gradient scaler).
PRECISIONS: dict[str, tuple[torch.dtype | None, bool]] = {
    "16-mixed": (torch.float16, True),
    "bf16-mixed": (torch.bfloat16, False),
    "32-true": (None, False),
    "32": (None, False),
}


def amp_of(precision: str, device: torch.device) -> tuple[torch.dtype | None, bool, str]:
    """``(autocast dtype, scaler, note)`` of a recipe's precision on ``device``.

    CPU autocast runs bfloat16 (float16 convolutions are not what a CPU is for): the smoke mode measures the code
    path, not the numbers, and the note says so.

    Example:
        >>> amp_of("16-mixed", torch.device("cpu"))
        (torch.bfloat16, False, 'float16 on a GPU; bfloat16 on the CPU')
    """
    if precision not in PRECISIONS:
        raise ValueError(f"trainer.precision={precision!r}: expected one of {', '.join(PRECISIONS)}")
    dtype, scaler = PRECISIONS[precision]
    if dtype is torch.float16 and device.type == "cpu":
        return torch.bfloat16, False, "float16 on a GPU; bfloat16 on the CPU"
    return dtype, scaler, ""


def to_device(batch: dict, device: torch.device) -> dict:
    """The batch's tensors on ``device`` (pinned memory is copied asynchronously, as Lightning does)."""
    return {k: v.to(device, non_blocking=True) if isinstance(v, Tensor) else v for k, v in batch.items()}


def synchronize(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


class Stepper:
    """One training step of ``module`` as the Trainer runs it with the recipe's precision and clipping."""

    def __init__(
        self,
        module: BenchmarkTask,
        device: torch.device,
        amp_dtype: torch.dtype | None,
        scaler: bool,
        clip_norm: float | None,
    ) -> None:
        self.module = module.to(device).train()
        self.device, self.amp_dtype, self.clip_norm = device, amp_dtype, clip_norm
        lr = getattr(module.optimizer_factory, "keywords", {}).get("lr")
        self.optimizer = module.optimizer_factory(params=module.parameter_groups(lr))
        self.scaler = torch.amp.GradScaler(device.type, enabled=scaler)

    def loss(self, batch: dict) -> tuple[Tensor, dict[str, Tensor]]:
        """The forward pass and the loss under the recipe's autocast: ``(loss, outputs)``."""
        with torch.autocast(
            self.device.type, dtype=self.amp_dtype or torch.float32, enabled=self.amp_dtype is not None
        ):
            outputs = self.module.net.forward_with_aux(*self.module.model_inputs(batch))
            return self.module.loss_terms(outputs, batch)["loss"], outputs

    def __call__(self, batch: dict) -> Tensor:
        loss, _ = self.loss(batch)
        self.scaler.scale(loss).backward()
        if self.clip_norm:
            self.scaler.unscale_(self.optimizer)
            torch.nn.utils.clip_grad_norm_(self.module.parameters(), self.clip_norm)
        self.scaler.step(self.optimizer)
        self.scaler.update()
        self.optimizer.zero_grad(set_to_none=True)
        return loss.detach()


class _Marks:
    """Points on the device's timeline: CUDA events on a GPU, the host clock elsewhere (the host is the device)."""

    def __init__(self, device: torch.device) -> None:
        self.cuda = device.type == "cuda"

    def mark(self) -> Any:
        if not self.cuda:
            return time.perf_counter()
        event = torch.cuda.Event(enable_timing=True)
        event.record()
        return event

    def ms(self, a: Any, b: Any) -> float:
        return a.elapsed_time(b) if self.cuda else (b - a) * 1e3


def cached_steps(
    stepper: Stepper,
    batch: dict,
    warmup: int,
    steps: int,
    phase: Phase,
    warm_s: float = 0.0,
    window_s: float = 0.0,
) -> dict[str, Any]:
    """Steps on one batch kept on the device: the model's own ceiling (no loader), and its peak memory.

    The warm-up runs ``warmup`` steps and at least ``warm_s`` seconds (a GPU's clocks ramp up and cuDNN settles its
    algorithms over the first second or so); the measurement ``steps`` steps and at least ``window_s`` seconds.
    """
    device = stepper.device
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)
    warm_started, warmed = time.perf_counter(), 0
    while (warmed < warmup or time.perf_counter() - warm_started < warm_s) and not phase.expired("warm-up"):
        stepper(batch)
        warmed += 1
    synchronize(device)
    size = int(batch["image"].shape[0])
    done, losses, started = 0, [], time.perf_counter()
    while done < steps or time.perf_counter() - started < window_s:
        if phase.expired("cached steps"):
            break
        losses.append(stepper(batch))
        done += 1
    synchronize(device)
    wall = time.perf_counter() - started
    out: dict[str, Any] = {
        "batch": size,
        "warmup_steps": warmed,
        "steps": done,
        "step_ms": wall / max(done, 1) * 1e3,
        "images_per_s": size * done / wall if done else None,
        "loss_last": float(losses[-1]) if losses else None,
    }
    return out | peak_memory(device)


def fed_steps(
    stepper: Stepper,
    batches: Iterator[dict],
    finish: Callable[[dict], dict],
    warmup: int,
    steps: int,
    phase: Phase,
    drain_s: float = 0.0,
    window_s: float = 0.0,
    empty_ms: float = 1.0,
) -> dict[str, Any]:
    """Steps fed by ``batches`` (a loader's iterator); ``finish`` runs on the device after the transfer.

    A loader's workers hold batches they made ahead (``prefetch_factor`` each), and a device that consumes faster
    than they produce eats that store before it waits: a short window after a short warm-up measures the store, not
    the loader. So the warm-up runs ``warmup`` steps, then goes on, for up to ``drain_s`` more seconds, until ``next()``
    first waits longer than ``empty_ms`` (the store is empty: from then on each batch comes as it is made);
    ``drained`` says whether that happened (if not, the loader kept the store filled for ``drain_s``: it keeps up,
    or nearly). The measurement runs ``steps`` steps and at least ``window_s`` seconds.

    Returns images/s, the host's wait in ``next()`` (share and ms per step), the device's idle share between steps,
    the device time of the transfer and finish, and of the step.
    """
    device = stepper.device
    marks = _Marks(device)
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)
    warm_started, warmed, drained = time.perf_counter(), 0, False
    # The wait for an empty store counts from the end of the minimum warm-up (a slow warm-up does not use it up).
    drain_started = warm_started if warmup <= 0 else None
    while warmed < warmup or (not drained and time.perf_counter() - drain_started < drain_s):
        if phase.expired("loader-fed warm-up"):
            break
        t0 = time.perf_counter()
        batch = next(batches)
        drained |= warmed >= warmup and time.perf_counter() - t0 > empty_ms / 1e3
        stepper(finish(to_device(batch, device)))
        warmed += 1
        if warmed == warmup:
            drain_started = time.perf_counter()
    synchronize(device)
    warm_s = time.perf_counter() - warm_started
    size, waits, points = 0, [], []
    started = time.perf_counter()
    while len(points) < steps or time.perf_counter() - started < window_s:
        if phase.expired("loader-fed steps"):
            break
        t0 = time.perf_counter()
        batch = next(batches)
        waits.append(time.perf_counter() - t0)
        start = marks.mark()
        batch = finish(to_device(batch, device))
        ready = marks.mark()
        stepper(batch)
        points.append((start, ready, marks.mark()))
        size = int(batch["image"].shape[0])
    synchronize(device)
    wall = time.perf_counter() - started
    done = len(points)
    if not done:
        return {"steps": 0}
    busy = [marks.ms(s, e) for s, _, e in points]
    gaps = [marks.ms(points[i - 1][2], points[i][0]) for i in range(1, done)]
    span = marks.ms(points[0][0], points[-1][2])
    out: dict[str, Any] = {
        "batch": size,
        "warmup_steps": warmed,
        "warmup_s": round(warm_s, 2),
        "drained": drained,
        "steps": done,
        "step_ms": wall / done * 1e3,
        "images_per_s": size * done / wall,
        "host_wait_ms_per_step": statistics.mean(waits) * 1e3,
        "host_wait_share": sum(waits) / wall,
        "device_idle_share": sum(gaps) / span if span > 0 and gaps else 0.0,
        "device_step_ms": statistics.median(busy),
        "device_transfer_and_finish_ms": statistics.median(marks.ms(s, r) for s, r, _ in points),
    }
    return out | peak_memory(device)


def peak_memory(device: torch.device) -> dict[str, float | None]:
    """Peak memory since the last reset, GiB (``None`` off a GPU)."""
    if device.type != "cuda":
        return {"peak_allocated_gib": None, "peak_reserved_gib": None}
    return {
        "peak_allocated_gib": torch.cuda.max_memory_allocated(device) / 2**30,
        "peak_reserved_gib": torch.cuda.max_memory_reserved(device) / 2**30,
    }


@torch.no_grad()
def amp_parity(stepper: Stepper, batch: dict) -> dict[str, Any]:
    """Loss and output of one forward pass in float32 and under the recipe's autocast, same weights, same batch.

    Train mode (batch statistics, as the training step sees them), the same seed before each pass (dropout).
    ``prediction_*`` compares what the metric scores: the label agreement on valid pixels (seg), or the relative
    range difference on valid pixels (depth, completion).
    """
    module = stepper.module
    dtype = stepper.amp_dtype
    results = {}
    for name, amp in (("fp32", None), ("amp", dtype)):
        stepper.amp_dtype = amp
        torch.manual_seed(0)
        loss, outputs = stepper.loss(batch)
        results[name] = (float(loss), module.prediction(outputs).float(), outputs[module.spec.output].float())
    stepper.amp_dtype = dtype
    (loss32, pred32, out32), (loss_amp, pred_amp, out_amp) = results["fp32"], results["amp"]
    valid = batch["valid_mask"]
    out: dict[str, Any] = {
        "amp_dtype": str(dtype).removeprefix("torch.") if dtype is not None else None,
        "mode": "train mode (batch statistics), no grad, the same seed for both passes",
        "loss_fp32": loss32,
        "loss_amp": loss_amp,
        "loss_rel_diff": abs(loss_amp - loss32) / abs(loss32) if loss32 else math.nan,
        "output_max_abs_diff": float((out_amp - out32).abs().max()),
        "output_max_abs": float(out32.abs().max()),
        "output_mean_abs_diff_rel": float(
            (out_amp - out32).abs().mean() / out32.abs().mean().clamp_min(1e-12)
        ),
    }
    if module.spec.target == "label":
        out["prediction_agreement"] = float((pred_amp == pred32)[valid].float().mean())
    else:
        mask = valid[:, None].expand_as(pred32) & (pred32 > 0)
        rel = ((pred_amp - pred32).abs() / pred32.clamp_min(1e-6))[mask]
        out["prediction_rel_diff_median"] = float(rel.median()) if rel.numel() else None
        out["prediction_rel_diff_max"] = float(rel.max()) if rel.numel() else None
    return out


__all__ = [
    "PRECISIONS",
    "Stepper",
    "amp_of",
    "amp_parity",
    "cached_steps",
    "fed_steps",
    "peak_memory",
    "to_device",
]
