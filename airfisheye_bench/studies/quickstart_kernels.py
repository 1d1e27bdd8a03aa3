"""How far a quick-start result moves with the CPU's kernels, beside how far it moves with the seed.

The quick-start record (``docs/quickstart_results.json``) is trained on the machine's own kernels; the records under
``docs/figures/quickstart_kernels/`` repeat some of its seeds with the kernels limited (each of their seeds names the
switches it ran with, ``cpu_kernels``; a record whose seeds name none is a re-run on the machine's own kernels).
Seed ``s`` on the limited kernels pairs with seed ``s`` of the record: same data, same initial weights and data order,
so the per-seed difference is what the kernels alone do (:func:`~airfisheye_bench.studies.paired.paired_difference`).
Beside it: each path's mean and sample standard deviation over its seeds, and the last validation score of each run
(validation and test are different flights, so a shift seen on one split only is the split's, not the model's).
A metric that is not among a run's test ``metrics`` is read from its ``breakdown`` (e.g. ``range_80-120/rmse``).

:func:`cross_evaluate` separates the two places the kernels could act: it scores each trained model under every
kernel setting, so a score that moves with the setting is the evaluation's, and one that does not is the training's.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from airfisheye_bench.studies.paired import paired_differences
from airfisheye_bench.studies.quickstart import CPU_KERNEL_SWITCHES, mean_std

__all__ = ["cross_evaluate", "evaluate_under", "kernel_runs", "kernel_spread", "load_records"]

_RECORD = "record"


def kernel_runs(record: Mapping[str, Any], others: Iterable[Mapping[str, Any]]) -> dict[str, dict[str, dict]]:
    """``task -> path -> seed -> run`` of the record (path ``"record"``) and of every limited-kernel run in
    ``others`` (path: torch's ``ATEN_CPU_CAPABILITY`` among its ``cpu_kernels`` switches, e.g. ``"avx2"``); a run of
    another record without switches is a re-run of the record's path and is left out (the record holds that path)."""
    out: dict[str, dict[str, dict]] = {}
    for task, entry in record["tasks"].items():
        out.setdefault(task, {})[_RECORD] = dict(entry["seeds"])
    for other in others:
        for task, entry in other["tasks"].items():
            for seed, run in entry["seeds"].items():
                switches = run.get("cpu_kernels")
                if switches:
                    out.setdefault(task, {}).setdefault(_path_name(switches), {})[seed] = run
    return out


def _path_name(switches: Mapping[str, str]) -> str:
    """``"avx2"`` for torch's ``ATEN_CPU_CAPABILITY=avx2`` (the switch every limited run sets); else every switch."""
    if "ATEN_CPU_CAPABILITY" in switches:
        return str(switches["ATEN_CPU_CAPABILITY"])
    return " ".join(f"{k}={v}" for k, v in sorted(switches.items()))


def _spread(values: list[float]) -> dict[str, Any]:
    return {**mean_std(values), "values": values}


def kernel_spread(
    runs: Mapping[str, Mapping[str, Mapping[str, Mapping[str, Any]]]], metrics: Mapping[str, list[str]]
) -> dict[str, Any]:
    """Per task: each path's spread over its seeds (test ``metrics[task]`` and the last validation score), and
    every limited path paired by seed with the record.

    Example:
        >>> def run(rmse, val):
        ...     return {"metrics": {"rmse": rmse}, "validation_curve": [{"epoch": 0, "val/rmse": val}]}
        >>> runs = {"depth": {"record": {"0": run(15.0, 18.0), "1": run(16.0, 19.0)},
        ...                   "X=avx2": {"0": run(14.0, 18.5), "1": run(14.5, 18.5)}}}
        >>> out = kernel_spread(runs, {"depth": ["rmse"]})["depth"]
        >>> out["paths"]["X=avx2"]["rmse"]["mean"], out["paired"]["X=avx2"]["rmse"]["diffs"]
        (14.25, [-1.0, -1.5])
        >>> out["paired"]["X=avx2"]["val/rmse"]["diffs"]
        [0.5, -0.5]
    """
    result: dict[str, Any] = {}
    for task, paths in runs.items():
        names = list(metrics[task])
        values: dict[str, dict[int, dict[str, float]]] = {}
        summary: dict[str, dict[str, Any]] = {}
        for path, seeds in paths.items():
            values[path] = {}
            for seed, run in seeds.items():
                scores = {**run.get("breakdown", {}), **run["metrics"]}
                row = {m: float(scores[m]) for m in names if scores.get(m) is not None}
                curve = run.get("validation_curve") or []
                for key in curve[-1] if curve else ():
                    if key.startswith("val/"):
                        row[key] = float(curve[-1][key])
                values[path][int(seed)] = row
            keys = sorted({k for row in values[path].values() for k in row})
            switches = {json.dumps(run.get("cpu_kernels"), sort_keys=True) for run in seeds.values()}
            summary[path] = {
                "seeds": sorted(values[path]),
                "cpu_kernels": [json.loads(s) for s in sorted(switches)],
                "commits": sorted({run.get("commit", "") for run in seeds.values()}),
                **{k: _spread([row[k] for row in values[path].values() if k in row]) for k in keys},
            }
        paired = paired_differences(values, reference=_RECORD) if len(values) > 1 else {}
        result[task] = {"paths": summary, "paired": paired}
    return result


def load_records(record_path: Path, folder: Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The quick-start record and every quick-start record in ``folder`` (``*.json`` with ``tasks``: the summary and
    the cross-evaluation kept beside them are not runs)."""
    record = json.loads(record_path.read_text())
    others = [json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))]
    return record, [other for other in others if "tasks" in other]


def datasets(records: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The data identities (``dataset``) the records were measured on, each once, in order of first appearance.

    Example:
        >>> same = {"name": "q", "content_sha256": "8cf0"}
        >>> datasets([{"dataset": same}, {"dataset": dict(same)}, {"tasks": {}}])
        [{'name': 'q', 'content_sha256': '8cf0'}]
    """
    seen: list[dict[str, Any]] = []
    for record in records:
        identity = record.get("dataset")
        if identity is not None and identity not in seen:
            seen.append(dict(identity))
    return seen


#: One kernel setting: the switches of :data:`~airfisheye_bench.studies.quickstart.CPU_KERNEL_SWITCHES` it sets
#: (none: the machine's own kernels).
Kernels = Mapping[str, str]


def _setting_name(kernels: Kernels) -> str:
    return _path_name(kernels) if kernels else "native"


def evaluate_under(run_dir: Path, kernels: Kernels, repo: Path) -> dict[str, float]:
    """Test ``metrics`` and ``breakdown`` of ``run_dir``'s best checkpoint, scored by ``scripts/evaluate.py`` in a
    fresh process whose CPU kernels are ``kernels`` (every other switch unset), on one thread and no loader workers,
    so that nothing else differs between two settings."""
    env = {k: v for k, v in os.environ.items() if k not in CPU_KERNEL_SWITCHES}
    env.update(kernels, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    with tempfile.TemporaryDirectory(prefix="kernels-eval-") as out:
        argv = [sys.executable, "scripts/evaluate.py", f"ckpt_path={run_dir}", "split=test", "device=cpu"]
        argv += ["num_workers=0", "num_panels=0", f"hydra.run.dir={out}"]
        subprocess.run(argv, cwd=repo, env=env, check=True, stdout=subprocess.DEVNULL)
        results = json.loads((Path(out) / "results.json").read_text())
    return {k: float(v) for k, v in {**results["breakdown"], **results["metrics"]}.items() if v is not None}


def cross_evaluate(
    run_dirs: Sequence[Path], evaluate: Callable[[Path, Kernels], Mapping[str, float]]
) -> dict[str, Any]:
    """Score every run of ``run_dirs`` under every kernel setting any of them was trained with.

    A run's setting is its ``benchmark.json``'s ``cpu_kernels`` (none: the machine's own). ``largest_change`` is,
    per run, the largest absolute change of any score between the settings: 0 when the evaluation does not depend
    on the kernels.

    Example:
        >>> import json, tempfile
        >>> root = Path(tempfile.mkdtemp())
        >>> for name, kernels in (("a", None), ("b", {"ATEN_CPU_CAPABILITY": "avx2"})):
        ...     (root / name).mkdir()
        ...     _ = (root / name / "benchmark.json").write_text(json.dumps({"cpu_kernels": kernels}))
        >>> scores = {"a": 15.0, "b": 14.0}
        >>> out = cross_evaluate([root / "a", root / "b"], lambda run, kernels: {"rmse": scores[run.name]})
        >>> out["settings"], out["runs"][1]["scores"], out["largest_change"]
        (['native', 'avx2'], {'native': {'rmse': 14.0}, 'avx2': {'rmse': 14.0}}, 0.0)
    """
    trained: list[tuple[Path, dict[str, str], dict[str, Any]]] = []
    for run in run_dirs:
        record = json.loads((Path(run) / "benchmark.json").read_text())
        trained.append((Path(run), dict(record.get("cpu_kernels") or {}), record))
    settings: dict[str, dict[str, str]] = {}
    for _, kernels, _ in trained:
        settings.setdefault(_setting_name(kernels), kernels)
    runs = []
    for run, kernels, record in trained:
        scores = {name: dict(evaluate(run, setting)) for name, setting in settings.items()}
        keys = set.intersection(*(set(s) for s in scores.values()))
        change = max(
            (max(s[k] for s in scores.values()) - min(s[k] for s in scores.values()) for k in keys),
            default=0.0,
        )
        runs.append(
            {
                "run": str(run),
                "trained_with": _setting_name(kernels),
                "trained": {"commit": record.get("commit"), "command": record.get("command")},
                "scores": scores,
                "largest_change": change,
            }
        )
    return {
        "settings": list(settings),
        "kernels": settings,
        "runs": runs,
        "largest_change": max((r["largest_change"] for r in runs), default=0.0),
    }
