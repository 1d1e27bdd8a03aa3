"""Training losses of the zoo: segmentation cross-entropy, AdaBins (SILog + bin Chamfer), completion (L1 + L2).

A task's loss is chosen in its config: ``task.module.loss: {_target_: models.losses.<Loss>, _partial_: true, ...}``,
an option of the ``loss`` group (``configs/loss/<loss>.yaml``, ``loss=<loss>``; each task config picks its default).
The task module builds it and records those settings in its checkpoints.

The calling convention a loss keeps (``BenchmarkTask.loss_terms``): it is called with the model's primary output
(the task spec's ``output``: logits or depth) and the target (the spec's ``target``), or, when its class sets
``takes_model_outputs = True``, with the whole ``forward_with_aux`` mapping (AdaBins' ``"bin_edges"``); a
``terms(...)`` method of the same arguments returning ``{"loss": total, ...parts}`` has its parts logged too.
"""

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
