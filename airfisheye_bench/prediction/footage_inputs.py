"""Frames of footage as the input images of a model: the camera check, resizing, and ERP panoramas re-rendered.

A model predicts the camera it was trained for. :func:`frame_preparer` checks the footage against it from the
frames' headers, before anything is predicted, and returns what turns each frame into the model's input image
(``uint8 [H, W, 3]`` at the model's size, black outside its lens, as the served training images are):

- ``fisheye`` frames: without ``camera`` they are taken to be of the lens of the dataset they belong to (its
  ``calib.yaml``, :func:`~airfisheye_bench.io.layout.calibration_beside`) or else of the model's lens, so they must be the model's size;
  with ``camera`` (a calibration file of the footage's lens) they must be that lens's size, and the lens, scaled to
  the model's size (:meth:`~airfisheye_bench.geometry.cameras.CameraModel.resized`), must be the model's camera:
  the frames are then resized to it. Anything else is refused with one line naming the mismatch, unless
  ``allow_camera_mismatch``, which resizes every frame to the model's size (warned once).
- ``erp`` panoramas (``W = 2 H``) are rendered into the model's camera by
  :class:`~airfisheye_bench.geometry.equirect.EquirectToFisheye`, the camera looking ``yaw_deg`` / ``pitch_deg``
  away from the panorama's centre (:func:`~airfisheye_bench.geometry.transforms.gimbal_rotation`: positive pitch
  looks down), antialiased with up to 4 x 4 samples per pixel where the panorama is finer than the camera.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import torch
from PIL import Image

from airfisheye_bench.errors import ConfigError, MissingFileError
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.equirect import EquirectToFisheye
from airfisheye_bench.geometry.transforms import gimbal_rotation
from airfisheye_bench.io.calibration_files import camera_label, camera_mismatch, load_camera
from airfisheye_bench.io.layout import calibration_beside
from airfisheye_bench.prediction.footage import Footage

__all__ = [
    "INPUT_FORMATS",
    "ErpPreparer",
    "FramePreparer",
    "erp_supersample",
    "frame_preparer",
]

log = logging.getLogger(__name__)

#: ``input_format``: fisheye frames (of the model's lens) or equirectangular panoramas.
INPUT_FORMATS = ("fisheye", "erp")
#: Most samples per pixel and axis when a panorama is finer than the camera.
MAX_ERP_SUPERSAMPLE = 4


class FramePreparer:
    """Turns a fisheye frame into the model's input image, resizing it when it is of another size.

    Attributes:
        resized: Frames resized so far.
    """

    def __init__(self, camera: CameraModel) -> None:
        self.size = (camera.width, camera.height)
        self.outside = ~camera.valid_mask().numpy()
        self.resized = 0

    def __call__(self, rgb: np.ndarray) -> np.ndarray:
        """``uint8 [h, w, 3]`` -> ``uint8 [H, W, 3]`` of the model's camera."""
        if (rgb.shape[1], rgb.shape[0]) != self.size:
            # Pillow's bilinear filter widens with the scale (antialiased) and maps corner to corner, as resized().
            rgb = np.asarray(Image.fromarray(rgb).resize(self.size, Image.Resampling.BILINEAR))
            self.resized += 1
        rgb = rgb.copy()
        rgb[self.outside] = 0  # the served images are black outside the lens
        return rgb


class ErpPreparer(FramePreparer):
    """Renders an equirectangular panorama into the model's camera (one remap table per panorama size)."""

    def __init__(self, camera: CameraModel, yaw_deg: float, pitch_deg: float) -> None:
        super().__init__(camera)
        self.camera = camera
        self.rotation = gimbal_rotation(yaw_deg=yaw_deg, pitch_deg=pitch_deg)
        self.remaps: dict[tuple[int, int], EquirectToFisheye] = {}

    def __call__(self, rgb: np.ndarray) -> np.ndarray:
        size = rgb.shape[:2]
        if size not in self.remaps:
            self.remaps[size] = EquirectToFisheye(
                self.camera, size, rotation=self.rotation, supersample=erp_supersample(self.camera, size[1])
            )
        chw = torch.from_numpy(np.ascontiguousarray(rgb)).permute(
            2, 0, 1
        )  # channels-last, as the remap blends
        return self.remaps[size](chw, mode="bilinear", fill=0).permute(1, 2, 0).numpy()


