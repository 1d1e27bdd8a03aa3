"""Rank every results.json by task next to the paper's baselines (the same as ``airfisheye-leaderboard``).

    python scripts/leaderboard.py runs=logs/ [out=leaderboard] [paper=true] [skip_invalid=false] \
        [html=leaderboard/leaderboard.html]
    python scripts/leaderboard.py runs=[logs/,other/,path/to/results.json]
"""

import sys

from airfisheye_bench.cli.commands import leaderboard

if __name__ == "__main__":
    sys.exit(leaderboard())
