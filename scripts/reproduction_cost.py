"""Write the estimate of what the paper's recipes cost at the paper's scale into ``docs/training.md`` ("What a
reproduction costs"), from the GPU campaign's measured images/s and the generator's measured CPU time per frame.

    python scripts/reproduction_cost.py [--check]

The arithmetic is ``airfisheye_bench.studies.reproduction_cost``; ``--check`` only says whether the block is current.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.studies import reproduction_cost
from airfisheye_bench.studies.generated_blocks import replace_block

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "training.md"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 when docs/training.md's block is stale")
    args = parser.parse_args()
    text = DOC.read_text(encoding="utf-8")
    block = reproduction_cost.committed_block(REPO)
    new = replace_block(text, block, reproduction_cost.BEGIN, reproduction_cost.END)
    if args.check:
        print("docs/training.md: reproduction cost " + ("current" if new == text else "stale"))
        return int(new != text)
    atomic_write_text(DOC, new)
    print(f"wrote {DOC}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
