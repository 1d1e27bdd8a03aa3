"""NLSPN on CPU: the two propagation implementations, eager PyTorch vs ONNX Runtime, 1 and 2 threads.

For each ``propagation_impl`` (``grid_sample``, ``deform_conv``) builds the paper configuration (ResNet34,
18 steps, TGASS, 8 neighbours; random weights, the offset/affinity conv perturbed so propagation is not the
identity) and measures, at batch 1 and ``--size`` x ``--size``:

- propagation only (``NonLocalPropagation``: offsets, affinities and the 18 steps), eager;
- the whole network, eager (eval, ``torch.no_grad``);
- the whole network in ONNX Runtime (CPU EP; exported once, dynamic batch) and its max relative difference
  to eager on pixels with depth > 1 m.

Median of ``--repeats`` after a warm-up. Prints a markdown table.

    python scripts/bench_nlspn.py                    # 512x512, threads 1 and 2
    python scripts/bench_nlspn.py --size 256 --no-onnx
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from airfisheye_bench.export import export_onnx
from models.nlspn import NLSPN, PROPAGATION_IMPLS


def make_inputs(batch: int, size: int) -> dict[str, Tensor]:
    g = torch.Generator().manual_seed(0)
    depth = 1 + 99 * torch.rand(batch, 1, size, size, generator=g)
    return {
        "image": torch.randn(batch, 3, size, size, generator=g),
        "sparse_depth": depth * (torch.rand(batch, 1, size, size, generator=g) < 0.05),  # ~5 % LiDAR returns
    }


def median_ms(fn: Callable[[], object], repeats: int) -> float:
    fn()  # warm-up
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append((time.perf_counter() - start) * 1e3)
    return statistics.median(times)


def build(impl: str) -> NLSPN:
    torch.manual_seed(0)
    model = NLSPN(propagation_impl=impl).eval()
    with (
        torch.no_grad()
    ):  # trained-like: offsets of about a pixel, positive affinities (a stable propagation)
        conv, n = model.prop_layer.conv_offset_aff, model.prop_layer.num_neighbours
        conv.weight.normal_(0.0, 0.3 / conv.weight[0].numel() ** 0.5)
        conv.weight[2 * n :] *= 0.2
        conv.bias[: 2 * n].normal_(0.0, 1.0)
        conv.bias[2 * n :].uniform_(0.5, 2.0)
    return model


def propagation_inputs(model: NLSPN, inputs: dict[str, Tensor]) -> tuple[Tensor, ...]:
    with torch.no_grad():
        aux = model.forward_with_aux(**inputs)
    return aux["initial_depth"], aux["guidance"], aux["confidence"], inputs["sparse_depth"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-onnx", action="store_true")
    args = parser.parse_args()

    inputs = make_inputs(1, args.size)
    rows = []
    for impl in PROPAGATION_IMPLS:
        model = build(impl)
        params = sum(p.numel() for p in model.parameters())
        prop_args = propagation_inputs(model, inputs)
        session_path = None
        tmp = tempfile.TemporaryDirectory()
        if not args.no_onnx:
            session_path = export_onnx(
                model, make_inputs(2, args.size), Path(tmp.name) / f"nlspn_{impl}.onnx", "depth"
            )
        for threads in args.threads:
            torch.set_num_threads(threads)
            with torch.no_grad():
                prop_ms = median_ms(lambda m=model, a=prop_args: m.prop_layer(*a), args.repeats)
                eager_ms = median_ms(lambda m=model: m(**inputs), args.repeats)
                expected = model(**inputs).numpy()
            ort_ms, rel = float("nan"), float("nan")
            if session_path is not None:
                import onnxruntime as ort

                options = ort.SessionOptions()
                options.intra_op_num_threads = threads
                options.inter_op_num_threads = 1
                session = ort.InferenceSession(str(session_path), options, providers=["CPUExecutionProvider"])
                feed = {k: v.numpy() for k, v in inputs.items()}
                ort_ms = median_ms(lambda s=session, f=feed: s.run(None, f), args.repeats)
                actual = session.run(None, feed)[0]
                far = expected > 1.0
                rel = float((np.abs(actual - expected)[far] / expected[far]).max())
            rows.append((impl, threads, params, prop_ms, eager_ms, ort_ms, rel))
            print(f"done {impl} threads={threads}", flush=True)
        tmp.cleanup()

    print(f"\nNLSPN paper configuration, {args.size}x{args.size}, batch 1, CPU, median of {args.repeats}\n")
    print("| propagation | threads | params (M) | propagation eager (ms) | network eager (ms) | network ORT (ms) "
          "| ORT max rel diff (depth > 1 m) |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|---:|")
    for impl, threads, params, prop_ms, eager_ms, ort_ms, rel in rows:
        print(
            f"| {impl} | {threads} | {params / 1e6:.2f} | {prop_ms:.0f} | {eager_ms:.0f} | {_fmt(ort_ms)} "
            f"| {_fmt(rel, 'e')} |"
        )


def _fmt(value: float, digits: int | str = 0) -> str:
    if value != value:  # nan
        return "–"
    return f"{value:.1e}" if digits == "e" else f"{value:.{digits}f}"


if __name__ == "__main__":
    main()