def erp_supersample(camera: CameraModel, erp_width: int) -> int:
    """Samples per pixel and axis: the panorama's texels across one camera pixel at its centre, 1 to 4.

    Example:
        >>> from airfisheye_bench.geometry import ideal_camera
        >>> camera = ideal_camera(64, 64, fov_deg=190.0)  # about 3 deg per pixel
        >>> erp_supersample(camera, 128), erp_supersample(camera, 256), erp_supersample(camera, 8192)
        (1, 2, 4)
    """
    centre = camera.pixels_per_radian()[camera.height // 2, camera.width // 2]
    texels_per_pixel = (erp_width / (2 * math.pi)) / float(centre)
    return int(min(MAX_ERP_SUPERSAMPLE, max(1, math.floor(texels_per_pixel + 0.5))))


def frame_preparer(
    camera: CameraModel,
    footage: Footage,
    input_format: str = "fisheye",
    lens_file: str | None = None,
    lens_name: str | None = None,
    allow_mismatch: bool = False,
    yaw_deg: float = 0.0,
    pitch_deg: float = 0.0,
) -> FramePreparer:
    """Check that the model's ``camera`` can serve every frame of ``footage`` (headers only) and return the
    preparer of its frames.

    Args:
        camera: The model's camera.
        footage: The frames.
        input_format: ``fisheye`` or ``erp``.
        lens_file: A calibration file of the footage's lens (``camera=``; fisheye only).
        lens_name: Which camera of that file (``camera_name=``).
        allow_mismatch: Resize frames the camera cannot serve instead of refusing them (warned once).
        yaw_deg: ERP: where the camera looks, left of the panorama's centre (degrees).
        pitch_deg: ERP: how far the camera looks down (degrees).

    Raises:
        ConfigError: a frame the camera cannot serve (one line naming both and the way out), or a bad option.
        MissingFileError: ``lens_file`` does not exist.
        InputFileError: a frame whose header cannot be read.
    """
    if input_format not in INPUT_FORMATS:
        raise ConfigError(f"input_format={input_format}: expected one of {', '.join(INPUT_FORMATS)}")
    if input_format == "erp":
        if lens_file is not None:
            raise ConfigError(
                "camera= is the lens of fisheye footage; an equirectangular panorama (input_format=erp) has none"
            )
        _check_panoramas(footage, allow_mismatch)
        return ErpPreparer(camera, yaw_deg, pitch_deg)
    if yaw_deg or pitch_deg:
        raise ConfigError(
            f"erp_yaw_deg={yaw_deg:g}, erp_pitch_deg={pitch_deg:g}: they turn the view of input_format=erp; "
            "fisheye frames are seen as they were taken"
        )
    if lens_file is None:
        found = calibration_beside(footage.path)
        if found is not None:
            log.info("camera=%s: the calibration of the dataset the frames belong to", found)
            lens_file = str(found)
    problem = _fisheye_problem(camera, footage, lens_file, lens_name)
    if problem is not None:
        message, fix = problem
        if not allow_mismatch:
            raise ConfigError(f"{message}; {fix}")
        log.warning(
            "warning: %s (allow_camera_mismatch=true: frames are resized to %dx%d, the model's size)",
            message,
            camera.width,
            camera.height,
        )
    return FramePreparer(camera)


def _check_panoramas(footage: Footage, allow_mismatch: bool) -> None:
    for name, (width, height) in footage.sizes():
        if width != 2 * height:
            message = (
                f"input frame {name} is {width}x{height}, not an equirectangular panorama (input_format=erp: "
                "width = 2 x height, the whole sphere)"
            )
            if not allow_mismatch:
                raise ConfigError(f"{message}; allow_camera_mismatch=true reads it as one anyway")
            log.warning("warning: %s (allow_camera_mismatch=true: read as one anyway)", message)
            return


def _fisheye_problem(
    camera: CameraModel, footage: Footage, lens_file: str | None, lens_name: str | None
) -> tuple[str, str] | None:
    """The first reason the model's ``camera`` cannot serve the footage, and the way out; ``None`` when it can."""
    size = (camera.width, camera.height)
    resize = f"allow_camera_mismatch=true to predict anyway (frames resized to {size[0]}x{size[1]})"
    lens = None
    if lens_file is not None:
        try:
            lens = load_camera(lens_file, lens_name, option="camera_name")
        except FileNotFoundError:
            raise MissingFileError(f"camera={lens_file}: no such calibration file") from None
        except ValueError as err:
            raise ConfigError(f"camera={lens_file}: {err}") from None
        mismatch = camera_mismatch(camera, _scaled(lens, size))
        if mismatch is not None:
            return f"camera={lens_file} is not the lens the model was trained for: {mismatch}", resize
    expected = (lens.width, lens.height) if lens is not None else size
    owner = f"camera={lens_file}" if lens is not None else f"the model's camera ({camera_label(camera)})"
    for name, (width, height) in footage.sizes():
        if (width, height) != expected:
            panorama = " (2:1: an equirectangular panorama? input_format=erp)" if width == 2 * height else ""
            fix = resize
            if lens is None:
                fix = f"give camera=<its calibration file> if it is this lens at another size, or {resize}"
            message = (
                f"input frame {name} is {width}x{height} but {owner} takes {expected[0]}x{expected[1]} images"
            )
            return message + panorama, fix
    return None


def _scaled(lens: CameraModel, size: tuple[int, int]) -> CameraModel:
    """``lens`` seen at ``size`` when its aspect ratio allows, else ``lens`` (which then differs in size)."""
    if lens.width * size[1] != lens.height * size[0]:
        return lens
    return lens.resized(*size)
