"""NLSPN depth completion (Park et al., ECCV 2020): network, ONNX-exportable non-local propagation.

Importing this package registers the model as ``nlspn`` for the ``completion`` task.
"""

from __future__ import annotations

from models.nlspn.model import NLSPN
from models.nlspn.propagation import (
    AFFINITY_TYPES,
    CONFIDENCE_SAMPLING,
    PROPAGATION_IMPLS,
    NonLocalPropagation,
    PropagationOutput,
    kernel_taps,
    normalize_affinity,
    sample_neighbours,
)
from models.registry import register_model

__all__ = [
    "AFFINITY_TYPES",
    "CONFIDENCE_SAMPLING",
    "NLSPN",
    "PROPAGATION_IMPLS",
    "NonLocalPropagation",
    "PropagationOutput",
    "kernel_taps",
    "nlspn",
    "normalize_affinity",
    "sample_neighbours",
]


@register_model("nlspn", task="completion")
def nlspn(**kwargs) -> NLSPN:
    """NLSPN with the AirFisheye paper defaults (ResNet34, 18 steps, TGASS, 8 neighbours); any :class:`NLSPN`
    argument can be overridden.

    Example:
        >>> import models
        >>> net = models.create_model("nlspn", encoder_name="resnet18", prop_steps=4)
        >>> models.model_task("nlspn"), net.prop_layer.steps, net.prop_layer.affinity
        ('completion', 4, 'TGASS')
    """
    return NLSPN(**kwargs)
