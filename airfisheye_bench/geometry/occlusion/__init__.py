"""LiDAR-to-fisheye projection with occlusion correction (paper, III-C) and its baselines (z-buffer, HPR).

The camera and the LiDAR sit at different places, so a LiDAR point can project into the image although the
camera cannot see it: something nearer *to the camera* hides it. :func:`occlusion_mask` tells, per point,
whether it projects into the image and is not occluded. docs/design.md ("LiDAR and occlusion") is the one
explanation of the methods, of the readings of III-C decided here, of the known limits and of the three
implementations of ``ordering``; one concept per module:

==========================  ===========================================================================
``api``                     :func:`occlusion_mask`, :func:`project_lidar`, :func:`lidar_depth_map`,
                            :func:`ordering_mask` / :func:`ordering_reference` and the implementations
``options``                 :data:`OCCLUSION_METHODS`, :data:`OCCLUSION_OPTIONS`, :func:`check_occlusion_options`,
                            :data:`SPARSE_INPUTS` (the methods and the ground-truth ``oracle``)
                            :class:`Occlusion` (a method with its checked options), :func:`sparse_input` (either)
``projection``              the transform's check, the projection of the points and their pixel
``zbuffer``                 the z-buffer baseline
``hpr``                     Hidden Point Removal (Katz, Tal, Basri 2007)
``ordering``                the paper's method: steps 1-3, the compiled and the literal solver of step 4
``ordering_vectorised``     step 4 in numpy (a cross-check, the benchmark's old-vs-new comparison)
==========================  ===========================================================================
"""

from airfisheye_bench.geometry.occlusion.api import (
    ORDERING_IMPLEMENTATIONS,
    LidarProjection,
    lidar_depth_map,
    occlusion_mask,
    ordering_mask,
    ordering_reference,
    project_lidar,
)
from airfisheye_bench.geometry.occlusion.options import (
    OCCLUSION_METHODS,
    OCCLUSION_OPTIONS,
    ORACLE,
    SPARSE_INPUTS,
    Occlusion,
    check_occlusion_options,
    check_sparse_input_options,
    sparse_input,
)

__all__ = [
    "OCCLUSION_METHODS",
    "OCCLUSION_OPTIONS",
    "ORACLE",
    "ORDERING_IMPLEMENTATIONS",
    "SPARSE_INPUTS",
    "LidarProjection",
    "Occlusion",
    "check_occlusion_options",
    "check_sparse_input_options",
    "lidar_depth_map",
    "occlusion_mask",
    "ordering_mask",
    "ordering_reference",
    "project_lidar",
    "sparse_input",
]
