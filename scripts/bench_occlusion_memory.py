"""Peak memory and time of each occlusion method, to test the paper's claim that ordering needs less memory.

The code is :mod:`airfisheye_bench.studies.occlusion_memory` (its docstring says what is measured and how; ``--help``
lists the options).
"""

from airfisheye_bench.studies.occlusion_memory import main

if __name__ == "__main__":
    main()
