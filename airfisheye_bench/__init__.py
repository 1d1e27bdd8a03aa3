"""airfisheye-bench: training and benchmark framework for fisheye perception on drones (AirFisheye).

Importing the package costs nothing but the finder of the import paths that moved in 0.2
(:mod:`airfisheye_bench.moved`, standard library only): every other module is imported where it is used.
"""

from airfisheye_bench import moved

moved.install()
