"""Occlusion-correction study on a synthetic split: how well each method recovers the camera-visible LiDAR points.

The code is :mod:`airfisheye_bench.studies.occlusion_study` (its docstring says what is measured and how; ``--help``
lists the options).
"""

from airfisheye_bench.studies.occlusion_study import main

if __name__ == "__main__":
    main()
