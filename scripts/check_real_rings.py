"""Rings estimated on a real sweep (read without its ring field) against the sensor's own ring field.

The code is :mod:`airfisheye_bench.studies.real_rings` (its docstring says what is measured and how; ``--help``
lists the options).
"""

from airfisheye_bench.studies.real_rings import main

if __name__ == "__main__":
    main()
