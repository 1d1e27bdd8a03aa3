"""Geometry: camera models, cubemap- and panorama-to-fisheye remapping, rigid transforms, LiDAR projection and occlusion."""

from airfisheye_bench.geometry.cameras import (
    CAMERA_MODELS,
    LENS_MODELS,
    CameraModel,
    camera_from_dict,
    ideal_camera,
    incidence_angle,
)
from airfisheye_bench.geometry.cubemap import FACE_NAMES, CubemapToFisheye, face_rays, face_rotation
from airfisheye_bench.geometry.equirect import EquirectToFisheye
from airfisheye_bench.geometry.lidar import LidarSpec, spherical_coordinates
from airfisheye_bench.geometry.lidar_layout import organize_scan
from airfisheye_bench.geometry.occlusion import (
    OCCLUSION_METHODS,
    LidarProjection,
    lidar_depth_map,
    occlusion_mask,
    ordering_reference,
    project_lidar,
)
from airfisheye_bench.geometry.perspective_views import PerspectiveViews, parse_views
from airfisheye_bench.geometry.transforms import (
    CAM_FROM_FLU,
    check_rigid,
    euler_to_matrix,
    gimbal_rotation,
    invert_rigid,
    make_transform,
    matrix_to_quaternion,
    quaternion_to_matrix,
    relative_transform,
    transform_points,
)

__all__ = [
    "CAMERA_MODELS",
    "CAM_FROM_FLU",
    "FACE_NAMES",
    "LENS_MODELS",
    "OCCLUSION_METHODS",
    "CameraModel",
    "CubemapToFisheye",
    "EquirectToFisheye",
    "LidarProjection",
    "LidarSpec",
    "PerspectiveViews",
    "camera_from_dict",
    "check_rigid",
    "euler_to_matrix",
    "face_rays",
    "face_rotation",
    "gimbal_rotation",
    "ideal_camera",
    "incidence_angle",
    "invert_rigid",
    "lidar_depth_map",
    "make_transform",
    "matrix_to_quaternion",
    "occlusion_mask",
    "ordering_reference",
    "organize_scan",
    "parse_views",
    "project_lidar",
    "quaternion_to_matrix",
    "relative_transform",
    "spherical_coordinates",
    "transform_points",
]
