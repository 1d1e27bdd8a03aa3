"""NLSPN depth-completion network (Park et al., "Non-Local Spatial Propagation Network for Depth Completion",
ECCV 2020), following the official code zzangjinsun/NLSPN_ECCV20 (``src/model/nlspnmodel.py``).

Architecture (strides relative to the input):

- stems at full resolution without BN: RGB 3 -> 48 and sparse depth 1 -> 16 channels, concatenated to 64;
- ResNet stages ``layer1..layer4`` (torchvision, no stem / max-pool) at 1, 1/2, 1/4, 1/8, then ``conv6`` at 1/16;
- a shared decoder of stride-2 ``ConvTranspose2d`` blocks with skip concatenation (decoder maps are cropped at the
  bottom/right to the skip size, so any input size works);
- three full-resolution heads: initial depth (conv + LeakyReLU, no BN), guidance (``k*k - 1`` affinity channels,
  no activation) and confidence (conv + sigmoid);
- :class:`~models.nlspn.propagation.NonLocalPropagation`, then ``clamp(min=0)``.

Module names match upstream (``conv1_rgb``, ``conv2`` .. ``conv6``, ``dec5`` .. ``dec2``, ``id_dec*``, ``gd_dec*``,
``cf_dec*``, ``prop_layer``), so an upstream state dict loads after stripping ``module.`` and dropping the
constant ``prop_layer.w``, ``prop_layer.b`` and ``prop_layer.w_conf`` tensors (released checkpoints need
``confidence_sampling="legacy"``).
"""

from __future__ import annotations

import os

import torch
from torch import Tensor, nn

from models.camera_input import RAY_MAP_CHANNELS, check_camera_input, check_rays, widen_conv, widen_first_conv
from models.input_checks import check_image, check_sparse_depth
from models.nlspn.blocks import conv_bn_relu, convt_bn_relu, resnet_stages
from models.nlspn.propagation import NonLocalPropagation
from models.weights import load_weights, resolve_weights_path, weights_identity

__all__ = ["NLSPN"]


