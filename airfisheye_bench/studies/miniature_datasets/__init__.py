"""Miniature public datasets in their real layouts and encodings: the inputs of the dataset benchmarks
(``scripts/bench_kitti360.py``, ``scripts/bench_tartanair.py``) and the fixtures of the dataset readers' tests.

No real data (the datasets' licences): everything is simulated. :mod:`~.kitti360` writes a KITTI-360 root, with
scans of :mod:`~.spinning_scans` (the structure of real spinning LiDARs' files), and :mod:`~.kitti360_devkit` is the
devkit's own formulas re-implemented line by line (the reference the readers and the curl are checked and timed
against); :mod:`~.tartanair` writes a TartanAir V2 root from an analytic scene. Nothing is imported here.
"""
