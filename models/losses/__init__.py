"""Training losses of the zoo: segmentation cross-entropy, AdaBins (SILog + bin Chamfer), completion (L1 + L2)."""

from models.losses.completion import L1L2Loss, NLSPNLoss, masked_l1_l2
from models.losses.depth import AdaBinsLoss, BinsChamferLoss, SILogLoss, valid_depth_mask
from models.losses.segmentation import SegmentationCELoss

__all__ = [
    "AdaBinsLoss",
    "BinsChamferLoss",
    "L1L2Loss",
    "NLSPNLoss",
    "SILogLoss",
    "SegmentationCELoss",
    "masked_l1_l2",
    "valid_depth_mask",
]
