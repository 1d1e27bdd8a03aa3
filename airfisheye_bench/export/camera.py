"""A camera-aware model's ray map at export (``model.camera_input=rays``; docs/design.md, "Ray map").

The ONNX file of such a model takes the ray map as a second named input, ``rays`` ``[B, 4, H, W]``, which a consumer
computes from its lens (``geometry.ray_maps.ray_map``); with ``bake_camera=true`` the data's camera's map is stored
in the graph as a constant instead, and the file takes the image alone (for a deployment on that one lens).
"""

from __future__ import annotations

from torch import Tensor, nn

__all__ = ["BakedRays", "bake_problem"]


class BakedRays(nn.Module):
    """``net`` with its ray map fixed: ``forward(image[, sparse_depth])`` calls ``net(..., rays=<the map>)``.

    Args:
        net: A zoo model built with ``camera_input="rays"``.
        rays: ``[4, H, W]``, the camera's ray map (``datamodule.ray_map()``), held as a buffer (an ONNX constant).
    """

    def __init__(self, net: nn.Module, rays: Tensor) -> None:
        super().__init__()
        self.net = net
        self.register_buffer("rays", rays.detach().float()[None].contiguous())

    def forward(self, image: Tensor, sparse_depth: Tensor | None = None) -> Tensor:
        rays = self.rays.expand(image.shape[0], -1, -1, -1)
        if sparse_depth is None:
            return self.net(image, rays=rays)
        return self.net(image, sparse_depth, rays=rays)


def bake_problem(bake_camera: bool, camera_input: str, dynamic_spatial: bool) -> str | None:
    """Why ``bake_camera`` cannot be honoured (``None``: it can).

    Example:
        >>> bake_problem(True, "none", False)
        'bake_camera=true bakes the ray map of a camera-aware model in, and this model takes none (its model.camera_input is none)'
    """
    if not bake_camera:
        return None
    if camera_input != "rays":
        return (
            "bake_camera=true bakes the ray map of a camera-aware model in, and this model takes none "
            f"(its model.camera_input is {camera_input})"
        )
    if dynamic_spatial:
        return (
            "bake_camera=true fixes the image to the camera's size (its ray map is a constant): drop "
            "dynamic_spatial=true, or export without bake_camera (the file then takes rays as an input)"
        )
    return None
