"""Camera models: one interface (:class:`CameraModel`), one module per family, one table (``CAMERA_MODELS``).

Each model declares its parameters once (``declaration``, ``params.py``); ``camera_from_dict`` builds any model from
its flat dict, ``ideal_camera`` the ideal lenses by the config's spelling. See docs/design.md, "Fisheye camera", for
every model's parameters and the code it follows, and "Adding a camera model".
"""

from airfisheye_bench.geometry.cameras.base import CameraModel, incidence_angle
from airfisheye_bench.geometry.cameras.division import Division
from airfisheye_bench.geometry.cameras.double_sphere import DoubleSphere
from airfisheye_bench.geometry.cameras.eucm import EUCM
from airfisheye_bench.geometry.cameras.fov import Fov
from airfisheye_bench.geometry.cameras.ideal import LENS_MODELS, ideal_camera
from airfisheye_bench.geometry.cameras.kannala_brandt import KannalaBrandt
from airfisheye_bench.geometry.cameras.ocam import Ocam
from airfisheye_bench.geometry.cameras.perturbation import Perturbation
from airfisheye_bench.geometry.cameras.pinhole_radtan import PinholeRadtan
from airfisheye_bench.geometry.cameras.radial import (
    Equidistant,
    Equisolid,
    Orthographic,
    Pinhole,
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
    "LENS_MODELS",
    "CameraModel",
    "Division",
    "DoubleSphere",
    "Equidistant",
    "Equisolid",
    "Fov",
    "KannalaBrandt",
    "Ocam",
    "Orthographic",
    "Perturbation",
    "Pinhole",
    "PinholeRadtan",
    "RadTanThinPrismFisheye",
    "RadialCamera",
    "RadialPoly",
    "Stereographic",
    "ThinPrismFisheye",
    "Unified",
    "camera_from_dict",
    "ideal_camera",
    "incidence_angle",
]
