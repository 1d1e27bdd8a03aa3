"""Occlusion corrections as detectors of hidden points, with the test flight as the unit.

Scored with the visible points as the positive class (precision, recall and F1 of what a method *keeps*), doing
nothing scores an F1 of 0.97 on a rig where 6 % of the points are hidden: the measure says little about the task.
Here the positive class is the hidden points that project into the image: a method detects one when it removes it.
Per frame (from :func:`airfisheye_bench.studies.occlusion_study.measure_frame`'s counts):

* ``tp`` = hidden points removed = ``hidden - hidden_kept``; ``fn`` = ``hidden_kept``;
* ``fp`` = visible points removed = ``truth - tp_visible`` (``truth``: visible points that project).

Counts are pooled per flight (frames of one flight are not independent), precision / recall / F1 computed per
flight, and each reported as the mean over the flights with a t-interval over the flights; methods are compared
pairwise, flight by flight (:func:`paired_f1`): the family is the pairs compared, for the Holm correction, the
Bonferroni interval and the minimum detectable effects alike (:mod:`airfisheye_bench.studies.clustered`).

A record's comparisons are restated from its per-flight scores without measuring again (:func:`restate`,
``scripts/hidden_detection.py``), into a record of its own whose table ``docs/results.md`` shows
(:func:`paired_report`, between :data:`REPORT_BEGIN` and :data:`REPORT_END`): so a record written before the family
was the pairs compared (the first ``hidden_detection_1536.json``: Bonferroni over every pair of methods, Holm over
the pairs compared) could be corrected; that record has since been measured again with the pairs as the family.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from airfisheye_bench.studies.clustered import cluster_difference, holm

__all__ = [
    "REPORT_BEGIN",
    "REPORT_END",
    "detection_counts",
    "detection_table",
    "hidden_detection",
    "paired_f1",
    "paired_report",
    "paired_table",
    "precision_recall_f1",
    "ratio",
    "restate",
]

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
    paired = paired_f1(per_flight)
    return {"per_flight": per_flight, "scores": scores, "paired_f1": paired, "flights": len(by_flight)}


def _f1(scores: Mapping[str, float | None]) -> float:
    """A flight's F1, NaN where it has none (``null`` in a record read back)."""
    value = scores.get("f1")
    return math.nan if value is None else float(value)


def paired_f1(
    per_flight: Mapping[str, Mapping[str, Mapping[str, float | None]]],
) -> dict[str, dict[str, Any]]:
    """Each pair of methods' F1 difference, flight by flight (:func:`cluster_difference`), over the flights where
    both have an F1. The family is the pairs compared, for every correction alike: the Bonferroni interval and the
    minimum detectable effects at the family's level, and Holm's adjusted p-values (``p_holm``). A method without an
    F1 on two shared flights (one that removes nothing has no precision) is in no pair.

    Example:
        >>> flights = {"a": {"f1": 0.5}, "b": {"f1": 0.7}, "c": {"f1": 0.6}}
        >>> per_flight = {"x": flights, "y": {k: {"f1": v["f1"] - 0.1} for k, v in flights.items()},
        ...               "none": {k: {"f1": None} for k in flights}}
        >>> paired = paired_f1(per_flight)
        >>> list(paired), paired["x - y"]["family_size"], round(paired["x - y"]["mean"], 3)
        (['x - y'], 1, 0.1)
    """
    compared: dict[str, dict[str, float]] = {}
    for a, b in itertools.combinations(list(per_flight), 2):
        shared = sorted(set(per_flight[a]) & set(per_flight[b]))
        diffs = {f: _f1(per_flight[a][f]) - _f1(per_flight[b][f]) for f in shared}
        diffs = {f: d for f, d in diffs.items() if not math.isnan(d)}
        if len(diffs) > 1:
            compared[f"{a} - {b}"] = diffs
    paired = {key: cluster_difference(diffs, family_size=len(compared)) for key, diffs in compared.items()}
    for key, p in holm({k: v["p"] for k, v in paired.items()}).items():
        paired[key]["p_holm"] = p
    return paired


def restate(record: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """``{size: paired F1 differences}`` recomputed by :func:`paired_f1` from the per-flight scores an
    ``occlusion_study`` record holds (``results.<size>.hidden_detection.per_flight``): the comparisons of a record
    written before the family was the pairs compared, without measuring the frames again."""
    return {
        size: paired_f1(result["hidden_detection"]["per_flight"])
        for size, result in record["results"].items()
        if "hidden_detection" in result
    }


#: The generated block of ``docs/results.md`` (section 4.0) that :func:`paired_report` writes.
REPORT_BEGIN = (
    "<!-- results-detection:begin (generated by scripts/hidden_detection.py --report docs/results.md from "
    "docs/figures/occlusion_ablation/hidden_detection_1536_paired.json; do not edit) -->"
)
REPORT_END = "<!-- results-detection:end -->"


def paired_report(restated: Mapping[str, Any], name: str) -> str:
    """The block of ``docs/results.md``: each size's :func:`paired_table` from a restated record (the file
    ``name`` under ``docs/figures/``), and where it and its source come from."""
    lines = []
    for size, paired in restated["paired_f1"].items():
        lines += [f"At {size} px, over the test flights:", "", paired_table(paired), ""]
    source = restated["source"]
    lines.append(
        f"From [`{Path(name).name}`](figures/{name}) (`{restated['provenance']['command']}`, commit "
        f"`{restated['provenance']['commit']}`), restated from the per-flight scores of "
        f"[`{Path(source['file']).name}`]({source['file'].removeprefix('docs/')}) (commit `{source['commit']}`)."
    )
    return "\n".join(lines)


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
        lines += ["", paired_table(result["paired_f1"])]
    return "\n".join(lines)


def paired_table(paired: Mapping[str, Mapping[str, Any]]) -> str:
    """Markdown: each pair's F1 difference over the flights, its 95 % and family-wise intervals, Holm's p and the
    minimum detectable effect (80 % power: alone; at the family's level)."""
    family = {int(d["family_size"]) for d in paired.values()}
    lines = [
        f"| F1 difference | flights | mean [95 %; family of {'/'.join(map(str, sorted(family)))}] | p (Holm) | "
        "detectable (80 %): alone; family |",
        "|---|---|---:|---:|---:|",
    ]
    for pair, d in paired.items():
        lo, hi = d["ci"]
        flo, fhi = d["ci_family"]
        lines.append(
            f"| {pair} | {d['n']} | {d['mean']:+.3f} [{lo:+.3f}, {hi:+.3f}; {flo:+.3f}, {fhi:+.3f}] | "
            f"{d['p_holm']:.2g} | {d['mde']:.3f}; {d['mde_family']:.3f} |"
        )
    return "\n".join(lines)
