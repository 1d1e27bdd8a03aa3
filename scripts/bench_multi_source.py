"""What serving and scoring several sources (``data.sources``) adds: the same frames, one source against a mixture.

The code is :mod:`airfisheye_bench.studies.multi_source_cost` (its docstring says what is measured and how;
``--help`` lists the options).
"""

from airfisheye_bench.studies.multi_source_cost import main

if __name__ == "__main__":
    main()
