"""Size and speed of the paper's model configurations: parameters, forward latency, training-step time, and
ONNX Runtime vs PyTorch eager latency.

Builds each registered paper configuration with its defaults (DeepLabV3+ / ResNet50 at output stride 16,
AdaBins / ResNet50 with 256 bins, NLSPN / ResNet34 with 18 steps if ``nlspn`` is registered), then on CPU
(``--threads`` torch threads) and on CUDA when available:

- forward latency: eval mode, ``torch.no_grad``, batch ``--batch``, median of ``--repeats`` after a warm-up;
- train step: ``forward_with_aux`` + the model's training loss + backward + AdamW step, batch
  ``--train-batch`` (>= 2, BatchNorm needs it), median of ``--repeats``;
- ONNX: export at batch 2 with a dynamic batch, then ONNX Runtime (CPU, same thread count) vs eager at batch
  ``--batch``; also the max abs difference of the outputs.

Prints a markdown table. Weights are random (never downloaded); timings do not depend on them.

``--camera-input none rays`` builds each model both ways (``model.camera_input``: the ray map of a 190 deg
equidistant lens beside the image; the same seed) and times them side by side: each round of the forward and the
train-step timing runs every variant once, in turn, so a machine's load drifting over the run reaches both alike.
``--set key=value`` overrides a constructor argument of the models (e.g. ``encoder_name=resnet18``); ``--out``
writes the table as JSON with its provenance (commit, command, machine), each variant's train step over the first's
round by round, and each model's forward operations (torch's FLOP count: what a variant costs whatever the load).

    python scripts/bench_models.py                             # 512x512, 2 threads, 3 repeats
    python scripts/bench_models.py --models adabins --size 256 --no-onnx
    python scripts/bench_models.py --models adabins --size 128 --set encoder_name=resnet18 --set patch_size=4 \
        --camera-input none rays --no-onnx --repeats 20 --out docs/figures/camera_input_steps.json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import torch
import yaml
from torch import Tensor, nn
from torch.utils.flop_counter import FlopCounterMode

import models
from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.export import export_onnx, verify_onnx
from airfisheye_bench.geometry.cameras import ideal_camera
from airfisheye_bench.geometry.ray_maps import CAMERA_INPUTS, ray_map
from airfisheye_bench.specs import get_task
from airfisheye_bench.studies.provenance import provenance
from models.losses import AdaBinsLoss, L1L2Loss, SegmentationCELoss, SILogLoss

PAPER_MODELS = ("deeplabv3plus", "adabins", "nlspn")


def make_inputs(
    task: str, batch: int, size: int, device: torch.device, camera_input: str = "none"
) -> dict[str, Tensor]:
    g = torch.Generator().manual_seed(0)
    inputs = {"image": torch.randn(batch, 3, size, size, generator=g)}
    if "sparse_depth" in get_task(task).inputs:  # ~5 % of pixels with a LiDAR-like return
        depth = 1 + 99 * torch.rand(batch, 1, size, size, generator=g)
        inputs["sparse_depth"] = depth * (torch.rand(batch, 1, size, size, generator=g) < 0.05)
    if camera_input == "rays":  # the ray map of the quick start's lens
        inputs["rays"] = ray_map(ideal_camera(size, size, fov_deg=190.0))[None].expand(batch, -1, -1, -1)
    return {k: v.to(device) for k, v in inputs.items()}


def make_target(task: str, batch: int, size: int, device: torch.device) -> Tensor:
    g = torch.Generator().manual_seed(1)
    if get_task(task).uses_classes:
        return torch.randint(0, 13, (batch, size, size), generator=g).to(device)
    return (1 + 99 * torch.rand(batch, 1, size, size, generator=g)).to(device)


def make_loss(task: str, outputs: dict[str, Tensor]) -> Callable[[dict[str, Tensor], Tensor], Tensor]:
    if task == "seg":
        ce = SegmentationCELoss()
        return lambda out, target: ce(out["logits"], target)
    if "bin_edges" in outputs:
        return AdaBinsLoss()
    if task == "completion":
        l1l2 = L1L2Loss()
        return lambda out, target: l1l2(out["depth"], target)
    silog = SILogLoss()
    return lambda out, target: silog(out["depth"], target)


def rounds_ms(
    fns: dict[str, Callable[[], object]], repeats: int, device: torch.device
) -> dict[str, list[float]]:
    """The wall time of each of ``fns`` in each of ``repeats`` rounds, a round calling every one once, in turn
    (after a warm-up call of each): variants timed side by side see the same drift of the machine's load."""

    def sync() -> None:
        if device.type == "cuda":
            torch.cuda.synchronize(device)

    for fn in fns.values():
        fn()  # warm-up
    sync()
    times: dict[str, list[float]] = {key: [] for key in fns}
    for _ in range(repeats):
        for key, fn in fns.items():
            start = time.perf_counter()
            fn()
            sync()
            times[key].append((time.perf_counter() - start) * 1e3)
    return times


