"""The metadata contract of a deployed ONNX model (``airfisheye-export`` writes it, evaluation reads it).

Every key lives in the model's ``metadata_props`` with an ``airfisheye.`` prefix; every value is a string,
JSON where the value is structured (lists, dicts, numbers). A consumer needs nothing else to feed the model and
to interpret its output.

Every task:

- ``airfisheye.format_version``: ``"1"`` (this contract; bumped on an incompatible change).
- ``airfisheye.task``: the task name (``seg`` | ``depth`` | ``completion``, or another registered task).
- ``airfisheye.model``: registry name of the zoo model (``deeplabv3plus``, ``adabins``, ``nlspn``, ...).
- ``airfisheye.model_config``: JSON of the checkpoint's ``hyper_parameters.model`` dict.
- ``airfisheye.inputs``: JSON list of graph input names, ``["image"]`` or ``["image", "sparse_depth"]`` (a
  camera-aware model whose ray map is not baked in: ``"rays"`` last).
- ``airfisheye.output``: graph output name, ``logits`` (seg) or ``depth``.
- ``airfisheye.normalization``: JSON ``{"mean": [r, g, b], "std": [r, g, b]}``, meaning
  ``image = (rgb / 255 - mean) / std``, RGB order, NCHW float32.
- ``airfisheye.camera``: JSON of the served camera's flat dict (``CameraModel.to_dict()``: ``model``, ``width``,
  ``height`` and that model's parameters, docs/design.md "Fisheye camera"); ``camera_from_dict`` rebuilds it.
  ``airfisheye-evaluate`` refuses to score the model on data served with another camera unless
  ``allow_camera_mismatch=true``.
- ``airfisheye.image_size``: JSON ``[H, W]`` the model was trained and verified at.
- ``airfisheye.data_config``: JSON of the run's resolved ``data`` config (with the export-time overrides), enough
  to rebuild the same datamodule (``hydra.utils.instantiate``); a ``camera.calibration`` file is replaced by the
  flat dict of the lens it holds, so no file of the training machine is needed.
- ``airfisheye.checkpoint_sha256``: SHA-256 of the source ``.ckpt`` file.
- ``airfisheye.source_checkpoint``: path of the source ``.ckpt`` file.

Optional, every task (read when present; models exported before it lack it):

- ``airfisheye.weights``: JSON of the weights the model started from before training
  (``models.weights.weights_identity``: ``encoder_weights`` such as ``imagenet`` with source, file and SHA-256).
- ``airfisheye.camera_input``: ``rays`` for a camera-aware model (``model.camera_input=rays``; absent: ``none``,
  the image alone), which takes the ray map of its camera (docs/design.md, "Ray map").
- ``airfisheye.rays_baked``: JSON bool, with ``camera_input``: the camera's ray map is a constant of the graph
  (``bake_camera=true``: the graph takes the image alone), else the graph's input ``rays`` ``[B, 4, H, W]``.

Segmentation (``seg``) only:

- ``airfisheye.class_names``: JSON list of training class names; logits channel ``c`` is class ``c``.
- ``airfisheye.palette``: JSON list of ``[r, g, b]`` per class.
- ``airfisheye.ignore_index``: JSON int, the label of unlabelled pixels (255, incl. outside the image circle).

Depth (``depth``) and completion (``completion``) only:

- ``airfisheye.min_depth``: JSON float, metres: lower bound of valid ground truth in evaluation (depth: the Eigen
  ``min_depth``, 1e-3 by default; completion: ``1e-4``).
- ``airfisheye.max_depth``: JSON float, metres: upper bound of valid depth (120 by default).

Completion only:

- ``airfisheye.occlusion``: occlusion correction of the sparse input (``ordering`` | ``zbuffer`` | ``hpr`` |
  ``none``); its options, if any were set, are ``occlusion_options`` in ``airfisheye.data_config``.
  ``sparse_depth`` is range in metres, float32 ``[B, 1, H, W]``, 0 = no LiDAR point.

Outputs: ``logits`` ``[B, C, H, W]`` (argmax over ``C`` gives the class id), ``depth`` ``[B, 1, H, W]`` range in
metres. The keys of one task are exactly the common keys plus that task's keys plus the optional keys given
(``OPTIONAL_KEYS``): :func:`deployment_metadata` writes them, :func:`parse_deployment_metadata` checks and decodes
them. Which keys a task has, and its input and output names, are facts of its spec (``TaskSpec.export.metadata``,
``inputs``, ``output``), looked up here by the task's name (:func:`airfisheye_bench.specs.get_task`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from typing import Any

from airfisheye_bench.errors import InputFileError, MissingFileError
from airfisheye_bench.specs import UnknownTaskError, get_task

__all__ = [
    "COMMON_KEYS",
    "FORMAT_VERSION",
    "KEY_CAMERA",
    "KEY_CAMERA_INPUT",
    "KEY_CHECKPOINT_SHA256",
    "KEY_CLASS_NAMES",
    "KEY_DATA_CONFIG",
    "KEY_FORMAT_VERSION",
    "KEY_IGNORE_INDEX",
    "KEY_IMAGE_SIZE",
    "KEY_INPUTS",
    "KEY_MAX_DEPTH",
    "KEY_MIN_DEPTH",
    "KEY_MODEL",
    "KEY_MODEL_CONFIG",
    "KEY_NORMALIZATION",
    "KEY_OCCLUSION",
    "KEY_OUTPUT",
    "KEY_PALETTE",
    "KEY_RAYS_BAKED",
    "KEY_SOURCE_CHECKPOINT",
    "KEY_TASK",
    "KEY_WEIGHTS",
    "OPTIONAL_KEYS",
    "PREFIX",
    "deployment_metadata",
    "graph_inputs",
    "parse_deployment_metadata",
    "read_deployment_metadata",
    "read_onnx_metadata",
]

PREFIX = "airfisheye."
FORMAT_VERSION = "1"

KEY_FORMAT_VERSION = "airfisheye.format_version"
KEY_TASK = "airfisheye.task"
KEY_MODEL = "airfisheye.model"
KEY_MODEL_CONFIG = "airfisheye.model_config"
KEY_INPUTS = "airfisheye.inputs"
KEY_OUTPUT = "airfisheye.output"
KEY_NORMALIZATION = "airfisheye.normalization"
KEY_CAMERA = "airfisheye.camera"
KEY_IMAGE_SIZE = "airfisheye.image_size"
KEY_DATA_CONFIG = "airfisheye.data_config"
KEY_CHECKPOINT_SHA256 = "airfisheye.checkpoint_sha256"
KEY_SOURCE_CHECKPOINT = "airfisheye.source_checkpoint"
KEY_CLASS_NAMES = "airfisheye.class_names"
KEY_PALETTE = "airfisheye.palette"
KEY_IGNORE_INDEX = "airfisheye.ignore_index"
KEY_MIN_DEPTH = "airfisheye.min_depth"
KEY_MAX_DEPTH = "airfisheye.max_depth"
KEY_OCCLUSION = "airfisheye.occlusion"
KEY_WEIGHTS = "airfisheye.weights"
KEY_CAMERA_INPUT = "airfisheye.camera_input"
KEY_RAYS_BAKED = "airfisheye.rays_baked"

COMMON_KEYS: tuple[str, ...] = (
    KEY_FORMAT_VERSION,
    KEY_TASK,
    KEY_MODEL,
    KEY_MODEL_CONFIG,
    KEY_INPUTS,
    KEY_OUTPUT,
    KEY_NORMALIZATION,
    KEY_CAMERA,
    KEY_IMAGE_SIZE,
    KEY_DATA_CONFIG,
    KEY_CHECKPOINT_SHA256,
    KEY_SOURCE_CHECKPOINT,
)
#: Keys written when their value is known, decoded when present.
OPTIONAL_KEYS: tuple[str, ...] = (KEY_WEIGHTS, KEY_CAMERA_INPUT, KEY_RAYS_BAKED)

# Values stored as plain strings; every other key holds JSON.
_STRING_KEYS = frozenset(
    {
        KEY_FORMAT_VERSION,
        KEY_TASK,
        KEY_MODEL,
        KEY_OUTPUT,
        KEY_CHECKPOINT_SHA256,
        KEY_SOURCE_CHECKPOINT,
        KEY_OCCLUSION,
        KEY_CAMERA_INPUT,
    }
)


def graph_inputs(
    task_inputs: Sequence[str], camera_input: str = "none", baked: bool = False
) -> tuple[str, ...]:
    """The graph input names of a model: its task's, then ``rays`` for a camera-aware one whose map is not baked.

    Example:
        >>> graph_inputs(("image",), "rays"), graph_inputs(("image",), "rays", baked=True)
        (('image', 'rays'), ('image',))
    """
    return (*task_inputs, "rays") if camera_input == "rays" and not baked else tuple(task_inputs)


def deployment_metadata(
    *,
    task: str,
    model: str,
    model_config: Mapping[str, Any],
    normalization: Mapping[str, Sequence[float]],
    camera: Mapping[str, Any],
    data_config: Mapping[str, Any],
    checkpoint_sha256: str,
    source_checkpoint: str | os.PathLike,
    weights: Mapping[str, Any] | None = None,
    camera_input: str = "none",
    rays_baked: bool = False,
    **task_values: Any,
) -> dict[str, str]:
    """Encode the deployment metadata of one model as ``metadata_props`` strings (see the module docstring).

    ``image_size`` follows from ``camera``; the graph's input and output names from the task's spec. The task's own
    values (``task_values``) must be exactly the keys of its spec (``TaskSpec.export.metadata``), so the key set is
    always the common keys plus the task's.

    Args:
        task: A registered task name.
        model: registry name of the zoo model.
        model_config: the checkpoint's model hyperparameters (``{"name": ..., **kwargs}``).
        normalization: ``{"mean": [3 floats], "std": [3 floats]}`` applied to ``rgb / 255``.
        camera: the served camera's ``to_dict()`` (needs ``width`` and ``height``).
        data_config: the run's resolved ``data`` config as plain containers.
        checkpoint_sha256: hex digest of the checkpoint file.
        source_checkpoint: path of the checkpoint file.
        weights: optional record of the weights the model started from (``airfisheye.weights``).
        camera_input: ``rays`` for a camera-aware model (``airfisheye.camera_input`` and ``airfisheye.rays_baked``
            are written for it only: the metadata of a model without a camera input is what it was before).
        rays_baked: its ray map is a constant of the graph, not the input ``rays``.
        **task_values: the task's own values by short name, e.g. seg: ``class_names`` (in logits channel
            order), ``palette`` (``[r, g, b]`` per class), ``ignore_index``; depth and completion: ``min_depth``,
            ``max_depth`` (metres); completion: ``occlusion`` (the sparse input's occlusion correction).

    Returns:
        ``{key: str}`` with exactly the common and the task's keys, plus ``airfisheye.weights`` when given and the
        camera input's keys for a camera-aware model.

    Raises:
        ValueError: an unknown task, a missing or superfluous task-specific value, or a malformed value.

    Example:
        >>> meta = deployment_metadata(
        ...     task="depth", model="adabins", model_config={"name": "adabins"},
        ...     normalization={"mean": [0.485, 0.456, 0.406], "std": [0.229, 0.224, 0.225]},
        ...     camera={"model": "equidistant", "width": 64, "height": 48, "fov_deg": 190.0},
        ...     data_config={"task": "depth"}, checkpoint_sha256="0" * 64, source_checkpoint="run/last.ckpt",
        ...     min_depth=1e-3, max_depth=120.0)
        >>> meta["airfisheye.image_size"], meta["airfisheye.inputs"], meta["airfisheye.output"]
        ('[48, 64]', '["image"]', 'depth')
        >>> parse_deployment_metadata(meta)["max_depth"]
        120.0
    """
    spec = get_task(task)
    specific = {PREFIX + k: v for k, v in task_values.items() if v is not None}
    wanted = [PREFIX + k for k in spec.export.metadata]
    missing = [k for k in wanted if k not in specific]
    extra = [k for k in specific if k not in wanted]
    if missing or extra:
        raise ValueError(
            f"task={task} needs {_short(missing) or 'no more'} and takes no {_short(extra) or 'other'} metadata"
        )
    if "width" not in camera or "height" not in camera:
        raise ValueError(
            f"camera must describe 'width' and 'height' (CameraModel.to_dict()), got {dict(camera)}"
        )
    values: dict[str, Any] = {
        KEY_FORMAT_VERSION: FORMAT_VERSION,
        KEY_TASK: task,
        KEY_MODEL: model,
        KEY_MODEL_CONFIG: dict(model_config),
        KEY_INPUTS: list(graph_inputs(spec.inputs, camera_input, rays_baked)),
        KEY_OUTPUT: spec.output,
        KEY_NORMALIZATION: {
            "mean": [float(v) for v in normalization["mean"]],
            "std": [float(v) for v in normalization["std"]],
        },
        KEY_CAMERA: dict(camera),
        KEY_IMAGE_SIZE: [int(camera["height"]), int(camera["width"])],
        KEY_DATA_CONFIG: dict(data_config),
        KEY_CHECKPOINT_SHA256: checkpoint_sha256,
        KEY_SOURCE_CHECKPOINT: str(source_checkpoint),
        **{key: _plain(key, value) for key, value in specific.items()},
    }
    out = {key: _encode(key, values[key]) for key in (*COMMON_KEYS, *wanted)}
    if weights is not None:
        out[KEY_WEIGHTS] = _encode(KEY_WEIGHTS, dict(weights))
    if camera_input != "none":
        out[KEY_CAMERA_INPUT] = _encode(KEY_CAMERA_INPUT, camera_input)
        out[KEY_RAYS_BAKED] = _encode(KEY_RAYS_BAKED, bool(rays_baked))
    # The writer never produces what the reader would reject.
    parse_deployment_metadata(out)
    return out


def parse_deployment_metadata(props: Mapping[str, str]) -> dict[str, Any]:
    """Check and decode deployment metadata (``metadata_props`` as a dict); other keys are ignored.

    Args:
        props: The model's ``metadata_props``; its task's own keys are those of the task's spec.

    Returns:
        The decoded values keyed by the name without the ``airfisheye.`` prefix, e.g. ``"task"`` (str),
        ``"inputs"`` (list), ``"image_size"`` (``[H, W]``), ``"class_names"`` (seg), ``"max_depth"`` (float).
        String-valued keys (``format_version``, ``task``, ``model``, ``output``, ``occlusion``,
        ``checkpoint_sha256``, ``source_checkpoint``) stay strings; the others are JSON-decoded.

    Raises:
        ValueError: no or an unsupported ``airfisheye.format_version``, an unknown task, missing keys for the
            task, or a value that is not valid JSON (the message names the key).

    Example:
        >>> parse_deployment_metadata({"airfisheye.format_version": "2"})
        Traceback (most recent call last):
        ...
        ValueError: airfisheye.format_version is '2'; this reader understands '1' (re-export the model ...)
    """
    version = props.get(KEY_FORMAT_VERSION)
    if version is None:
        raise ValueError(
            f"no {KEY_FORMAT_VERSION} in the ONNX metadata: not a model written by airfisheye-export"
        )
    if version != FORMAT_VERSION:
        raise ValueError(
            f"{KEY_FORMAT_VERSION} is {version!r}; this reader understands {FORMAT_VERSION!r} "
            "(re-export the model with this version of airfisheye-export)"
        )
    task = props.get(KEY_TASK)
    try:
        keys = (*COMMON_KEYS, *(PREFIX + k for k in get_task(str(task)).export.metadata))
    except UnknownTaskError as err:
        raise ValueError(f"{KEY_TASK}: {err}") from None
    missing = [k for k in keys if k not in props]
    if missing:
        raise ValueError(f"ONNX metadata of a task={task} model lacks {missing}")
    decoded: dict[str, Any] = {}
    for key in (*keys, *(k for k in OPTIONAL_KEYS if k in props)):
        value = props[key]
        if key not in _STRING_KEYS:
            try:
                value = json.loads(value)
            except json.JSONDecodeError as err:
                raise ValueError(f"ONNX metadata {key} is not valid JSON ({err}): {value[:80]!r}") from None
        decoded[key[len(PREFIX) :]] = value
    return decoded


def read_onnx_metadata(path: str | os.PathLike) -> dict[str, str]:
    """The ``metadata_props`` of an ONNX file as a dict (weights are not loaded).

    Example:
        >>> import onnx, tempfile
        >>> model = onnx.helper.make_model(onnx.helper.make_graph([], "empty", [], []))
        >>> onnx.helper.set_model_props(model, {"max_depth": "120"})
        >>> path = tempfile.mkdtemp() + "/empty.onnx"
        >>> onnx.save(model, path)
        >>> read_onnx_metadata(path)
        {'max_depth': '120'}
    """
    import onnx  # on use: reading metadata is rare, and onnx (protobuf) is slow to import

    model = onnx.load(str(path), load_external_data=False)
    return {prop.key: prop.value for prop in model.metadata_props}


def read_deployment_metadata(path: str | os.PathLike) -> dict[str, Any]:
    """:func:`parse_deployment_metadata` of an ``.onnx`` file (the weights are not loaded).

    Raises:
        FileNotFoundError: ``path`` does not exist.
        ValueError: see :func:`parse_deployment_metadata` (the message names the file).
    """
    if not os.path.isfile(path):
        raise MissingFileError(f"ONNX model {path} does not exist")
    try:
        props = read_onnx_metadata(path)
    except Exception as err:  # onnx raises protobuf's DecodeError (and others) on a file that is not a model
        raise InputFileError(
            f"{path}: not an ONNX model (it cannot be parsed: {type(err).__name__}); give a file written by "
            "scripts/export_onnx.py"
        ) from err
    try:
        return parse_deployment_metadata(props)
    except ValueError as err:
        raise InputFileError(f"{path}: {err}; give a file written by scripts/export_onnx.py") from None


def _encode(key: str, value: Any) -> str:
    if key in _STRING_KEYS:
        if not isinstance(value, str) or not value:
            raise ValueError(f"{key} must be a non-empty string, got {value!r}")
        return value
    try:
        return json.dumps(value, allow_nan=False)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{key} is not JSON-serialisable ({err}): {value!r}") from None


def _plain(key: str, value: Any) -> Any:
    """A task value as plain JSON-ready data (numpy numbers and tuples from configs become floats and lists)."""
    if key == KEY_CLASS_NAMES:
        return [str(n) for n in value]
    if key == KEY_PALETTE:
        return [[int(c) for c in rgb] for rgb in value]
    if key == KEY_IGNORE_INDEX:
        return int(value)
    if key in (KEY_MIN_DEPTH, KEY_MAX_DEPTH):
        return float(value)
    return value


def _short(keys: list[str]) -> str:
    return ", ".join(k[len(PREFIX) :] for k in keys)
