"""Make the leaderboard example of ``docs/evaluation.md`` again: a one-epoch AdaBins run on the ``tiny`` preset, its
training test, its checkpoint evaluated with and without ``tta=flip``, its fp32 and int8 ONNX exports evaluated, the
five ``results.json`` kept under ``docs/figures/leaderboard_example/`` and ranked by ``airfisheye-leaderboard``.

    OMP_NUM_THREADS=1 nice -n 10 python scripts/leaderboard_example.py [--work DIR]   # about 2 minutes on 2 cores
    python scripts/leaderboard_example.py --report   # only rank the kept files again and rewrite the doc's block

No network: the ``tiny`` preset is generated into the data cache when missing, weights are random. The logic is
``airfisheye_bench.studies.leaderboard_example``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.studies import leaderboard_example as example
from airfisheye_bench.studies.generated_blocks import replace_block
from airfisheye_bench.studies.provenance import REPO, provenance

DOC = REPO / "docs" / "evaluation.md"


def run(argv: list[str] | tuple[str, ...]) -> None:
    """``python <argv>`` in the repository, one torch thread, this checkout's code; stops the script if it fails."""
    env = {
        **os.environ,
        "OMP_NUM_THREADS": "1",
        "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
    }
    print("$ python " + " ".join(argv), flush=True)
    done = subprocess.run([sys.executable, *argv], cwd=REPO, env=env, check=False)
    if done.returncode != 0:
        raise SystemExit(f"python {' '.join(argv)} exited with {done.returncode}")


def make_results(work: Path, dest: Path) -> None:
    """Train, evaluate and export in ``work``; keep each ``results.json`` under ``dest``."""
    record = provenance("scripts/leaderboard_example.py")  # before anything here is rewritten
    example.clear(dest)
    for step in example.steps(work):
        run(step.argv)
        if step.results:
            print(f"kept {example.keep(work / step.results, dest, record, step)}")


def rank(work: Path, dest: Path) -> str:
    """``airfisheye-leaderboard`` over ``dest`` (without the paper's rows): its markdown, also kept in ``dest``."""
    run(["scripts/leaderboard.py", f"runs={dest}", f"out={work / 'leaderboard'}", "paper=false"])
    markdown = (work / "leaderboard" / "leaderboard.md").read_text(encoding="utf-8")
    atomic_write_text(dest / "leaderboard.md", markdown)
    return markdown


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--work", type=Path, help="folder for the run, evaluations and exports (default: a temporary one)"
    )
    parser.add_argument("--report", action="store_true", help="rank the kept results again; train nothing")
    args = parser.parse_args()
    dest = REPO / example.RECORD
    work = args.work or Path(tempfile.mkdtemp(prefix="leaderboard_example_"))
    try:
        if not args.report:
            make_results(work, dest)
        markdown = rank(work, dest)
    finally:
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)
    text = DOC.read_text(encoding="utf-8")
    atomic_write_text(DOC, replace_block(text, example.doc_block(markdown), example.BEGIN, example.END))
    print(f"wrote {dest / 'leaderboard.md'} and the block of {DOC}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
