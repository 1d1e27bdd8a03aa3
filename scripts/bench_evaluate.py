"""Evaluation from prediction files: wall time of ``evaluate_predictions`` over N frames (default 1000 at 512^2).

The code is :mod:`airfisheye_bench.studies.evaluation_speed` (its docstring says what is measured and how; ``--help``
lists the options).
"""

from airfisheye_bench.studies.evaluation_speed import main

if __name__ == "__main__":
    main()
