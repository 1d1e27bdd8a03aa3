"""Completion ablation of the occlusion correction: train and test NLSPN per (method, seed), report mean ± std.

The code is :mod:`airfisheye_bench.studies.occlusion_ablation` (its docstring says what is measured and how; ``--help``
lists the options).
"""

from airfisheye_bench.studies.occlusion_ablation import main

if __name__ == "__main__":
    main()
