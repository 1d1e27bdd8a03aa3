"""The trained occlusion ablation's per-run records, and their summary with the flight as the unit.

Each finished run of :mod:`airfisheye_bench.studies.occlusion_ablation` leaves one small JSON under the record
folder (``docs/figures/occlusion_ablation/<method>_seed<s>.json``): the commit and command it was trained with,
the data's identity, its test metrics, its validation curve (to show it had flattened) and its best checkpoint's
per-frame scores on every region of :data:`~airfisheye_bench.studies.crossover.FRAME_REGIONS`. The study is
the set of these files: :func:`summarise` reads nothing else, so it never depends on a run folder that was not
committed, and it grows run by run across sessions.

The summary (:func:`summarise`):

* per arm, each metric's mean and sample standard deviation over the seeds (a seed's value: the mean over its
  test frames, as the task metric);
* per arm against ``none``, paired by seed and frame: per test flight, the mean over its frames and the seeds of
  ``arm - none``; the mean over the flights with a t-interval over the flights (``n`` = flights), its p-value,
  Holm-adjusted over the whole family (every arm x metric reported) and the Bonferroni interval at the family's
  level (:mod:`airfisheye_bench.studies.clustered`); beside it, the mean difference per seed, whose spread is
  what the training noise alone does;
* per run (:func:`run_overview`): how its training went (epochs, whether early stopping ended it, its validation
  RMSE first, best and last, its test RMSE) and what it cost (running time over its segments).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from airfisheye_bench.studies.clustered import cluster_difference, flight_of, holm, sign_test_p
from airfisheye_bench.studies.provenance import records_of_format

__all__ = [
    "FAMILY_METRICS",
    "build_record",
    "load_records",
    "mean_std",
    "means_table",
    "paired_table",
    "report_block",
    "run_overview",
    "running_time",
    "runs_table",
    "summarise",
    "summary_tables",
    "validation_curve",
]

RECORD_FORMAT = "airfisheye-ablation-run/1"
#: The paired comparisons of the family (``region/metric``), Holm-corrected together across the arms.
FAMILY_METRICS = ("all/rmse", "changed/rmse", "near/rmse", "all/mae", "changed/mae")


def validation_curve(metrics_csv: str | Path, metric: str) -> list[dict[str, float]]:
    """``[{"epoch", metric}]`` of a run's ``metrics.csv`` (the validation rows, in order)."""
    path = Path(metrics_csv)
    if not path.is_file():
        return []
    with path.open(newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    return [
        {"epoch": int(float(r["epoch"])), metric: float(r[metric])}
        for r in rows
        if r.get(metric) not in (None, "")
    ]


def build_record(
    method: str,
    seed: int,
    provenance: Mapping[str, Any],
    results: Mapping[str, Any],
    frames: Mapping[str, Any],
    curve: Sequence[Mapping[str, float]],
    wall_s: float | None,
) -> dict[str, Any]:
    """One run's record (see the module docstring)."""
    return {
        "format": RECORD_FORMAT,
        "method": method,
        "seed": int(seed),
        "provenance": dict(provenance),
        "dataset": results.get("dataset"),
        "metrics": results.get("metrics"),
        "checkpoint": Path(str(frames.get("checkpoint", ""))).name,
        "epochs_trained": (max(int(c["epoch"]) for c in curve) + 1) if curve else None,
        "validation_curve": list(curve),
        "wall_s": wall_s,
        "radius_px": frames.get("radius_px"),
        "near_m": frames.get("near_m"),
        "frames": frames["frames"],
    }


def load_records(folder: str | Path) -> list[dict[str, Any]]:
    """Every run record under ``folder`` (sorted by method and seed)."""
    return sorted(records_of_format(folder, RECORD_FORMAT), key=lambda r: (r["method"], r["seed"]))


def _frame_values(record: Mapping[str, Any], name: str) -> dict[str, float]:
    region, metric = name.split("/")
    return {
        row["sample_id"]: float(row["regions"][region][metric])
        for row in record["frames"]
        if region in row["regions"]
    }


def mean_std(values: Sequence[float]) -> dict[str, float]:
    """Mean and sample standard deviation (``ddof = 1``; NaN for a single value).

    Example:
        >>> mean_std([1.0, 2.0, 3.0])
        {'mean': 2.0, 'std': 1.0, 'n': 3}
    """
    n = len(values)
    mean = sum(values) / n
    std = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1)) if n > 1 else math.nan
    return {"mean": mean, "std": std, "n": n}