def paired_ratios(times: dict[str, list[float]]) -> dict[str, dict[str, float]]:
    """Each variant's time over the first's, round by round: quartiles ``{q1, median, q3}`` (the first aside)."""
    first, *others = times
    out = {}
    for key in others:
        ratios = [t / f for t, f in zip(times[key], times[first], strict=True)]
        q1, median, q3 = statistics.quantiles(ratios, n=4) if len(ratios) > 1 else ratios * 3
        out[key] = {"q1": q1, "median": median, "q3": q3}
    return out


def bench_device(
    variants: dict[str, nn.Module],
    task: str,
    args: argparse.Namespace,
    device: torch.device,
    train: bool = True,
) -> tuple[dict[str, tuple[float, float]], dict[str, dict[str, float]]]:
    """``{camera_input: (forward ms, train-step ms or nan)}`` of a model's variants on ``device``, and each variant's
    train step over the first's, round by round (:func:`paired_ratios`)."""
    forward, steps = {}, {}
    for camera_input, model in variants.items():
        model.to(device).eval()
        inputs = make_inputs(task, args.batch, args.size, device, camera_input)
        forward[camera_input] = torch.no_grad()(lambda model=model, inputs=inputs: model(**inputs))
    forward_ms = {key: statistics.median(t) for key, t in rounds_ms(forward, args.repeats, device).items()}
    if not train:
        return {key: (forward_ms[key], float("nan")) for key in variants}, {}
    for camera_input, model in variants.items():
        model.train()
        train_inputs = make_inputs(task, args.train_batch, args.size, device, camera_input)
        target = make_target(task, args.train_batch, args.size, device)
        loss_fn = make_loss(task, model.forward_with_aux(**train_inputs))
        optimizer = torch.optim.AdamW(model.parameters(), lr=1e-4)

        def step(
            model=model, optimizer=optimizer, loss_fn=loss_fn, inputs=train_inputs, target=target
        ) -> None:
            optimizer.zero_grad(set_to_none=True)
            loss_fn(model.forward_with_aux(**inputs), target).backward()
            optimizer.step()

        steps[camera_input] = step
    train_times = rounds_ms(steps, args.repeats, device)
    train_ms = {key: statistics.median(t) for key, t in train_times.items()}
    for model in variants.values():
        model.to("cpu")
    return {key: (forward_ms[key], train_ms[key]) for key in variants}, paired_ratios(train_times)


def forward_gflop(model: nn.Module, task: str, args: argparse.Namespace, camera_input: str) -> float:
    """Floating-point operations of one forward pass at the forward batch, in GFLOP (torch's count: a multiply-add
    is two), on CPU: what a variant costs whatever the machine's load."""
    model = model.cpu().eval()
    inputs = make_inputs(task, args.batch, args.size, torch.device("cpu"), camera_input)
    counter = FlopCounterMode(display=False)
    with torch.no_grad(), counter:
        model(**inputs)
    return counter.get_total_flops() / 1e9


