"""Rank every results.json by task next to the paper's baselines (thin wrapper of the leaderboard module).

python scripts/leaderboard.py runs=logs/[,other/,path/to/results.json] [out=leaderboard] [paper=true] \
    [skip_invalid=false] [html=leaderboard/leaderboard.html]
"""

import sys

from airfisheye_bench.evaluation.leaderboard_command import main

if __name__ == "__main__":
    sys.exit(main())