def summarise(
    records: Iterable[Mapping[str, Any]], reference: str = "none", metrics: Sequence[str] = FAMILY_METRICS
) -> dict[str, Any]:
    """Per-arm means over the seeds and flight-clustered paired differences against ``reference``, Holm-adjusted
    across every (arm, metric) of the family. Only seeds that the arm and the reference both have are paired."""
    by_arm: dict[str, dict[int, Mapping[str, Any]]] = {}
    for record in records:
        by_arm.setdefault(record["method"], {})[int(record["seed"])] = record
    arms: dict[str, Any] = {}
    for arm, runs in by_arm.items():
        per_metric = {}
        for name in metrics:
            seed_means = []
            for record in runs.values():
                values = _frame_values(record, name)
                if values:
                    seed_means.append(sum(values.values()) / len(values))
            if seed_means:
                per_metric[name] = mean_std(seed_means)
        arms[arm] = {
            "seeds": sorted(runs),
            "epochs_trained": [runs[s].get("epochs_trained") for s in sorted(runs)],
            "metrics": per_metric,
        }
    differences: dict[str, dict[str, Any]] = {}
    if reference in by_arm:
        ref = by_arm[reference]
        for arm, runs in by_arm.items():
            if arm == reference:
                continue
            seeds = sorted(set(runs) & set(ref))
            if not seeds:
                continue
            differences[arm] = {}
            for name in metrics:
                per_flight: dict[str, list[float]] = {}
                per_seed: list[float] = []
                for seed in seeds:
                    a, r = _frame_values(runs[seed], name), _frame_values(ref[seed], name)
                    shared = sorted(set(a) & set(r))
                    if not shared:
                        continue
                    frame_diffs: dict[str, list[float]] = {}
                    for sample_id in shared:
                        frame_diffs.setdefault(flight_of(sample_id), []).append(a[sample_id] - r[sample_id])
                    for flight, d in frame_diffs.items():
                        per_flight.setdefault(flight, []).append(sum(d) / len(d))
                    per_seed.append(sum(a[s] - r[s] for s in shared) / len(shared))
                if per_flight:
                    flights = {f: sum(v) / len(v) for f, v in sorted(per_flight.items())}
                    differences[arm][name] = {"seeds": seeds, "per_flight": flights, "per_seed": per_seed}
    family = sum(len(m) for m in differences.values())
    for by_metric in differences.values():
        for entry in by_metric.values():
            entry.update(cluster_difference(entry["per_flight"], family_size=family))
            entry["seed_spread"] = mean_std(entry["per_seed"])
            # Secondary, chosen after the results were seen: how consistently the sign holds, flight by flight.
            entry["post_hoc_sign_test_p"] = sign_test_p(list(entry["per_flight"].values()))
    adjusted = holm({f"{arm}|{name}": e["p"] for arm, m in differences.items() for name, e in m.items()})
    for key, p in adjusted.items():
        arm, name = key.split("|")
        differences[arm][name]["p_holm"] = p
    return {
        "reference": reference,
        "family_size": family,
        "arms": arms,
        "paired": differences,
        "runs": [run_overview(r) for arm in by_arm.values() for r in arm.values()],
    }


def run_overview(record: Mapping[str, Any], metric: str = "val/rmse") -> dict[str, Any]:
    """How a recorded run trained and what it cost: epochs (of the command's ``trainer.max_epochs``; fewer: early
    stopping ended it), the validation ``metric`` after the first epoch, at its best (1-based epoch, the checkpoint
    tested) and after the last, the test RMSE, and the running time summed over its segments (a segment's
    ``wall_s`` less the time it was stopped, ``paused_s``; a cut segment's ``span_s`` from its log, or its
    ``fit_wall_s``), ``None`` where a segment states none.

    Example:
        >>> record = {"method": "none", "seed": 0, "metrics": {"rmse": 7.5}, "epochs_trained": 3,
        ...           "validation_curve": [{"epoch": e, "val/rmse": v} for e, v in enumerate([9.0, 7.0, 8.0])],
        ...           "provenance": {"command": "python train.py trainer.max_epochs=30", "segments": [
        ...               {"span_s": 100.0}, {"wall_s": 500.0, "paused_s": 200.0}]}}
        >>> o = run_overview(record)
        >>> o["early_stopped"], o["best_epoch"], o["val_best"], o["running_s"], o["segments"]
        (True, 2, 7.0, 400.0, 2)
    """
    curve = [float(c[metric]) for c in record.get("validation_curve") or []]
    best = min(range(len(curve)), key=curve.__getitem__) if curve else None
    provenance = record.get("provenance") or {}
    overrides = dict(arg.split("=", 1) for arg in str(provenance.get("command", "")).split() if "=" in arg)
    max_epochs = int(overrides["trainer.max_epochs"]) if "trainer.max_epochs" in overrides else None
    segments = provenance.get("segments") or [{"wall_s": record.get("wall_s")}]
    epochs = record.get("epochs_trained")
    return {
        "method": record["method"],
        "seed": int(record["seed"]),
        "epochs_trained": epochs,
        "max_epochs": max_epochs,
        "early_stopped": None if epochs is None or max_epochs is None else epochs < max_epochs,
        "val_first": curve[0] if curve else None,
        "val_best": curve[best] if best is not None else None,
        "best_epoch": best + 1 if best is not None else None,
        "val_last": curve[-1] if curve else None,
        "test_rmse": (record.get("metrics") or {}).get("rmse"),
        "running_s": running_time(segments),
        "segments": len(segments),
    }


