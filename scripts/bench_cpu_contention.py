"""How much a recipe's training step slows when the host's other cores are busy, as a loader's workers keep them.

``python scripts/bench_cpu_contention.py --task seg --busy 0 15 0 15 --out FILE`` on a machine with a GPU: the
recipe (``experiment=paper/<task> trainer=gpu``, random weights) steps on one batch kept on the device (the GPU
campaign's ceiling, :func:`~airfisheye_bench.studies.train_throughput.cached_steps`) while ``N`` processes spin
on the CPU, for each ``N`` of ``--busy`` in order (repeat a value to see the run-to-run spread). A step is launched
from the host: when the loader's workers take every core, the launches wait, and the GPU idles *inside* the step,
which the campaign's idle share between steps does not see. The batch comes from the ``tiny`` preset served at the
recipe's size (generated on first use).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import shlex
import sys
import time
from pathlib import Path

import torch

from airfisheye_bench.atomic import atomic_write_json
from airfisheye_bench.runs.results import portable_identity
from airfisheye_bench.studies.campaign_record import Phase
from airfisheye_bench.studies.gpu_campaign import compose_recipe, kept_batch_stepper, provenance
from airfisheye_bench.studies.train_throughput import cached_steps
from airfisheye_bench.training import build


def _spin(stop) -> None:
    while not stop.is_set():
        pass


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="seg", choices=("seg", "depth", "completion"))
    parser.add_argument(
        "--busy", type=int, nargs="+", default=[0, 15, 0, 15], help="spinning processes, in order"
    )
    parser.add_argument("--window-s", type=float, default=4.0, help="each timed run, at least")
    parser.add_argument("--steps", type=int, default=10, help="each timed run, at least")
    parser.add_argument(
        "overrides", nargs="*", help="more config overrides (a CPU check: data.camera.size=64 ...)"
    )
    parser.add_argument("--commit", default=None, help="the commit measured (default: the checkout's HEAD)")
    parser.add_argument("--out", required=True, help="the JSON record")
    args = parser.parse_args()
    device = torch.device("cuda" if torch.cuda.is_available() else "cpu")
    command = shlex.join(["python", "scripts/bench_cpu_contention.py", *sys.argv[1:]])
    data = ["data.preset=tiny", "data.num_workers=0"]
    cfg = compose_recipe(args.task, [*data, *args.overrides])
    datamodule, module = build(cfg)
    dataset = datamodule.split_dataset("train")
    root = datamodule.dataset_root()
    stepper, batch = kept_batch_stepper(cfg, module, dataset, device)
    batch_size = int(cfg.data.batch_size)
    phase = Phase("contention", time.monotonic() + 3600.0)
    cached_steps(stepper, batch, 3, 1, phase, warm_s=2.0 if device.type == "cuda" else 0.0)  # clocks, cuDNN
    rows = []
    for busy in args.busy:
        stop = mp.Event()
        spinners = [mp.Process(target=_spin, args=(stop,), daemon=True) for _ in range(busy)]
        for p in spinners:
            p.start()
        try:
            time.sleep(0.5 if busy else 0.0)
            row = cached_steps(stepper, batch, 3, args.steps, phase, warm_s=0.5, window_s=args.window_s)
        finally:
            stop.set()
            for p in spinners:
                p.join()
        rows.append({"busy_processes": busy} | row)
        print(f"busy {busy:2d}: {row['step_ms']:.1f} ms/step, {row['images_per_s']:.1f} images/s", flush=True)
    record = {
        "provenance": provenance(command, args.commit, device),
        "recipe": {
            "experiment": f"paper/{args.task}",
            "batch": batch_size,
            "size": int(cfg.data.camera.size),
            "overrides": args.overrides,
        },
        "data": "the tiny preset's training split, served at the recipe's size",
        "dataset": portable_identity(root, "tiny"),
        "cpu_count": os.cpu_count(),
        "rows": rows,
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(args.out, record)


if __name__ == "__main__":
    main()
