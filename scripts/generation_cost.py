"""What generating each preset costs: seconds per frame on one core and the preset's core-hours, with the load average.

The code is :mod:`airfisheye_bench.studies.generation_cost` (its docstring says what is measured and how; ``--help``
lists the options).
"""

from airfisheye_bench.studies.generation_cost import main

if __name__ == "__main__":
    main()
