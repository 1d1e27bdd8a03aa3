"""The GPU campaign: whether the loader feeds one GPU for each paper recipe, in one time-boxed command.

``python scripts/gpu_campaign.py --commit <sha>`` on a machine with one GPU (under 9 minutes, its own data included;
JSON under ``docs/figures/gpu/``); ``--smoke`` runs the same on the CPU at toy sizes. The code and what it measures:
:mod:`airfisheye_bench.studies.gpu_campaign` (``--help`` lists the options).
"""

from airfisheye_bench.studies.gpu_campaign import main

if __name__ == "__main__":
    main()