def running_time(segments: Iterable[Mapping[str, Any]]) -> float | None:
    """A run's running time summed over its segments (:func:`_running_s`), or ``None`` when a segment's is
    unknown (one killed before it could write it): an unknown part is never counted as 0.

    Example:
        >>> running_time([{"wall_s": 10.0}, {"wall_s": 5.0, "paused_s": 2.5}])
        12.5
        >>> running_time([{"wall_s": 10.0}, {}]) is None
        True
    """
    running = [_running_s(segment) for segment in segments]
    return None if None in running else sum(running)


def _running_s(segment: Mapping[str, Any]) -> float | None:
    """How long one segment ran: its wall time less any time it was stopped; a cut one's span or fit time."""
    if segment.get("wall_s") is not None:
        return float(segment["wall_s"]) - float(segment.get("paused_s") or 0.0)
    for key in ("span_s", "fit_wall_s"):
        if segment.get(key) is not None:
            return float(segment[key])
    return None


def runs_table(overviews: Iterable[Mapping[str, Any]]) -> str:
    """Markdown: one row per recorded run, from its :func:`run_overview` (the summary's ``runs``)."""
    lines = [
        "| input | seed | epochs | ended by | val RMSE: first, best (epoch), last | test RMSE | running time (segments) |",
        "|---|---:|---:|---|---|---:|---|",
    ]
    for o in overviews:
        ended = "-" if o["early_stopped"] is None else "early stopping" if o["early_stopped"] else "the cap"
        val = (
            f"{o['val_first']:.2f}, {o['val_best']:.2f} ({o['best_epoch']}), {o['val_last']:.2f}"
            if o["val_best"] is not None
            else "-"
        )
        test = "-" if o["test_rmse"] is None else f"{o['test_rmse']:.3f}"
        running = "-" if o["running_s"] is None else f"{o['running_s']:,.0f} s"
        lines.append(
            f"| `{o['method']}` | {o['seed']} | {o['epochs_trained']} | {ended} | {val} | {test} "
            f"| {running} ({o['segments']}) |"
        )
    return "\n".join(lines)


#: How a score of the family reads in a table.
METRIC_LABELS = {
    "all/rmse": "RMSE, whole image",
    "changed/rmse": "RMSE, `changed`",
    "near/rmse": "RMSE, < 20 m",
    "all/mae": "MAE, whole image",
    "changed/mae": "MAE, `changed`",
}

#: The report's generated block (``scripts/occlusion_ablation.py --collect-only --report``).
REPORT_BEGIN = (
    "<!-- ablation-summary:begin (generated by scripts/occlusion_ablation.py --collect-only --report from "
    "docs/figures/occlusion_ablation/summary.json; do not edit) -->"
)
REPORT_END = "<!-- ablation-summary:end -->"


