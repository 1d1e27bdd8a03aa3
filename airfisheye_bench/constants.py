"""Constants several layers share, kept at the bottom so that none of them imports another for a number.

Example:
    >>> [round(m / s, 3) for m, s in zip(IMAGENET_MEAN, IMAGENET_STD)]
    [2.118, 2.036, 1.804]
"""

from __future__ import annotations

__all__ = ["IMAGENET_MEAN", "IMAGENET_STD", "LENS_MODELS"]

#: Per-channel RGB mean and standard deviation of ImageNet, in ``[0, 1]`` units: every encoder of the zoo was
#: pretrained on images normalised as ``(rgb / 255 - mean) / std``, so the datamodules feed them the same.
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)

#: Fisheye projection models of :class:`~airfisheye_bench.geometry.FisheyeCamera` (the config checks list them
#: without importing the geometry, and with it torch).
LENS_MODELS = ("equidistant", "equisolid", "stereographic", "orthographic", "kannala_brandt")
