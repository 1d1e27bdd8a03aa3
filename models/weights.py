"""Initial weights of zoo models: ImageNet encoders, local weight files, and the record of what was loaded.

Every model takes ``encoder_weights``, one of:

- ``None``: random initialisation (the quick start: nothing is read or downloaded);
- ``"imagenet"``: the encoder's ImageNet weights, fetched once through the library that defines the encoder
  (segmentation-models-pytorch from the Hugging Face Hub, timm, or torchvision) into that library's cache
  (``HF_HOME`` / ``HF_HUB_CACHE``, ``TORCH_HOME``). Offline and not cached: one :class:`WeightsUnavailableError`
  naming the cache and the file to place there;
- a local file: a torchvision or timm ResNet ``state_dict`` (``fc.*`` is ignored), or a checkpoint holding one.

Files are read with ``weights_only=True`` (tensors and plain containers only): a corrupt file, or one holding
arbitrary pickled objects, is refused with a :class:`ValueError` naming it. Each model keeps
``weights_identity`` (:func:`weights_identity`): what it started from, with the SHA-256 of the files, which
training and export write into ``results.json`` and the ONNX metadata.

A checkpoint restores every weight, so rebuilding its model must not fetch anything:
:func:`pretrained_weights_disabled` switches ``encoder_weights`` and ``weights_path`` off while it is active.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import os
import socket
import threading
import urllib.error
import urllib.parse
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, TypeVar

import torch
from torch import Tensor, nn

from airfisheye_bench.errors import UserError
from airfisheye_bench.io.manifest import sha256_file

__all__ = [
    "IMAGENET",
    "WeightsUnavailableError",
    "build_smp_with_encoder_weights",
    "file_identity",
    "load_weights",
    "pretrained_weights_disabled",
    "read_state_dict",
    "resolve_encoder_weights",
    "resolve_weights_path",
    "smp_pretrained",
    "torchvision_imagenet_state",
    "weights_identity",
]

IMAGENET = "imagenet"
#: File suffixes that mark an ``encoder_weights`` value as a path even when it does not exist (clear error).
_WEIGHT_SUFFIXES = (".pt", ".pth", ".bin", ".ckpt", ".safetensors", ".tar")

_DISABLED: contextvars.ContextVar[bool] = contextvars.ContextVar("pretrained_weights_disabled", default=False)

T = TypeVar("T")


class WeightsUnavailableError(UserError, RuntimeError):
    """Pretrained weights are neither cached nor downloadable (offline); the message says where to put them."""


@contextlib.contextmanager
def pretrained_weights_disabled() -> Iterator[None]:
    """Build models without reading ``encoder_weights`` or ``weights_path`` (their weights come from elsewhere).

    Example:
        >>> import models
        >>> with pretrained_weights_disabled():
        ...     net = models.create_model("deeplabv3plus", encoder_name="resnet18", encoder_weights="imagenet")
        >>> net.weights_identity["encoder_weights"] is None
        True
    """
    token = _DISABLED.set(True)
    try:
        yield
    finally:
        _DISABLED.reset(token)


def resolve_encoder_weights(spec: str | os.PathLike | None) -> tuple[str | None, Path | None]:
    """Split an ``encoder_weights`` value into ``(pretrained tag, local file)``; at most one is set.

    A value with a path separator or a weights-file suffix is a file (it must exist); another string is a
    pretrained tag of the encoder's library (``"imagenet"``). Inside :func:`pretrained_weights_disabled`
    both are ``None``.

    Raises:
        ValueError: a file that does not exist, or a value that is neither a string nor a path.

    Example:
        >>> resolve_encoder_weights("imagenet"), resolve_encoder_weights(None)
        (('imagenet', None), (None, None))
        >>> resolve_encoder_weights("/nonexistent/resnet50.pth")
        Traceback (most recent call last):
        ...
        ValueError: encoder_weights '/nonexistent/resnet50.pth' does not exist; expected null, 'imagenet' or a local weights file
    """
    if spec is None or _DISABLED.get():
        return None, None
    if not isinstance(spec, (str, os.PathLike)):
        raise ValueError(f"encoder_weights must be null, 'imagenet' or a file path, got {spec!r}")
    text = os.fspath(spec)
    looks_like_file = isinstance(spec, os.PathLike) or os.sep in text or "/" in text
    if looks_like_file or text.endswith(_WEIGHT_SUFFIXES) or Path(text).is_file():
        path = Path(text).expanduser()
        if not path.is_file():
            raise ValueError(
                f"encoder_weights {text!r} does not exist; expected null, 'imagenet' or a local weights file"
            )
        return None, path
    return text, None


def resolve_weights_path(path: str | os.PathLike | None) -> Path | None:
    """The ``weights_path`` to load: ``None`` when unset or inside :func:`pretrained_weights_disabled`."""
    return None if path is None or _DISABLED.get() else Path(path)


def file_identity(path: str | os.PathLike, **extra: Any) -> dict[str, Any]:
    """``{**extra, "file": absolute path, "sha256": hex digest}`` of a weights file."""
    path = Path(path)
    return {**extra, "file": str(path.resolve()), "sha256": sha256_file(path)}


def weights_identity(encoder: dict[str, Any] | None, weights_path: Path | None) -> dict[str, Any]:
    """What a model started from: ``{"encoder_weights": record or None, "weights_path": record or None}``.

    A record holds the ``encoder_weights`` value, its ``source`` for downloaded weights, and the ``file`` and
    ``sha256`` of what was read (see :func:`file_identity`).
    """
    return {
        "encoder_weights": encoder,
        "weights_path": None if weights_path is None else file_identity(weights_path),
    }


def read_state_dict(path: str | os.PathLike, what: str = "weights file") -> dict[str, Tensor]:
    """A state dict from a ``torch.save`` / ``.safetensors`` file, unwrapping ``state_dict`` / ``model`` keys.

    Raises:
        ValueError: the file does not exist, cannot be read safely (corrupt, or pickled objects other than
            tensors and plain containers), or holds no mapping of tensors. The message names the file.

    Example:
        >>> import tempfile
        >>> path = Path(tempfile.mkdtemp()) / "bad.pth"
        >>> _ = path.write_bytes(b"not a checkpoint")
        >>> read_state_dict(path)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        ValueError: weights file '.../bad.pth' is not a readable weights file (...): ...
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{what} {str(path)!r} does not exist or is not a file")
    try:
        if path.suffix == ".safetensors":
            from safetensors.torch import load_file  # only .safetensors files need it (it comes with timm)

            state = load_file(str(path), device="cpu")
        else:
            state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # any decoding failure means a bad file; torch's own text advises unsafe loading
        raise ValueError(
            f"{what} {str(path)!r} is not a readable weights file ({type(err).__name__}): expected a state_dict "
            "of tensors saved with torch.save or safetensors; a corrupt file, or one holding pickled objects "
            "other than tensors and plain containers, is refused"
        ) from None
    for key in ("state_dict", "model"):
        if isinstance(state, Mapping) and isinstance(state.get(key), Mapping):
            state = state[key]
    if not isinstance(state, Mapping) or not state or not all(isinstance(v, Tensor) for v in state.values()):
        raise ValueError(f"{what} {str(path)!r} holds no state dict of tensors")
    return dict(state)