def means_table(summary: Mapping[str, Any], metrics: Sequence[str] = FAMILY_METRICS) -> str:
    """Markdown: per arm, each score's mean ± sample standard deviation over its seeds (metres)."""
    lines = [
        "| input | seeds | epochs | " + " | ".join(METRIC_LABELS.get(m, m) for m in metrics) + " |",
        "|---|---|---|" + "---:|" * len(metrics),
    ]
    for arm, entry in summary["arms"].items():
        cells = []
        for name in metrics:
            stat = entry["metrics"].get(name)
            cells.append(
                "-"
                if stat is None
                else f"{stat['mean']:.3f}"
                if math.isnan(stat["std"])
                else f"{stat['mean']:.3f} ± {stat['std']:.3f}"
            )
        seeds = ",".join(str(s) for s in entry["seeds"])
        epochs = ",".join(str(e) for e in entry["epochs_trained"])
        lines.append(f"| `{arm}` | {seeds} | {epochs} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def paired_table(summary: Mapping[str, Any], metrics: Sequence[str] = FAMILY_METRICS) -> str:
    """Markdown: one row per comparison of the family (arm x score) against the reference: the mean over the test
    flights of ``arm - reference``, its 95 % t-interval over the flights, the Bonferroni interval at the family's
    level, the unadjusted and Holm-adjusted p-values, the minimum detectable effect (80 % power; alone, and at the
    family's level), the flight that differs most and the range of the others, and the per-seed differences (what
    the training noise alone does)."""
    reference = summary["reference"]
    lines = [
        f"| input − `{reference}` | score | seeds | mean | 95 % over flights | family-wise "
        f"({summary['family_size']}) | p | Holm p | detectable (80 %): alone; family | most different flight; "
        "the others | per seed |",
        "|---|---|---|---:|---|---|---:|---:|---|---|---|",
    ]
    for arm, by_metric in summary["paired"].items():
        for name in metrics:
            d = by_metric.get(name)
            if d is None:
                continue
            seeds = ",".join(str(s) for s in d["seeds"])
            per_seed = ", ".join(_minus(f"{v:+.3f}") for v in d["per_seed"])
            if math.isnan(d["ci"][0]):  # one flight: no interval
                cells = ["-", "-", "-", "-", "-"]
            else:
                (lo, hi), (flo, fhi) = d["ci"], d["ci_family"]
                cells = [
                    _minus(f"[{lo:+.3f}, {hi:+.3f}]"),
                    _minus(f"[{flo:+.3f}, {fhi:+.3f}]"),
                    f"{d['p']:.2g}",
                    f"{d['p_holm']:.2g}",
                    f"{d['mde']:.3f}; {d['mde_family']:.3f}",
                ]
            lines.append(
                f"| `{arm}` | {METRIC_LABELS.get(name, name)} | {seeds} | {_minus(format(d['mean'], '+.3f'))} | "
                + " | ".join(cells)
                + f" | {_flights_cell(d['per_flight'])} | {per_seed} |"
            )
    return "\n".join(lines)


def _flights_cell(per_flight: Mapping[str, float]) -> str:
    """``downtown/traj07 +1.21; −0.45 to +0.39``: the flight farthest from 0, and the range of the others.

    Example:
        >>> _flights_cell({"a/traj01": 0.1, "b/traj02": -2.0, "c/traj03": 0.3})
        '`b/traj02` −2.00; +0.10 to +0.30'
    """
    worst = max(per_flight, key=lambda flight: abs(per_flight[flight]))
    others = [v for flight, v in per_flight.items() if flight != worst]
    rest = _minus(f"; {min(others):+.2f} to {max(others):+.2f}") if others else ""
    return f"`{worst}` {_minus(format(per_flight[worst], '+.2f'))}{rest}"


def _minus(text: str) -> str:
    """Signed numbers with the typographic minus (U+2212), as the report writes them."""
    return text.replace("-", "\u2212")


def summary_tables(summary: Mapping[str, Any], metrics: Sequence[str] = FAMILY_METRICS) -> str:
    """Markdown: the arms' means ± seed std, then the paired differences with their intervals."""
    return "\n\n".join([means_table(summary, metrics), paired_table(summary, metrics)])


def report_block(summary: Mapping[str, Any], source: str = "figures/occlusion_ablation/summary.json") -> str:
    """What ``docs/results.md`` shows of the summary between :data:`REPORT_BEGIN` and :data:`REPORT_END`: the
    summary it comes from (path, commit), the runs, the arms' means and the family of paired comparisons."""
    commit = summary["provenance"]["commit"]
    n = len(summary["records"])
    return "\n\n".join(
        [
            f"From [`summary.json`]({source}) ({n} run records; written at commit `{commit}`). The runs:",
            runs_table(summary["runs"]),
            "Test scores per arm, mean ± standard deviation over its seeds (metres; a seed's score is the mean over "
            "the test frames):",
            means_table(summary),
            f"Each arm against `{summary['reference']}` on the seeds both have: per test flight the mean over its "
            "frames and the paired seeds; the mean over the flights with its 95 % t-interval over the flights and "
            f"the Bonferroni interval over the family of {summary['family_size']} comparisons, the unadjusted and "
            "Holm-adjusted p-values, the minimum detectable effect (the smallest true difference the comparison "
            "finds with 80 % power, over these flights: alone at 5 %, and at the family's Bonferroni level), the "
            "flight that differs most and the range of the others (metres), and each seed's difference over all "
            "test frames:",
            paired_table(summary),
        ]
    )
