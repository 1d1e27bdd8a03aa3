"""AdaBins monocular depth (registered as ``adabins``; defaults = the AirFisheye paper: ResNet50, 256 bins,
depth range [1e-3, 120] m)."""

from __future__ import annotations

from models.adabins.decoder import DecoderBN, UpSampleBN
from models.adabins.mini_vit import (
    MiniViT,
    PatchTransformerEncoder,
    PixelWiseDotProduct,
    normalize_bin_widths,
)
from models.adabins.model import UnetAdaptiveBins
from models.registry import register_model

__all__ = [
    "DecoderBN",
    "MiniViT",
    "PatchTransformerEncoder",
    "PixelWiseDotProduct",
    "UnetAdaptiveBins",
    "UpSampleBN",
    "adabins",
    "normalize_bin_widths",
]


@register_model("adabins", task="depth")
def adabins(**kwargs) -> UnetAdaptiveBins:
    """AdaBins with the paper defaults; any :class:`UnetAdaptiveBins` argument can be overridden.

    Example:
        >>> import models
        >>> net = models.create_model("adabins", encoder_name="resnet18", n_bins=32, decoder_features=64)
        >>> net.n_bins, net.max_depth, net.output_stride
        (32, 120.0, 32)
    """
    return UnetAdaptiveBins(**kwargs)
