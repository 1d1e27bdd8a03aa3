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

    python scripts/bench_models.py                             # 512x512, 2 threads, 3 repeats
    python scripts/bench_models.py --models adabins --size 256 --no-onnx
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import torch
from torch import Tensor, nn

import models
from airfisheye_bench.export import export_onnx, verify_onnx
from airfisheye_bench.specs import get_task
from models.losses import AdaBinsLoss, SegmentationCELoss, SILogLoss

PAPER_MODELS = ("deeplabv3plus", "adabins", "nlspn")


def make_inputs(task: str, batch: int, size: int, device: torch.device) -> dict[str, Tensor]:
    g = torch.Generator().manual_seed(0)
    inputs = {"image": torch.randn(batch, 3, size, size, generator=g)}
    if "sparse_depth" in get_task(task).inputs:  # ~5 % of pixels with a LiDAR-like return
        depth = 1 + 99 * torch.rand(batch, 1, size, size, generator=g)
        inputs["sparse_depth"] = depth * (torch.rand(batch, 1, size, size, generator=g) < 0.05)
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
        from models.losses import L1L2Loss

        l1l2 = L1L2Loss()
        return lambda out, target: l1l2(out["depth"], target)
    silog = SILogLoss()
    return lambda out, target: silog(out["depth"], target)


def median_ms(fn: Callable[[], object], repeats: int, device: torch.device) -> float:
    def sync() -> None:
        if device.type == "cuda":
            torch.cuda.synchronize(device)

    fn()  # warm-up
    sync()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        sync()
        times.append((time.perf_counter() - start) * 1e3)
    return statistics.median(times)


def bench_device(
    model: nn.Module, task: str, args: argparse.Namespace, device: torch.device, train: bool = True
) -> tuple[float, float]:
    """(forward ms, train-step ms or nan) on ``device``."""
    model = model.to(device)
    inputs = make_inputs(task, args.batch, args.size, device)
    model.eval()
    with torch.no_grad():
        forward_ms = median_ms(lambda: model(**inputs), args.repeats, device)
    if not train:
        model.to("cpu")
        return forward_ms, float("nan")

    model.train()
    train_inputs = make_inputs(task, args.train_batch, args.size, device)
    target = make_target(task, args.train_batch, args.size, device)
    loss_fn = make_loss(task, model.forward_with_aux(**train_inputs))
    optimizer = torch.optim.AdamW(model.parameters(), lr=1e-4)

    def step() -> None:
        optimizer.zero_grad(set_to_none=True)
        loss_fn(model.forward_with_aux(**train_inputs), target).backward()
        optimizer.step()

    train_ms = median_ms(step, args.repeats, device)
    model.to("cpu")
    return forward_ms, train_ms


def bench_onnx(model: nn.Module, name: str, task: str, args: argparse.Namespace) -> tuple[float, float]:
    """(ORT / eager latency ratio, max abs diff) on CPU."""
    model = model.cpu().eval()
    primary = get_task(task).output
    with tempfile.TemporaryDirectory() as tmp:
        path = export_onnx(
            model,
            make_inputs(task, 2, args.size, torch.device("cpu")),
            Path(tmp) / f"{name}.onnx",
            output_name=primary,
        )
        report = verify_onnx(
            path,
            model,
            make_inputs(task, args.batch, args.size, torch.device("cpu")),
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
    args = parser.parse_args()
    if args.train_batch < 2:
        parser.error("--train-batch must be >= 2 (BatchNorm in training mode needs more than one value)")
    torch.set_num_threads(args.threads)
    cuda = torch.device("cuda") if torch.cuda.is_available() else None

    rows = []
    for name in args.models:
        if name.lower() not in models.list_models():
            print(f"skipping {name!r}: not registered")
            continue
        task = models.model_task(name)
        torch.manual_seed(0)
        model = models.create_model(name)
        params = sum(p.numel() for p in model.parameters()) / 1e6
        cpu_fwd, cpu_train = bench_device(model, task, args, torch.device("cpu"), train=not args.no_cpu_train)
        gpu_fwd, gpu_train = bench_device(model, task, args, cuda) if cuda else (float("nan"), float("nan"))
        ratio, diff = (
            bench_onnx(model, name, task, args) if not args.no_onnx else (float("nan"), float("nan"))
        )
        rows.append((name, params, cpu_fwd, cpu_train, gpu_fwd, gpu_train, ratio, diff))
        print(f"done {name}", flush=True)

    gpu_name = torch.cuda.get_device_name(0) if cuda else "no GPU"
    print(
        f"\n{args.size}x{args.size}, forward/ONNX batch {args.batch}, train batch {args.train_batch}, "
        f"CPU {args.threads} threads, median of {args.repeats}; GPU: {gpu_name}\n"
    )
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


def _fmt(value: float, digits: int | str = 0) -> str:
    if value != value:  # nan
        return "–"
    return f"{value:.1e}" if digits == "e" else f"{value:.{digits}f}"


if __name__ == "__main__":
    main()
