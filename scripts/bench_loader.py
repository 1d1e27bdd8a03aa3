"""Data-loading speed: ms per sample (one process, one thread; samples/s from CPU time) for every task and source at a served resolution.

The code is :mod:`airfisheye_bench.studies.loader_speed` (its docstring says what is measured and how; ``--help``
lists the options).
"""

from airfisheye_bench.studies.loader_speed import main

if __name__ == "__main__":
    main()
