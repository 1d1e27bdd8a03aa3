"""Model zoo: segmentation (segmentation-models-pytorch), AdaBins (monocular depth), NLSPN (depth completion).

Calling convention shared by every model:

- inputs: ``image`` float ``[B, 3, H, W]`` normalised with ImageNet mean/std; completion models also take
  ``sparse_depth`` ``[B, 1, H, W]`` in metres (range), 0 where there is no LiDAR return; a model built with
  ``camera_input="rays"`` also takes the keyword input ``rays`` ``[B, 4, H, W]``, the ray map of its camera
  (:mod:`models.camera_input`), and refuses to run without it.
- ``forward(...)`` returns the primary output only: segmentation logits ``[B, C, H, W]`` or depth ``[B, 1, H, W]``
  in metres at the input resolution. This is what is exported to ONNX.
- ``forward_with_aux(...)`` returns a dict holding the primary output (``"logits"`` or ``"depth"``) and any auxiliary
  outputs the training loss needs (e.g. AdaBins ``"bin_edges"``).
- constructors take ``encoder_weights`` (``None``, ``"imagenet"`` or a local file) and ``weights_path``, and keep
  ``weights_identity``, the record of what was loaded (see :mod:`models.weights`).
"""

from models.registry import create_model, list_models, model_task, register_model

__all__ = ["create_model", "list_models", "model_task", "register_model"]

# Importing the zoo's subpackages registers their models.
import models.adabins
import models.nlspn
import models.segmentation  # noqa: F401