def load_weights(
    module: nn.Module, path: str | os.PathLike, strict: bool = True, what: str = "weights file"
) -> nn.Module:
    """Load a local state dict into ``module`` and return it.

    Accepts a plain state dict, a Lightning checkpoint (``{"state_dict": ...}``) or ``{"model": ...}``, saved
    with ``torch.save`` or as ``.safetensors`` (see :func:`read_state_dict`). Keys may carry a prefix (e.g.
    ``"model."`` from a LightningModule attribute, ``"module."`` from DDP); the prefix is found by matching the
    module's own keys and stripped, and keys outside it are ignored.

    Args:
        module: the model (or submodule, e.g. an encoder) to fill.
        path: the file.
        strict: require every key of ``module`` to be present (and no unexpected key after prefix stripping).
        what: how error messages name the file (e.g. the config key it came from).

    Raises:
        ValueError: see :func:`read_state_dict`; or the file shares no key with ``module``, or its tensors do
            not fit it.

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
    state = _strip_prefix(read_state_dict(path, what), set(module.state_dict()), path, what)
    try:
        module.load_state_dict(state, strict=strict)
    except RuntimeError as err:  # missing / unexpected keys or shape mismatches: say which file
        raise ValueError(f"{what} {str(path)!r} does not fit {type(module).__name__}: {err}") from None
    return module


def smp_pretrained(build: Callable[[str | bool], T], encoder_name: str, tag: str) -> tuple[T, dict[str, Any]]:
    """``build(weights)`` with segmentation-models-pytorch's pretrained ``tag``, and the record of the file.

    smp fetches its encoders from the Hugging Face Hub (``smp-hub/<encoder>.<tag>``) and ``tu-`` encoders through
    timm, both into the Hugging Face cache; a failed fetch becomes one :class:`WeightsUnavailableError`.

    Args:
        build: builds the model or encoder given smp's ``encoder_weights`` argument.
        encoder_name: smp encoder name (``resnet50``) or ``tu-<timm name>``.
        tag: pretrained tag, ``"imagenet"`` for every ResNet.
    """
    # smp's encoder table and the hub client take seconds to import: loaded when pretrained weights are looked up
    from huggingface_hub import constants, try_to_load_from_cache
    from segmentation_models_pytorch.encoders import encoders

    timm_name = encoder_name[3:] if encoder_name.startswith("tu-") else None
    if timm_name is not None:
        repo, filename, revision = _timm_hub_file(timm_name)
        source = f"timm:{timm_name}"
    else:
        settings = encoders.get(encoder_name, {}).get("pretrained_settings", {})
        if tag not in settings:
            raise ValueError(
                f"encoder_weights={tag!r} is not available for encoder {encoder_name!r}; "
                f"choose one of {sorted(settings) or 'none'}, a local weights file, or null"
            )
        repo, filename, revision = settings[tag]["repo_id"], "model.safetensors", settings[tag]["revision"]
        source = f"hf:{repo}@{revision}"
    cached = try_to_load_from_cache(repo, filename, revision=revision) if repo else None
    offline = None if isinstance(cached, str) else network_unavailable(constants.ENDPOINT)
    try:
        if offline is not None:  # not cached and no network: fail at once, not after the hub's retries
            raise ConnectionError(offline)
        built = build(True if timm_name is not None else tag)
    except Exception as err:
        if not _is_download_failure(err):
            raise
        where = Path(constants.HF_HUB_CACHE)
        wanted = f"{repo}/{filename}" if repo else f"timm's {timm_name} weights"
        folder = where / ("models--" + repo.replace("/", "--")) if repo else where
        reason = offline or type(err).__name__
        raise WeightsUnavailableError(
            f"encoder_weights={tag!r} for encoder {encoder_name!r} needs {wanted} from the Hugging Face Hub, "
            f"which is not in its cache ({where}; set by HF_HOME or HF_HUB_CACHE) and could not be downloaded "
            f'({reason}). On a machine with network, run python -c "import '
            f"segmentation_models_pytorch as smp; smp.encoders.get_encoder('{encoder_name}', weights="
            f'{True if timm_name else repr(tag)})" and copy the folder {folder.name} of its cache to {folder}; '
            "or set encoder_weights to a local ResNet state_dict file (torchvision or timm), or to null to train "
            "from scratch."
        ) from None
    record: dict[str, Any] = {"encoder_weights": tag, "source": source}
    cached = try_to_load_from_cache(repo, filename, revision=revision) if repo else None
    if isinstance(cached, str) and Path(cached).is_file():
        record = file_identity(cached, **record)
    return built, record


def build_smp_with_encoder_weights(
    build: Callable[[str | bool | None], T],
    encoder_name: str,
    encoder_weights: str | os.PathLike | None,
    encoder_of: Callable[[T], nn.Module] = lambda module: module,
) -> tuple[T, dict[str, Any] | None]:
    """``build(weights)`` with ``encoder_weights`` applied (see :func:`resolve_encoder_weights`), and its record.

    ``imagenet`` (or another smp tag) goes through :func:`smp_pretrained`; a local file is loaded into
    ``encoder_of(module)``; ``None`` builds from random initialisation (record ``None``).
    """
    tag, encoder_file = resolve_encoder_weights(encoder_weights)
    if tag is not None:
        return smp_pretrained(build, encoder_name, tag)
    module = build(None)
    if encoder_file is None:
        return module, None
    load_weights(encoder_of(module), encoder_file, what="encoder_weights")
    return module, file_identity(encoder_file, encoder_weights=str(encoder_weights))


def torchvision_imagenet_state(name: str) -> tuple[dict[str, Tensor], dict[str, Any]]:
    """The ImageNet ``state_dict`` of torchvision's ``name`` (``resnet34``) and its record, via the torch hub cache.

    Raises:
        WeightsUnavailableError: not in ``<TORCH_HOME>/hub/checkpoints`` and not downloadable; the message
            gives the URL and the exact path to place the file at.
    """
    import torchvision  # seconds to import: loaded when torchvision's weights are looked up

    weights = torchvision.models.get_model_weights(name).DEFAULT
    path = Path(torch.hub.get_dir()) / "checkpoints" / os.path.basename(weights.url)
    offline = None if path.is_file() else network_unavailable(weights.url)
    try:
        if offline is not None:
            raise ConnectionError(offline)
        state = weights.get_state_dict(progress=False, check_hash=True)
    except Exception as err:
        if not _is_download_failure(err):
            raise
        raise WeightsUnavailableError(
            f"encoder_weights='imagenet' for {name} needs torchvision's {weights} ({weights.url}), which is not "
            f"in the torch hub cache ({path.parent}; set by TORCH_HOME) and could not be downloaded "
            f"({offline or type(err).__name__}). Download that URL on a machine with network and place the file at {path}; "
            "or set encoder_weights to a local ResNet state_dict file, or to null to train from scratch."
        ) from None
    return state, file_identity(path, encoder_weights=IMAGENET, source=f"torchvision:{weights}")


#: Seconds the network probe waits for a name lookup and a connection before calling the network unavailable.
PROBE_TIMEOUT_S = 3.0


@functools.cache
def network_unavailable(url: str, timeout: float = PROBE_TIMEOUT_S) -> str | None:
    """Why ``url``'s server cannot be reached (offline mode, no name lookup, no connection), or ``None``.

    Asked once per server and process, before a download that would otherwise retry for half a minute (the
    Hugging Face client backs off five times). ``HF_HUB_OFFLINE=1`` answers at once; otherwise a name lookup and a
    TCP connection to the server's port, given ``timeout`` seconds in all (in a thread: a lookup ignores socket
    timeouts).

    Example:
        >>> network_unavailable("https://127.0.0.1:9/")  # doctest: +ELLIPSIS
        'no connection to 127.0.0.1:9 (...)'
    """
    from huggingface_hub import constants  # the hub's own switch; loaded when a download is about to happen

    if constants.HF_HUB_OFFLINE:
        return "HF_HUB_OFFLINE is set"
    parsed = urllib.parse.urlparse(url)
    host, port = parsed.hostname or "", parsed.port or (443 if parsed.scheme == "https" else 80)
    outcome: list[str | None] = []

    def probe() -> None:
        try:
            socket.getaddrinfo(host, port)
        except OSError as err:
            outcome.append(f"cannot look up {host}: {err.strerror or err}")
            return
        try:
            socket.create_connection((host, port), timeout=timeout).close()
        except OSError as err:
            outcome.append(f"no connection to {host}:{port} ({err.strerror or type(err).__name__})")
            return
        outcome.append(None)

    thread = threading.Thread(target=probe, daemon=True)
    thread.start()
    thread.join(timeout)
    return outcome[0] if outcome else f"no answer from {host} within {timeout:g} s"


def _timm_hub_file(timm_name: str) -> tuple[str | None, str, str | None]:
    """The Hugging Face repo and file timm loads ``timm_name``'s pretrained weights from (``None`` if elsewhere)."""
    import timm  # seconds to import: loaded when a timm encoder's weights are looked up

    cfg = timm.models.get_pretrained_cfg(timm_name)
    repo = getattr(cfg, "hf_hub_id", None) if cfg is not None else None
    return repo, "model.safetensors", None