class NLSPN(nn.Module):
    """NLSPN: encoder-decoder predicting initial depth, guidance and confidence, refined by non-local propagation.

    Follows the zoo calling convention (``models/__init__.py``): ``forward(image, sparse_depth, rays=None)`` returns
    the completed depth ``[B, 1, H, W]`` in metres (exported to ONNX); ``forward_with_aux`` also returns the
    intermediate outputs.

    Args:
        encoder_name: ``"resnet34"`` (paper) or ``"resnet18"``.
        encoder_weights: ``None`` (random), ``"imagenet"`` (torchvision's, through the torch hub cache, as
            upstream's ``pretrained/resnet34.pth``) or a local torchvision/timm ResNet ``state_dict`` file for the
            encoder stages; see :mod:`models.weights`.
        weights_path: optional local file with weights for the whole model (state dict or Lightning checkpoint).
        prop_steps: propagation steps (paper: 18).
        prop_kernel: neighbourhood size ``k``; ``k*k - 1`` non-local neighbours (paper: 3 -> 8).
        affinity: affinity normalisation, ``"TGASS"`` (paper), ``"TC"``, ``"AS"`` or ``"ASS"``.
        affinity_gamma: TGASS initial ``gamma / (k*k - 1)``.
        conf_prop: confidence branch, used to weight the affinities (upstream default True).
        preserve_input: replace valid sparse pixels before every propagation step (upstream ``--preserve_input``,
            off by default as upstream; used with its released NYU and KITTI models).
        confidence_sampling: ``"offset"`` (default, upstream non-legacy), ``"neighbour"`` (the paper's text,
            upstream issue #46) or ``"legacy"``; see :mod:`models.nlspn.propagation`.
        propagation_impl: ``"grid_sample"`` (default) or ``"deform_conv"`` (torchvision DCN, ONNX opset >= 19).
        camera_input: ``"none"`` or ``"rays"``: the ray map ``rays`` ``[B, 4, H, W]`` enters the RGB stem (4 more
            input channels) and, at full resolution, the first layer of each head (initial depth, guidance,
            confidence) beside the decoder's features; the weights reading it start at zero
            (:mod:`models.camera_input`).

    Example:
        >>> model = NLSPN(encoder_name="resnet18", prop_steps=2).eval()
        >>> image, sparse = torch.randn(1, 3, 32, 48), torch.zeros(1, 1, 32, 48)
        >>> sparse[..., ::7, ::5] = 10.0
        >>> with torch.no_grad():
        ...     out = model.forward_with_aux(image, sparse)
        >>> out["depth"].shape, bool((out["depth"] >= 0).all()), sorted(out)[:3]
        (torch.Size([1, 1, 32, 48]), True, ['affinity', 'confidence', 'depth'])
    """

    #: smallest accepted height/width: one pixel at the coarsest (1/16) encoder level.
    min_size = 16

    def __init__(
        self,
        encoder_name: str = "resnet34",
        encoder_weights: str | os.PathLike | None = None,
        weights_path: str | os.PathLike | None = None,
        prop_steps: int = 18,
        prop_kernel: int = 3,
        affinity: str = "TGASS",
        affinity_gamma: float = 0.5,
        conf_prop: bool = True,
        preserve_input: bool = False,
        confidence_sampling: str = "offset",
        propagation_impl: str = "grid_sample",
        camera_input: str = "none",
    ) -> None:
        super().__init__()
        self.camera_input = check_camera_input(camera_input)
        num_neighbours = prop_kernel * prop_kernel - 1
        self.conf_prop = conf_prop

        # Encoder. Names and strides as upstream: conv2..conv5 are the ResNet stages at 1, 1/2, 1/4, 1/8.
        self.conv1_rgb = conv_bn_relu(3, 48, bn=False)
        self.conv1_dep = conv_bn_relu(1, 16, bn=False)
        stages, encoder_record = resnet_stages(encoder_name, encoder_weights)
        self.conv2, self.conv3, self.conv4, self.conv5 = stages
        self.conv6 = conv_bn_relu(512, 512, stride=2)  # 1/16

        # Shared decoder (input channels = decoder + skip).
        self.dec5 = convt_bn_relu(512, 256)  # 1/8
        self.dec4 = convt_bn_relu(256 + 512, 128)  # 1/4
        self.dec3 = convt_bn_relu(128 + 256, 64)  # 1/2
        self.dec2 = convt_bn_relu(64 + 128, 64)  # 1/1

        # Heads at full resolution, each fed by the decoder and the stage-1 / stem skips.
        self.id_dec1 = conv_bn_relu(64 + 64, 64)
        self.id_dec0 = conv_bn_relu(64 + 64, 1, bn=False, relu=True)
        self.gd_dec1 = conv_bn_relu(64 + 64, 64)
        self.gd_dec0 = conv_bn_relu(64 + 64, num_neighbours, bn=False, relu=False)
        if conf_prop:
            self.cf_dec1 = conv_bn_relu(64 + 64, 32)
            self.cf_dec0 = nn.Sequential(nn.Conv2d(32 + 64, 1, kernel_size=3, padding=1), nn.Sigmoid())

        self.prop_layer = NonLocalPropagation(
            guidance_channels=num_neighbours,
            kernel_size=prop_kernel,
            steps=prop_steps,
            affinity=affinity,
            affinity_gamma=affinity_gamma,
            conf_prop=conf_prop,
            preserve_input=preserve_input,
            confidence_sampling=confidence_sampling,
            impl=propagation_impl,
        )
        if self.camera_input == "rays":
            widen_first_conv(self.conv1_rgb, RAY_MAP_CHANNELS)
            for head in (self.id_dec1, self.gd_dec1, *((self.cf_dec1,) if conf_prop else ())):
                head[0] = widen_conv(head[0], RAY_MAP_CHANNELS)
        weights_path = resolve_weights_path(weights_path)
        if weights_path is not None:
            load_weights(self, weights_path, what="weights_path")
        self.weights_identity = weights_identity(encoder_record, weights_path)

    def forward(self, image: Tensor, sparse_depth: Tensor, rays: Tensor | None = None) -> Tensor:
        """Completed depth ``[B, 1, H, W]`` (metres, >= 0) from ``image`` ``[B, 3, H, W]`` (ImageNet-normalised)
        and ``sparse_depth`` ``[B, 1, H, W]`` (metres, 0 = no return); ``rays`` ``[B, 4, H, W]`` with
        ``camera_input="rays"``."""
        return self.forward_with_aux(image, sparse_depth, rays)["depth"]

    def forward_with_aux(
        self, image: Tensor, sparse_depth: Tensor, rays: Tensor | None = None
    ) -> dict[str, Tensor]:
        """All outputs: ``depth`` (final, clamped >= 0), ``initial_depth`` (before propagation), ``guidance``
        ``[B, n, H, W]``, ``offset`` ``[B, n, 2, H, W]``, ``affinity`` ``[B, n + 1, H, W]`` (normalised, centre at
        ``n // 2``) and, with ``conf_prop``, ``confidence`` ``[B, 1, H, W]``."""
        self._check_inputs(image, sparse_depth)
        check_rays(rays, image, self.camera_input)
        rgb = image if rays is None else torch.cat((image, rays), dim=1)
        fe1 = torch.cat((self.conv1_rgb(rgb), self.conv1_dep(sparse_depth)), dim=1)
        fe2 = self.conv2(fe1)
        fe3 = self.conv3(fe2)
        fe4 = self.conv4(fe3)
        fe5 = self.conv5(fe4)
        fe6 = self.conv6(fe5)

        fd5 = self.dec5(fe6)
        fd4 = self.dec4(_crop_cat(fd5, fe5))
        fd3 = self.dec3(_crop_cat(fd4, fe4))
        fd2 = self.dec2(_crop_cat(fd3, fe3))
        fd2_skip = _crop_cat(fd2, fe2)
        if rays is not None:  # the heads see each pixel's ray beside the decoder's features
            fd2_skip = torch.cat((fd2_skip, rays), dim=1)

        init_depth = self.id_dec0(torch.cat((self.id_dec1(fd2_skip), fe1), dim=1))
        guidance = self.gd_dec0(torch.cat((self.gd_dec1(fd2_skip), fe1), dim=1))
        confidence = None
        if self.conf_prop:
            confidence = self.cf_dec0(torch.cat((self.cf_dec1(fd2_skip), fe1), dim=1))

        prop = self.prop_layer(init_depth, guidance, confidence, sparse_depth)
        out = {
            "depth": prop.depth.clamp(min=0),
            "initial_depth": init_depth,
            "guidance": guidance,
            "offset": prop.offset,
            "affinity": prop.affinity,
        }
        if confidence is not None:
            out["confidence"] = confidence
        return out

    def _check_inputs(self, image: Tensor, sparse_depth: Tensor) -> None:
        check_image(image, in_channels=3)
        check_sparse_depth(sparse_depth, image)
        h, w = image.shape[-2:]
        if h < self.min_size or w < self.min_size:
            raise ValueError(f"image height and width must be >= {self.min_size}, got {h}x{w}")


def _crop_cat(decoded: Tensor, skip: Tensor) -> Tensor:
    """Concatenate a decoder map with its skip; the decoder may be larger (odd sizes), crop bottom/right."""
    return torch.cat((decoded[:, :, : skip.shape[2], : skip.shape[3]], skip), dim=1)
