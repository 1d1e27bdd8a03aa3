"""The lens study: train each arm (one lens, a lens list with jitter, + rays, a pinhole model) per task and seed,
score each run on every test lens and the robustness row, and commit each run's record as it is written.

The code is :mod:`airfisheye_bench.studies.lens_study` (its docstring says what is measured and how; ``--help``
lists the options).
"""

from airfisheye_bench.studies.lens_study import main

if __name__ == "__main__":
    main()