def _is_download_failure(err: BaseException) -> bool:
    """Whether ``err`` (or what caused it) is a failed fetch: no network, offline mode, or not in the cache."""
    from huggingface_hub import errors as hub_errors  # loaded on a failed fetch only

    kinds: tuple[type[BaseException], ...] = (
        urllib.error.URLError,
        ConnectionError,
        TimeoutError,
        hub_errors.LocalEntryNotFoundError,
        hub_errors.OfflineModeIsEnabled if hasattr(hub_errors, "OfflineModeIsEnabled") else ConnectionError,
    )
    seen: BaseException | None = err
    while seen is not None:
        if isinstance(seen, kinds) or type(seen).__module__.split(".")[0] in ("requests", "httpx", "urllib3"):
            return True
        seen = seen.__cause__ or seen.__context__
    return False


def _strip_prefix(state: dict[str, Tensor], own_keys: set[str], path: Path, what: str) -> dict[str, Tensor]:
    if own_keys & state.keys():
        return state
    # Find the shortest prefix p such that p + <own key> is in the file, then keep only keys under p.
    prefixes = {k[: len(k) - len(own)] for own in own_keys for k in state if k.endswith(own) and k != own}
    prefixes = {p for p in prefixes if p.endswith(".")}
    if not prefixes:
        raise ValueError(f"{what} {str(path)!r} shares no parameter name with the model")
    prefix = min(prefixes, key=len)
    return {k[len(prefix) :]: v for k, v in state.items() if k.startswith(prefix)}
