"""The qualitative panels of ``docs/results.md`` (section 7) from recorded runs, and their record.

    python scripts/report_panels.py --run seg=<run dir> --run depth=<run dir> --run completion=<run dir> \\
        [--frame modular_houses/traj03/000000] [--out docs/figures]

Writes ``<out>/panel_<task>.png`` and ``<out>/panels.json``; the logic is
:mod:`airfisheye_bench.studies.report_panels`.
"""

from airfisheye_bench.studies.report_panels import main

if __name__ == "__main__":
    main()
