"""Train each quick start on several seeds, score its trivial baseline, and write ``docs/quickstart_results.json``.

    python scripts/quickstart_benchmark.py --out logs/quickstart --seeds 0 1 2
    python scripts/quickstart_benchmark.py --out logs/quickstart --collect-only    # summarise what has finished
    python scripts/quickstart_benchmark.py --readme      # README's and docs/results.md's tables from the JSON
    python scripts/quickstart_benchmark.py --tasks completion --out logs/qs_paper_512 \
        --json docs/quickstart_results_paper_512.json -- data.lidar.density=paper_512   # a variant of its own
    python scripts/quickstart_benchmark.py --readme --variant docs/quickstart_results_paper_512.json

Each run is ``python train.py task=<task> seed=<seed> hydra.run.dir=<out>/<task>/seed<seed>`` (the README's
command); finished runs are skipped, so an interrupted benchmark resumes, and the seeds of the existing record
whose runs are not in ``--out`` are kept (``--fresh`` drops them). ``--tasks`` picks some of
``seg depth completion``; everything after ``--`` goes to ``train.py`` (then the results are not the quick start's:
give them a ``--json`` of their own, and ``--readme --variant <that file>`` shows them beside the quick start's rows,
with the paired difference; :mod:`airfisheye_bench.studies.quickstart_variant`).
The logic is :mod:`airfisheye_bench.studies.quickstart`.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.studies import quickstart, quickstart_report, quickstart_variant
from airfisheye_bench.studies.provenance import git_commit

REPO = Path(__file__).resolve().parents[1]
DEFAULT_JSON = REPO / "docs" / "quickstart_results.json"


def parse_args(argv: Sequence[str]) -> tuple[argparse.Namespace, list[str]]:
    argv = list(argv)
    overrides: list[str] = []
    if "--" in argv:
        cut = argv.index("--")
        argv, overrides = argv[:cut], argv[cut + 1 :]
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--out", type=Path, default=Path("logs/quickstart"), help="runs in <out>/<task>/seed<s>"
    )
    parser.add_argument("--tasks", nargs="+", default=list(quickstart.QUICKSTART_TASKS))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--threads", type=int, help="OMP_NUM_THREADS of the runs (default: torch's choice)")
    parser.add_argument("--collect-only", action="store_true", help="train nothing, summarise what is there")
    parser.add_argument("--no-collect", action="store_true", help="train only (another process summarises)")
    parser.add_argument(
        "--json", type=Path, default=DEFAULT_JSON, help="the record (the README cites the default)"
    )
    parser.add_argument(
        "--fresh",
        action="store_true",
        help="drop --json's seeds whose runs are not in --out (default: keep them)",
    )
    parser.add_argument("--readme", action="store_true", help="only regenerate README.md's table from --json")
    parser.add_argument(
        "--variant",
        type=Path,
        help="with --readme: also the README's block putting this record's rows beside the quick start's",
    )
    return parser.parse_args(argv), overrides


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args, overrides = parse_args(argv)
    readme = REPO / "README.md"
    if not args.readme:
        runs = quickstart.plan(args.out, args.tasks, args.seeds)
        if not args.collect_only:
            quickstart.train_missing(
                runs,
                REPO,
                overrides,
                log=lambda m: print(m, file=sys.stderr, flush=True),
                threads=args.threads,
            )
        if args.no_collect:
            return 0
        baselines = {}
        for task in args.tasks:
            # The data and metric of a run of the task: a finished one, else one with a checkpoint so far.
            started = [r for r in runs if r.task == task and list(r.out.glob("checkpoints/*.ckpt"))]
            started.sort(key=lambda r: not r.record.is_file())
            saved = args.out / task / "baseline.json"  # the data does not change between seeds: fitted once
            if saved.is_file():
                baselines[task] = json.loads(saved.read_text(encoding="utf-8"))
            elif started:
                print(f"baseline of {task} (data of {started[0].out})", file=sys.stderr, flush=True)
                baselines[task] = quickstart.evaluate_baseline(started[0].out)
                atomic_write_text(saved, json.dumps(baselines[task], indent=2) + "\n")
        command = "python scripts/quickstart_benchmark.py " + " ".join(argv)
        # Seeds finished elsewhere (an earlier machine, another day) stay in the record when their run is not here.
        previous = None
        if args.json.is_file() and not args.fresh:
            previous = json.loads(args.json.read_text(encoding="utf-8"))
        try:
            record = quickstart.summarize(runs, baselines, command, git_commit(REPO), previous, overrides)
        except ValueError as err:
            print(f"error: {err} (or pass --fresh to drop {args.json}'s seeds)", file=sys.stderr)
            return 2
        atomic_write_text(args.json, json.dumps(record, indent=2, ensure_ascii=False) + "\n")
        print(f"wrote {args.json}", file=sys.stderr)
    record = json.loads(args.json.read_text(encoding="utf-8"))
    committed = args.json.resolve() == DEFAULT_JSON
    table = quickstart.readme_table(
        record, source=DEFAULT_JSON.relative_to(REPO).as_posix() if committed else str(args.json)
    )
    if committed:  # the README and the report cite the committed file only
        atomic_write_text(readme, quickstart.replace_table(readme.read_text(encoding="utf-8"), table))
        report = REPO / "docs" / "results.md"
        text = quickstart_report.regenerate(report.read_text(encoding="utf-8"), record, REPO / "docs")
        atomic_write_text(report, text)
    print(table)
    if args.variant is not None:
        variant = json.loads(args.variant.read_text(encoding="utf-8"))
        block = quickstart_variant.variant_table(
            record,
            variant,
            args.json.resolve().relative_to(REPO).as_posix(),
            args.variant.resolve().relative_to(REPO).as_posix(),
        )
        text = quickstart.replace_table(
            readme.read_text(encoding="utf-8"),
            block,
            quickstart_variant.VARIANT_BEGIN,
            quickstart_variant.VARIANT_END,
        )
        atomic_write_text(readme, text)
        print(block)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
