"""The lens study's arms compared lens by lens (docs/results.md, section 9): does the lens list help, do rays help
on top of it, and what does a pinhole model lose against the one-lens fisheye model? And each arm against its own
lens perturbed (:func:`robustness_changes`): which change of the intrinsics moves it, and how far?

Each comparison ``x − y`` (:data:`CONTRASTS`) is measured on every test lens over the test flights: the score of
each flight averaged over the seeds both arms have (seeds are paired across arms: same data order and
initialisation stream), then arm ``x``'s minus arm ``y``'s, with a t-interval over the flights (frames of one flight
are not independent) and a Bonferroni family of every comparison and lens of the task. Where an interval holds 0 the
comparison is stated with the smallest difference it would have detected (80 % power, at the family's level).

Example:
    >>> run = lambda arm, seed, score: {"arm": arm, "task": "seg", "seed": seed, "cross_lens": {"lenses": [
    ...     {"name": "fisheye", "flights": {f: {"mIoU": score + i / 100} for i, f in enumerate("pqr")}}]}}
    >>> records = [run("a", 0, 0.20), run("a", 1, 0.22), run("b", 0, 0.25), run("b", 1, 0.25), run("b", 2, 0.9)]
    >>> out = arm_contrasts(records, {"seg": "mIoU"})["seg"]
    >>> out["family"], out["contrasts"]["b − a"]["seeds"], round(out["contrasts"]["b − a"]["lenses"]["fisheye"]["mean"], 3)
    (1, [0, 1], 0.04)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from airfisheye_bench.studies.clustered import cluster_difference

__all__ = [
    "CONTRASTS",
    "arm_contrasts",
    "contrast_lines",
    "flight_scores",
    "robustness_changes",
    "robustness_lines",
]

#: ``(x, y)``: arm x's score minus arm y's. b − a: what training across lenses buys; c − b: what the ray map adds
#: to it; d − a: a pinhole model through perspective views against the one-lens fisheye model.
CONTRASTS = (("b", "a"), ("c", "b"), ("d", "a"))


def flight_scores(records: Sequence[Mapping[str, Any]], lens: str, metric: str) -> dict[str, float]:
    """``{flight: score}`` of ``metric`` on test lens ``lens``, each flight's mean over ``records`` (the seeds of
    one arm) that scored it."""
    per: dict[str, list[float]] = {}
    for record in records:
        row = next((r for r in record["cross_lens"]["lenses"] if r["name"] == lens), None)
        for flight, values in ((row or {}).get("flights") or {}).items():
            value = values.get(metric)
            if value is not None and math.isfinite(value):
                per.setdefault(flight, []).append(float(value))
    return {flight: sum(v) / len(v) for flight, v in per.items()}


def arm_contrasts(
    records: Sequence[Mapping[str, Any]], metrics: Mapping[str, str], level: float = 0.95
) -> dict[str, Any]:
    """``{task: {"metric", "family", "contrasts": {"x − y": {"seeds", "lenses": {lens: interval}}}}}`` for each task
    of ``metrics`` (its compared metric) and each of :data:`CONTRASTS` whose two arms share a seed; an interval is
    :func:`~airfisheye_bench.studies.clustered.cluster_difference` of the per-flight differences."""
    out: dict[str, Any] = {}
    for task in dict.fromkeys(r["task"] for r in records if r["task"] in metrics):  # the records' order
        metric = metrics[task]
        by_arm: dict[str, list[Mapping[str, Any]]] = {}
        for record in records:
            if record["task"] == task:
                by_arm.setdefault(record["arm"], []).append(record)
        pairs = []
        for x, y in CONTRASTS:
            seeds = sorted({r["seed"] for r in by_arm.get(x, [])} & {r["seed"] for r in by_arm.get(y, [])})
            if seeds:
                pairs.append((x, y, seeds))
        if not pairs:
            continue
        lenses = [
            name
            for name in dict.fromkeys(
                row["name"] for r in records if r["task"] == task for row in r["cross_lens"]["lenses"]
            )
            if name != "trained"  # arm by arm its own lens or lens list: not one lens to compare on
        ]
        family = len(pairs) * len(lenses)
        contrasts = {}
        for x, y, seeds in pairs:
            mine = [r for r in by_arm[x] if r["seed"] in seeds]
            theirs = [r for r in by_arm[y] if r["seed"] in seeds]
            cells = {}
            for lens in lenses:
                a, b = flight_scores(mine, lens, metric), flight_scores(theirs, lens, metric)
                diffs = {f: a[f] - b[f] for f in sorted(a.keys() & b.keys())}
                cells[lens] = cluster_difference(diffs, family, level) if diffs else {"n": 0}
            contrasts[f"{x} − {y}"] = {"seeds": seeds, "lenses": cells}
        out[task] = {"metric": metric, "family": family, "contrasts": contrasts}
    return out


def robustness_changes(
    records: Sequence[Mapping[str, Any]], metrics: Mapping[str, str], level: float = 0.95
) -> dict[str, Any]:
    """``{task: {"metric", "family", "arms": {arm: {"seeds", "perturbations": {name: interval}}}}}``: per arm and
    perturbation of its robustness row (``cross_lens.robustness``), the change of the task's metric from the
    unperturbed lens, each flight's change averaged over the arm's seeds first, with a t-interval over the flights
    and a Bonferroni family of every arm and perturbation of the task.

    Example:
        >>> row = lambda seed, shift: {"arm": "a", "task": "seg", "seed": seed, "cross_lens": {"lenses": [],
        ...     "robustness": {"flights": {f: {"mIoU": 0.5} for f in "pqr"}, "perturbations": [{"name": "up",
        ...     "flights": {f: {"mIoU": 0.5 + shift + i / 100} for i, f in enumerate("pqr")}}]}}}
        >>> out = robustness_changes([row(0, -0.02), row(1, -0.04)], {"seg": "mIoU"})["seg"]
        >>> out["family"], round(out["arms"]["a"]["perturbations"]["up"]["mean"], 3)
        (1, -0.02)
    """
    out: dict[str, Any] = {}
    for task in dict.fromkeys(r["task"] for r in records if r["task"] in metrics):
        metric = metrics[task]
        by_arm: dict[str, list[Mapping[str, Any]]] = {}
        for record in records:
            if record["task"] == task and "robustness" in record["cross_lens"]:
                by_arm.setdefault(record["arm"], []).append(record)
        changes: dict[str, dict[str, dict[str, float]]] = {}  # arm -> perturbation -> flight -> mean change
        for arm, runs in by_arm.items():
            per: dict[str, dict[str, list[float]]] = {}
            for run in runs:
                row = run["cross_lens"]["robustness"]
                reference = row["flights"] or {}
                for perturbation in row["perturbations"]:
                    for flight, values in (perturbation.get("flights") or {}).items():
                        change = values.get(metric, math.nan) - reference.get(flight, {}).get(
                            metric, math.nan
                        )
                        if math.isfinite(change):
                            per.setdefault(perturbation["name"], {}).setdefault(flight, []).append(change)
            changes[arm] = {
                name: {f: sum(v) / len(v) for f, v in flights.items()} for name, flights in per.items()
            }
        family = sum(len(p) for p in changes.values())
        if not family:
            continue
        out[task] = {
            "metric": metric,
            "family": family,
            "arms": {
                arm: {
                    "seeds": sorted(r["seed"] for r in by_arm[arm]),
                    "perturbations": {
                        name: cluster_difference(flights, family, level) for name, flights in per_name.items()
                    },
                }
                for arm, per_name in changes.items()
            },
        }
    return out


def robustness_lines(
    changes: Mapping[str, Any],
    label: Mapping[str, str],
    titles: Mapping[str, str],
    source: str,
    largest: Mapping[str, Mapping[str, str]] | None = None,
) -> list[str]:
    """One markdown table per task: a row per arm (``titles``: its name), a column per perturbation and, with
    ``largest`` (``{task: {arm: text}}``), a last column with the arm's largest change."""
    lines: list[str] = []
    for task, block in changes.items():
        name = label.get(block["metric"], block["metric"])
        columns = list(dict.fromkeys(p for arm in block["arms"].values() for p in arm["perturbations"]))
        last = (largest or {}).get(task)
        heads = [c.removeprefix("trained (").removesuffix(")") for c in columns] + (
            ["largest change"] if last else []
        )
        lines += [
            "",
            f"**{task}, robustness row: change of {name} under each perturbation of the trained lens** (perturbed − "
            "unperturbed; per test flight the seeds' mean change first, then the mean over the flights with its 95 % "
            f"interval Bonferroni-corrected over the {block['family']} cells of the table; where that interval holds "
            "0, `mde` is the smallest change it would have detected at 80 % power"
            + ("; largest change: of the whole test split's score, mean ± std over the seeds" if last else "")
            + f"; `{source}`)",
            "",
            "| arm | seeds | " + " | ".join(heads) + " |",
            "|---|---:|" + "---:|" * len(heads),
        ]
        for arm, cells in block["arms"].items():
            row = [_cell(cells["perturbations"].get(c)) for c in columns] + (
                [last.get(arm, "–")] if last else []
            )
            seeds = ", ".join(map(str, cells["seeds"]))
            lines.append(f"| {arm}: {titles.get(arm, arm)} | {seeds} | " + " | ".join(row) + " |")
    return lines


