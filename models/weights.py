"""Load local weight files into zoo models (no downloads: this project never fetches weights at run time)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import torch
from torch import Tensor, nn


def load_weights(module: nn.Module, path: str | os.PathLike, strict: bool = True) -> nn.Module:
    """Load a local state dict into ``module`` and return it.

    Accepts a plain state dict, a Lightning checkpoint (``{"state_dict": ...}``) or ``{"model": ...}``, saved
    with ``torch.save`` or as ``.safetensors``. Keys may carry a prefix (e.g. ``"model."`` from a
    LightningModule attribute, ``"module."`` from DDP); the prefix is found by matching the module's own keys
    and stripped, and keys outside it are ignored. Files are read with ``weights_only=True`` (no pickled code).

    Args:
        module: the model (or submodule, e.g. an encoder) to fill.
        path: the file.
        strict: require every key of ``module`` to be present (and no unexpected key after prefix stripping).

    Raises:
        ValueError: the file does not exist, holds no state dict, or shares no key with ``module``.

    Example:
        >>> import tempfile, torch
        >>> net = torch.nn.Linear(2, 2)
        >>> path = tempfile.mkdtemp() + "/ckpt.pt"
        >>> torch.save({"state_dict": {"model." + k: v for k, v in net.state_dict().items()}}, path)
        >>> other = load_weights(torch.nn.Linear(2, 2), path)
        >>> torch.equal(other.weight, net.weight)
        True
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"weights_path {str(path)!r} does not exist or is not a file")
    if path.suffix == ".safetensors":
        from safetensors.torch import load_file

        state = load_file(str(path), device="cpu")
    else:
        state = torch.load(path, map_location="cpu", weights_only=True)
    for key in ("state_dict", "model"):
        if isinstance(state, Mapping) and isinstance(state.get(key), Mapping):
            state = state[key]
    if not isinstance(state, Mapping) or not all(isinstance(v, Tensor) for v in state.values()):
        raise ValueError(f"weights_path {str(path)!r} holds no state dict of tensors")
    state = _strip_prefix(dict(state), set(module.state_dict()), path)
    module.load_state_dict(state, strict=strict)
    return module


def _strip_prefix(state: dict[str, Tensor], own_keys: set[str], path: Path) -> dict[str, Tensor]:
    if own_keys & state.keys():
        return state
    # Find the shortest prefix p such that p + <own key> is in the file, then keep only keys under p.
    prefixes = {k[: len(k) - len(own)] for own in own_keys for k in state if k.endswith(own) and k != own}
    prefixes = {p for p in prefixes if p.endswith(".")}
    if not prefixes:
        raise ValueError(f"weights_path {str(path)!r} shares no parameter name with the model")
    prefix = min(prefixes, key=len)
    return {k[len(prefix) :]: v for k, v in state.items() if k.startswith(prefix)}