def bench_onnx(
    model: nn.Module, name: str, task: str, args: argparse.Namespace, camera_input: str = "none"
) -> tuple[float, float]:
    """(ORT / eager latency ratio, max abs diff) on CPU."""
    model = model.cpu().eval()
    primary = get_task(task).output
    cpu = torch.device("cpu")
    with tempfile.TemporaryDirectory() as tmp:
        path = export_onnx(
            model,
            make_inputs(task, 2, args.size, cpu, camera_input),
            Path(tmp) / f"{name}.onnx",
            output_name=primary,
        )
        report = verify_onnx(
            path,
            model,
            make_inputs(task, args.batch, args.size, cpu, camera_input),
            atol=1e-3,
            rtol=1e-3,
            repeats=args.repeats,
        )
    return report.latency_ratio, report.max_abs_diff


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--models",
        nargs="+",
        default=list(PAPER_MODELS),
        help="registered names (paper defaults are used); unregistered ones are skipped",
    )
    parser.add_argument("--size", type=int, default=512, help="square input side in pixels")
    parser.add_argument("--batch", type=int, default=1, help="batch of the forward / ONNX timings")
    parser.add_argument("--train-batch", type=int, default=2, help="batch of the train-step timing")
    parser.add_argument("--threads", type=int, default=2, help="torch (and ONNX Runtime) CPU threads")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-onnx", action="store_true", help="skip the ONNX export and ORT timing")
    parser.add_argument("--no-cpu-train", action="store_true", help="skip the (slow) CPU train-step timing")
    parser.add_argument(
        "--camera-input",
        nargs="+",
        choices=CAMERA_INPUTS,
        default=["none"],
        help="build each model with these model.camera_input values and time them side by side",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a constructor argument of every model (YAML value), e.g. encoder_name=resnet18",
    )
    parser.add_argument("--out", type=Path, help="also write the table as JSON with its provenance")
    args = parser.parse_args()
    if args.train_batch < 2:
        parser.error("--train-batch must be >= 2 (BatchNorm in training mode needs more than one value)")
    torch.set_num_threads(args.threads)
    cuda = torch.device("cuda") if torch.cuda.is_available() else None

    overrides = dict(_setting(item, parser) for item in args.set)
    nan = float("nan")
    rows, paired, flops = [], {}, {}
    for name in args.models:
        if name.lower() not in models.list_models():
            print(f"skipping {name!r}: not registered")
            continue
        task = models.model_task(name)
        variants = {}
        for camera_input in dict.fromkeys(args.camera_input):
            torch.manual_seed(0)
            variants[camera_input] = models.create_model(name, **overrides, camera_input=camera_input)
        cpu, cpu_paired = bench_device(variants, task, args, torch.device("cpu"), train=not args.no_cpu_train)
        gpu, gpu_paired = (
            bench_device(variants, task, args, cuda) if cuda else ({k: (nan, nan) for k in variants}, {})
        )
        for camera_input, model in variants.items():
            params = sum(p.numel() for p in model.parameters()) / 1e6
            onnx = (nan, nan) if args.no_onnx else bench_onnx(model, name, task, args, camera_input)
            label = name if camera_input == "none" else f"{name} (camera_input={camera_input})"
            rows.append((label, params, *cpu[camera_input], *gpu[camera_input], *onnx))
            flops[label] = forward_gflop(model, task, args, camera_input)
            if camera_input in cpu_paired or camera_input in gpu_paired:
                paired[label] = {"cpu": cpu_paired.get(camera_input), "gpu": gpu_paired.get(camera_input)}
        print(f"done {name}", flush=True)

    gpu_name = torch.cuda.get_device_name(0) if cuda else "no GPU"
    settings = (
        f"{args.size}x{args.size}, forward/ONNX batch {args.batch}, train batch {args.train_batch}, "
        f"CPU {args.threads} threads, median of {args.repeats}; GPU: {gpu_name}"
    )
    print(f"\n{settings}\n")
    print(
        "| model | params (M) | CPU fwd (ms) | CPU train step (ms) | GPU fwd (ms) | GPU train step (ms) "
        "| ORT / eager (CPU) | ONNX max abs diff |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, params, cf, ct, gf, gt, ratio, diff in rows:
        print(
            f"| {name} | {params:.1f} | {_fmt(cf)} | {_fmt(ct)} | {_fmt(gf, 1)} | {_fmt(gt, 1)} "
            f"| {_fmt(ratio, 2)} | {_fmt(diff, 'e')} |"
        )

    if args.out is not None:
        _write(args, rows, paired, flops, settings, overrides)


_COLUMNS = ("model", "params_m", "cpu_fwd_ms", "cpu_train_step_ms", "gpu_fwd_ms", "gpu_train_step_ms")


def _write(
    args: argparse.Namespace, rows: list[tuple], paired: dict, flops: dict, settings: str, overrides: dict
) -> None:
    """The table as JSON (``nan`` as null), with the commit, command and machine it comes from, the load averages
    of the machine at the end (a shared machine's timings mean little without them) and, for each variant beyond a
    model's first, its train step over the first's in the same round (quartiles over the rounds)."""
    columns = (*_COLUMNS, "ort_over_eager", "onnx_max_abs_diff")
    record = {
        **provenance("scripts/bench_models.py"),
        "settings": settings,
        "model_arguments": overrides,
        "camera_inputs": list(dict.fromkeys(args.camera_input)),
        "load_average_at_end": list(os.getloadavg()),
        "rows": [{c: (None if v != v else v) for c, v in zip(columns, row, strict=True)} for row in rows],
        "train_step_over_first_variant": paired,
        "forward_gflop": flops,
    }
    atomic_write_text(args.out, json.dumps(record, indent=2) + "\n")
    print(f"wrote {args.out}")


def _setting(item: str, parser: argparse.ArgumentParser) -> tuple[str, object]:
    key, sep, value = item.partition("=")
    if not sep or not key:
        parser.error(f"--set {item}: expected KEY=VALUE")
    return key, yaml.safe_load(value)


def _fmt(value: float, digits: int | str = 0) -> str:
    if value != value:  # nan
        return "–"
    return f"{value:.1e}" if digits == "e" else f"{value:.{digits}f}"


if __name__ == "__main__":
    main()