def contrast_lines(contrasts: Mapping[str, Any], label: Mapping[str, str], source: str) -> list[str]:
    """One markdown table per task: a row per comparison, a column per test lens (``label``: a metric's name)."""
    lines: list[str] = []
    for task, block in contrasts.items():
        name = label.get(block["metric"], block["metric"])
        lenses = list(dict.fromkeys(lens for c in block["contrasts"].values() for lens in c["lenses"]))
        lines += [
            "",
            f"**{task}, arms compared: difference of {name}** (arm x − arm y over the seeds both have; per test "
            "flight the seeds' mean score first, then the mean difference over the flights with its 95 % interval "
            f"Bonferroni-corrected over the {block['family']} comparisons of the table; where that interval holds 0, "
            f"`mde` is the smallest difference it would have detected at 80 % power; `{source}`)",
            "",
            "| arms | seeds | " + " | ".join(lenses) + " |",
            "|---|---:|" + "---:|" * len(lenses),
        ]
        for pair, contrast in block["contrasts"].items():
            cells = [_cell(contrast["lenses"].get(lens)) for lens in lenses]
            seeds = ", ".join(map(str, contrast["seeds"]))
            lines.append(f"| {pair} | {seeds} | " + " | ".join(cells) + " |")
    return lines


def _cell(interval: Mapping[str, Any] | None) -> str:
    if not interval or not interval.get("n"):
        return "–"
    low, high = interval["ci_family"]
    if not (math.isfinite(low) and math.isfinite(high)):
        return f"{interval['mean']:+.3f}"
    text = f"{interval['mean']:+.3f} [{low:+.3f}, {high:+.3f}]"
    if low <= 0.0 <= high and math.isfinite(interval["mde_family"]):
        text += f" · mde {interval['mde_family']:.3f}"
    return text
