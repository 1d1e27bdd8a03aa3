"""Occlusion corrections as detectors of hidden points, with the test flight as the unit.

Scored with the visible points as the positive class (precision, recall and F1 of what a method *keeps*), doing
nothing scores an F1 of 0.97 on a rig where 6 % of the points are hidden: the measure says little about the task.
Here the positive class is the hidden points that project into the image: a method detects one when it removes it.
Per frame (from :func:`airfisheye_bench.studies.occlusion_study.measure_frame`'s counts):

* ``tp`` = hidden points removed = ``hidden - hidden_kept``; ``fn`` = ``hidden_kept``;
* ``fp`` = visible points removed = ``truth - tp_visible`` (``truth``: visible points that project).

Counts are pooled per flight (frames of one flight are not independent), precision / recall / F1 computed per
flight, and each reported as the mean over the flights with a t-interval over the flights; methods are compared
pairwise, flight by flight, with a Holm correction over the pairs (:mod:`airfisheye_bench.studies.clustered`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from typing import Any

from airfisheye_bench.studies.clustered import cluster_difference, holm

__all__ = ["detection_counts", "detection_table", "hidden_detection", "precision_recall_f1", "ratio"]

SCORES = ("precision", "recall", "f1")


def detection_counts(row: Mapping[str, float], hidden: int) -> dict[str, int]:
    """``{"tp", "fp", "fn"}`` of hidden-point detection from a frame's row (``tp`` there: visible points kept).

    Example:
        >>> detection_counts({"tp": 90, "truth": 94, "hidden_kept": 2}, hidden=6)
        {'tp': 4, 'fp': 4, 'fn': 2}
    """
    kept_hidden = int(row["hidden_kept"])
    return {"tp": hidden - kept_hidden, "fp": int(row["truth"]) - int(row["tp"]), "fn": kept_hidden}


def ratio(num: float, den: float) -> float:
    """``num / den``, NaN where ``den`` is not positive."""
    return num / den if den > 0 else math.nan


def precision_recall_f1(tp: float, predicted: float, actual: float) -> dict[str, float]:
    """Precision ``tp / predicted``, recall ``tp / actual`` and their harmonic mean; NaN where a ratio has no
    denominator (nothing predicted, nothing to find) or F1 none (both 0).

    Example:
        >>> precision_recall_f1(4, 8, 6)  # detection_counts' tp, tp + fp, tp + fn
        {'precision': 0.5, 'recall': 0.6666666666666666, 'f1': 0.5714285714285715}
        >>> precision_recall_f1(0, 0, 6)["precision"], precision_recall_f1(0, 3, 6)["f1"]
        (nan, nan)
    """
    precision, recall = ratio(tp, predicted), ratio(tp, actual)
    return {"precision": precision, "recall": recall, "f1": ratio(2 * precision * recall, precision + recall)}


def _over_flights(values: Mapping[str, float]) -> dict[str, Any]:
    """The mean over the flights where a score is defined (precision needs a removal, recall a hidden point)."""
    finite = {f: v for f, v in values.items() if not math.isnan(v)}
    if not finite:
        return {"n": 0, "mean": math.nan, "std": math.nan, "ci": [math.nan, math.nan], "clusters": []}
    return cluster_difference(finite)


def hidden_detection(
    by_flight: Mapping[str, Mapping[str, Sequence[Mapping[str, int]]]], methods: Sequence[str]
) -> dict[str, Any]:
    """Per method, each score's mean over flights with its interval; pairwise differences with Holm.

    Args:
        by_flight: ``{flight: {method: [per-frame detection counts]}}``.
        methods: The methods to score (those with a detection decision; not ``oracle``).
    """
    per_flight: dict[str, dict[str, dict[str, float]]] = {m: {} for m in methods}
    for flight, rows in sorted(by_flight.items()):
        for method in methods:
            frames = rows.get(method, [])
            if frames:
                pooled = {k: sum(int(f[k]) for f in frames) for k in ("tp", "fp", "fn")}
                per_flight[method][flight] = precision_recall_f1(
                    pooled["tp"], pooled["tp"] + pooled["fp"], pooled["tp"] + pooled["fn"]
                )
    scores = {
        method: {name: _over_flights({f: s[name] for f, s in flights.items()}) for name in SCORES}
        for method, flights in per_flight.items()
        if flights
    }
    pairs = list(itertools.combinations([m for m in methods if per_flight[m]], 2))
    paired: dict[str, dict[str, Any]] = {}
    for a, b in pairs:
        shared = sorted(set(per_flight[a]) & set(per_flight[b]))
        diffs = {f: per_flight[a][f]["f1"] - per_flight[b][f]["f1"] for f in shared}
        diffs = {f: d for f, d in diffs.items() if not math.isnan(d)}
        if len(diffs) > 1:
            paired[f"{a} - {b}"] = cluster_difference(diffs, family_size=len(pairs))
    for key, p in holm({k: v["p"] for k, v in paired.items()}).items():
        paired[key]["p_holm"] = p
    return {"per_flight": per_flight, "scores": scores, "paired_f1": paired, "flights": len(by_flight)}


def detection_table(result: Mapping[str, Any]) -> str:
    """Markdown: each method's hidden-point precision, recall and F1 (mean over flights [95 % interval]), then the
    pairwise F1 differences with their Holm-adjusted p-values."""
    lines = [
        f"| method (hidden points = positive) | flights | {' | '.join(SCORES)} |",
        "|---|---|" + "---:|" * len(SCORES),
    ]
    for method, by_score in result["scores"].items():
        cells = []
        for name in SCORES:
            d = by_score[name]
            lo, hi = d["ci"]
            cells.append(f"{d['mean']:.3f} [{lo:.3f}, {hi:.3f}]")
        lines.append(f"| `{method}` | {by_score['f1']['n']} | " + " | ".join(cells) + " |")
    if result["paired_f1"]:
        lines += ["", "| F1 difference | flights | mean [95 %; family] | p (Holm) |", "|---|---|---:|---:|"]
        for pair, d in result["paired_f1"].items():
            lo, hi = d["ci"]
            flo, fhi = d["ci_family"]
            lines.append(
                f"| {pair} | {d['n']} | {d['mean']:+.3f} [{lo:+.3f}, {hi:+.3f}; {flo:+.3f}, {fhi:+.3f}] | "
                f"{d['p_holm']:.2g} |"
            )
    return "\n".join(lines)
