"""The ray map: a camera's geometry as input maps of a model (docs/design.md, "Ray map").

A camera-aware model (``model.camera_input=rays``, as CAM-Convs, arXiv 1904.02028, and OmniDet's camera tensor)
takes, beside the image, the map of its lens: ``[4, H, W]`` float32, channels 0-2 the unit ray ``(x, y, z)`` of
each pixel centre in the camera frame (OpenCV: x right, y down, z forward; docs/design.md, "Frames and units"),
channel 3 one where the pixel carries data and zero elsewhere, where the ray is zeroed too. It is computed from
the lens (``CameraModel.ray_grid()``), never learned per lens, so one model serves any lens it is given the map of.

Example:
    >>> from airfisheye_bench.geometry.cameras import ideal_camera
    >>> rays = ray_map(ideal_camera(32, 32, fov_deg=180.0))
    >>> rays.shape, rays.dtype
    (torch.Size([4, 32, 32]), torch.float32)
    >>> float(rays[3, 0, 0]), rays[:, 0, 0].tolist()  # a corner lies outside the image circle
    (0.0, [0.0, 0.0, 0.0, 0.0])
    >>> bool(torch.allclose(rays[:3, 16, 16].norm(), torch.tensor(1.0)))
    True
"""

from __future__ import annotations

import torch

from airfisheye_bench.geometry.cameras import CameraModel

__all__ = ["CAMERA_INPUTS", "RAY_MAP_CHANNELS", "check_camera_input", "ray_map"]

#: What a model may take of its camera besides the image (``model.camera_input``, ``data.camera_input``):
#: ``none``, or the ray map (sample key ``rays``).
CAMERA_INPUTS = ("none", "rays")
#: Channels of a ray map: the unit ray's x, y, z and the valid flag.
RAY_MAP_CHANNELS = 4


def ray_map(camera: CameraModel, valid: torch.Tensor | None = None) -> torch.Tensor:
    """The ray map ``[4, H, W]`` float32 of ``camera`` (see the module docstring).

    Args:
        camera: The lens, at the served size.
        valid: ``[H, W]`` bool, the pixels that carry data (a dataset's: inside the lens's field of view, on a cube
            face, on a calibration's sensor); ``None``: the camera's own ``valid_mask()``.

    Raises:
        ValueError: ``valid`` is not ``[H, W]`` of the camera.
    """
    mask = camera.valid_mask() if valid is None else valid.bool()
    if mask.shape != (camera.height, camera.width):
        raise ValueError(
            f"valid must be [{camera.height}, {camera.width}] (the camera's size), got {list(mask.shape)}"
        )
    rays = camera.ray_grid(torch.float32).permute(2, 0, 1)  # NaN where the lens has no ray: masked below
    rays = torch.where(mask, rays, torch.zeros((), dtype=torch.float32))
    return torch.cat([rays, mask[None].float()]).contiguous()


def check_camera_input(value: object, key: str = "camera_input") -> str:
    """``value`` if it is one of :data:`CAMERA_INPUTS`.

    Raises:
        ValueError: one line naming ``key`` and the choices.

    Example:
        >>> check_camera_input("ray", "model.camera_input")
        Traceback (most recent call last):
        ...
        ValueError: model.camera_input must be one of none, rays, got 'ray'
    """
    if value not in CAMERA_INPUTS:
        raise ValueError(f"{key} must be one of {', '.join(CAMERA_INPUTS)}, got {value!r}")
    return str(value)
