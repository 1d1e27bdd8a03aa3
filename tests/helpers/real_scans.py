"""The simulated scans with the structure of real spinning LiDARs' files, under the name the geometry tests import.

They are :mod:`airfisheye_bench.studies.miniature_datasets.spinning_scans` (the KITTI-360 benchmark's input writes
them too); new tests import them from there.
"""

from airfisheye_bench.studies.miniature_datasets.spinning_scans import simulate

__all__ = ["simulate"]
