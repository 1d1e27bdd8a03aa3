"""Probe AdaBins training on the quick-start data: where the bins and the predictions go, step by step.

A small, cheap stand-in for ``python train.py task=depth``: the quick-start model and data, the whole training split
cached in memory once (one pass of the loader, augmentation as in training), then a plain AdamW + OneCycle loop
that prints, every ``every`` steps, the SI and Chamfer losses, the gradient norm, the predicted and true mean depth
of the batch, the median bin centre and the widest bin; every 4th time also the RMSE, AbsRel and δ1 on the first
96 validation frames, in eval mode and in train mode (BatchNorm with batch statistics).

    python scripts/depth_probe.py steps=300 small=1 wch=0.1 tag=S0     # with the bins' Chamfer term (upstream)
    python scripts/depth_probe.py steps=300 small=1 wch=0 tag=S2       # without it
    python scripts/depth_probe.py steps=300 small=1 wch=0.1 chref=10   # the term range-normalised to 10 m

``small=1`` halves the resolution (64², mini-ViT patch 2, so the same 256 patches) to make a run ~4x cheaper;
``cache=FILE`` is where the batches are kept (default ``/tmp/depth_probe_batches.pt``; it names the dataset it was
read from, and another dataset's cache is refused); ``chref`` is the Chamfer term's ``reference_range`` (m; 0 =
metres, as upstream); ``lr``, ``wd``, ``clip`` (gradient norm, 0 = off), ``seed`` (the network's initialisation;
the batches are the cache's) and ``threads`` as named. ``json=FILE`` also writes every printed line's numbers, with
the commit, command and dataset identity. ``docs/results.md`` section 2.1 quotes its output.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from collections.abc import Iterable
from pathlib import Path

import hydra
import torch
import torch.nn.functional as F
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.constants import config_dir
from airfisheye_bench.runs.results import portable_identity
from airfisheye_bench.studies.provenance import provenance
from airfisheye_bench.training import build
from models.losses import AdaBinsLoss


def main(argv: list[str]) -> None:
    args = dict(a.split("=", 1) for a in argv if "=" in a)
    steps, every = int(args.get("steps", 300)), int(args.get("every", 20))
    lr, wd, clip = float(args.get("lr", 3e-4)), float(args.get("wd", 0.1)), float(args.get("clip", 0))
    wch, small, tag = float(args.get("wch", 0.1)), int(args.get("small", 0)), args.get("tag", "probe")
    chref = float(args.get("chref", 0)) or None
    cache = args.get("cache", "/tmp/depth_probe_batches.pt")
    record: dict = {**provenance("scripts/depth_probe.py", argv), "steps": []}
    torch.set_num_threads(int(args.get("threads", 1)))
    overrides = ["task=depth", "data.num_workers=0", "data.persistent_workers=false"]
    if small:
        overrides.append("model.patch_size=2")
    with initialize_config_dir(config_dir=str(config_dir()), version_base=None):
        cfg = compose("train", overrides=overrides)
    torch.manual_seed(int(args.get("seed", 42)))
    if not os.path.exists(cache):
        datamodule, module = build(cfg)
        train = [(b["image"], b["depth"]) for b in datamodule.train_dataloader()]
        datamodule.setup("validate")
        val = [(b["image"], b["depth"]) for _, b in zip(range(6), datamodule.val_dataloader(), strict=False)]
        root = datamodule.dataset_root()
        dataset = portable_identity(root, Path(root).name)
        torch.save({"tr": train, "va": val, "dataset": dataset}, cache)
    else:
        model_cfg = OmegaConf.to_container(cfg.model, resolve=True)
        module = hydra.utils.instantiate(
            cfg.task.module, model=model_cfg, ring_edges_deg=[0, 30, 60, 95], _convert_="partial"
        )
    batches = torch.load(cache)
    if "dataset" not in batches:
        raise SystemExit(f"{cache}: a cache from before caches named their dataset; delete it to rebuild it")
    train, val, record["dataset"] = batches["tr"], batches["va"], batches["dataset"]
    if small:
        train = [(F.avg_pool2d(x, 2), y[..., ::2, ::2].contiguous()) for x, y in train]
        val = [(F.avg_pool2d(x, 2), y[..., ::2, ::2].contiguous()) for x, y in val]
    baseline = _mean_depth_baseline(train, val)
    record["baseline"] = dict(zip(("rmse", "abs_rel", "delta1"), baseline, strict=True))
    print(
        f"{tag} baseline: the training batches' mean depth per pixel scores "
        f"rmse {baseline[0]:.2f} absrel {baseline[1]:.3f} d1 {baseline[2]:.3f}"
    )
    net = module.net
    max_depth = float(cfg.data.max_depth)
    loss_fn = AdaBinsLoss(w_chamfer=wch, min_depth=1e-3, max_depth=max_depth, chamfer_reference_range=chref)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=wd)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=lr, total_steps=steps, pct_start=0.3)
    start = time.time()
    for step in range(steps):
        x, y = train[step % len(train)]
        out = net.forward_with_aux(x)
        terms = loss_fn.terms(out, y)
        opt.zero_grad()
        terms["loss"].backward()
        norm = torch.nn.utils.clip_grad_norm_(net.parameters(), clip if clip > 0 else math.inf)
        opt.step()
        sched.step()
        if step % every and step != steps - 1:
            continue
        pred, valid = out["depth"].detach(), (y > 1e-3) & (y <= 120)
        edges = out["bin_edges"].detach()
        centres = 0.5 * (edges[:, 1:] + edges[:, :-1])
        row = {
            "step": step,
            "lr": opt.param_groups[0]["lr"],
            "silog": terms["silog"].item(),
            "chamfer": terms["chamfer"].item(),
            "grad_norm": float(norm),
            "pred_mean": pred[valid].mean().item(),
            "gt_mean": y[valid].mean().item(),
            "centre_median": centres.median().item(),
            "widest_bin": (edges[:, 1:] - edges[:, :-1]).max().item(),
        }
        line = (
            f"{tag} s{step} lr {row['lr']:.2e} silog {row['silog']:.3f} chamfer {row['chamfer']:.3f} "
            f"gn {row['grad_norm']:.2f} pred {row['pred_mean']:.1f} gt {row['gt_mean']:.1f} "
            f"cmed {row['centre_median']:.1f} wmax {row['widest_bin']:.2f}"
        )
        if step % (4 * every) == 0 or step == steps - 1:
            for mode in ("eval", "train"):
                rmse, abs_rel, delta1 = _validate(net, val, train_mode=mode == "train")
                row[f"val_{mode}"] = {"rmse": rmse, "abs_rel": abs_rel, "delta1": delta1}
                line += f" | val {mode}-mode rmse {rmse:.2f} absrel {abs_rel:.3f} d1 {delta1:.3f}"
        row["t_s"] = round(time.time() - start, 1)
        record["steps"].append(row)
        print(f"{line} t {row['t_s']:.0f}s", flush=True)
    if "json" in args:
        atomic_write_text(Path(args["json"]), json.dumps(record, indent=1) + "\n")


def _mean_depth_baseline(train: list, val: list) -> tuple[float, float, float]:
    """RMSE, AbsRel and δ1 on ``val`` of the per-pixel mean of the valid depths of ``train`` (the trivial baseline;
    pixels never valid get the mean of all)."""
    depths = torch.cat([y for _, y in train])
    valid = (depths > 1e-3) & (depths <= 120)
    total, count = (depths * valid).sum(0), valid.sum(0)
    mean = torch.where(count > 0, total / count.clamp_min(1), depths[valid].mean())
    return _pooled_scores((mean.expand_as(y), y) for _, y in val)


@torch.no_grad()
def _validate(net: torch.nn.Module, val: list, train_mode: bool) -> tuple[float, float, float]:
    net.train(train_mode)
    scores = _pooled_scores((net(x), y) for x, y in val)
    net.train()
    return scores


def _pooled_scores(pairs: Iterable[tuple[torch.Tensor, torch.Tensor]]) -> tuple[float, float, float]:
    """RMSE, AbsRel and δ1 over every valid pixel of ``(prediction, ground truth)`` batches, pooled (the probe's
    quick comparison between settings; the project's metrics average per image: ``airfisheye_bench.metrics``)."""
    sq = rel = hits = n = 0.0
    for pred, y in pairs:
        m = (y > 1e-3) & (y <= 120)
        p, g = pred[m], y[m]
        sq += (p - g).square().sum().item()
        rel += ((p - g).abs() / g).sum().item()
        hits += (torch.maximum(p / g, g / p) < 1.25).sum().item()
        n += m.sum().item()
    return math.sqrt(sq / n), rel / n, hits / n


if __name__ == "__main__":
    main(sys.argv[1:])
