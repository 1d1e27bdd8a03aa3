"""Camera models: one interface (:class:`CameraModel`), one module per family, one table (``CAMERA_MODELS``).

See docs/design.md, "Fisheye camera", for every model's parameters and the code it follows.
"""

from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.division import Division
from airfisheye_bench.geometry.cameras.double_sphere import DoubleSphere
from airfisheye_bench.geometry.cameras.eucm import EUCM
from airfisheye_bench.geometry.cameras.fov import Fov
from airfisheye_bench.geometry.cameras.kannala_brandt import KannalaBrandt
from airfisheye_bench.geometry.cameras.ocam import Ocam
from airfisheye_bench.geometry.cameras.pinhole_radtan import PinholeRadtan
from airfisheye_bench.geometry.cameras.radial import (
    Equidistant,
    Equisolid,
    Orthographic,
    RadialCamera,
    Stereographic,
)
from airfisheye_bench.geometry.cameras.radial_poly import RadialPoly
from airfisheye_bench.geometry.cameras.registry import CAMERA_MODELS, camera_from_dict
from airfisheye_bench.geometry.cameras.thin_prism import RadTanThinPrismFisheye, ThinPrismFisheye
from airfisheye_bench.geometry.cameras.unified import Unified

__all__ = [
    "CAMERA_MODELS",
    "EUCM",
    "CameraModel",
    "Division",
    "DoubleSphere",
    "Equidistant",
    "Equisolid",
    "Fov",
    "KannalaBrandt",
    "Ocam",
    "Orthographic",
    "PinholeRadtan",
    "RadTanThinPrismFisheye",
    "RadialCamera",
    "RadialPoly",
    "Stereographic",
    "ThinPrismFisheye",
    "Unified",
    "camera_from_dict",
]
