"""A perspective model on fisheye images (``views=``; docs/evaluation.md, "Perspective models on fisheye").

:class:`PerspectivePredictor` wraps a checkpoint's or an ONNX model's predictor whose camera is perspective (an
ideal ``pinhole`` or a calibrated ``pinhole_radtan``: a model trained with ``data.camera.model=pinhole``): each
fisheye image of a batch is rendered into the views (:class:`~airfisheye_bench.geometry.perspective_views.
PerspectiveViews`; sparse LiDAR maps moved point by point), the model runs on every view at the size it was trained
for, and its outputs are resampled back into the fisheye: depth blended and made range (``view_depth``: what the
model's depth measures, ``range`` for this project's models, ``z`` along the view's axis for most others), logits made
probabilities, blended, and their argmax taken. The result is what the wrapped predictor would give for the fisheye,
so the evaluation loop, its metrics and the prediction files are unchanged.
"""

from __future__ import annotations

from typing import Any

from torch import Tensor

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation.predictors import CheckpointPredictor, OnnxPredictor, to_prediction
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.perspective_views import (
    DEPTH_CONVENTIONS,
    PerspectiveViews,
    parse_views,
)
from airfisheye_bench.specs import get_task

__all__ = ["PERSPECTIVE_MODELS", "PerspectivePredictor", "perspective_predictor"]

#: The camera models a perspective model's views can have.
PERSPECTIVE_MODELS = ("pinhole", "pinhole_radtan")


class PerspectivePredictor:
    """A perspective model's predictions on fisheye batches (the module docstring says how).

    Args:
        inner: The model's predictor (:class:`CheckpointPredictor` or :class:`OnnxPredictor`), fed view batches.
        views: The fisheye seen through the model's camera.
        view_depth: ``range`` or ``z``: what the model's depth output measures in its views.
        spec: ``views=`` as given (recorded).
    """

    def __init__(
        self,
        inner: CheckpointPredictor | OnnxPredictor,
        views: PerspectiveViews,
        view_depth: str = "range",
        spec: Any = "cube",
    ) -> None:
        if view_depth not in DEPTH_CONVENTIONS:
            raise ValueError(f"view_depth must be one of {DEPTH_CONVENTIONS}, got {view_depth!r}")
        self.inner = inner
        self.views = views
        self.view_depth = view_depth
        self.spec = spec
        self.task = inner.task
        self._task = get_task(inner.task)

    def __call__(self, batch: dict) -> Tensor:
        n, h, w = len(self.views.views), self.views.camera.height, self.views.camera.width
        image = self.views.to_views(batch["image"].detach().cpu().float())  # fill 0: the mean colour
        count = image.shape[0]
        view_batch = {"image": image.reshape(count * n, -1, h, w)}
        if "sparse_depth" in self._task.inputs:
            sparse = self.views.splat_to_views(batch["sparse_depth"].detach().cpu().float(), self.view_depth)
            view_batch["sparse_depth"] = sparse.reshape(count * n, -1, h, w)
        output = self.inner.output(view_batch).float()
        output = output.reshape(count, n, -1, h, w)
        if self._task.uses_classes:  # probabilities blended, then the argmax
            blended = self.views.from_views(output.softmax(2))
        else:
            blended = self.views.from_views(output, depth=self.view_depth)
        return to_prediction(self.task, blended)

    def identity(self) -> dict[str, Any]:
        """The wrapped model's identity, with the views it was run through."""
        return {
            **self.inner.identity(),
            "views": {"spec": self.spec, "view_depth": self.view_depth, **self.views.describe()},
        }


def perspective_predictor(
    inner: CheckpointPredictor | OnnxPredictor,
    fisheye: CameraModel,
    model_camera: CameraModel,
    spec: Any,
    view_depth: str = "range",
    what: str = "the model",
    require_coverage: bool = True,
) -> PerspectivePredictor:
    """``inner`` run through the views ``spec`` (``views=``) of ``fisheye``, at ``model_camera``.

    Raises:
        ConfigError: one line: the model's camera is not perspective, ``spec`` or ``view_depth`` is not one this
            knows, or (``require_coverage``) the views leave valid fisheye pixels unseen.
    """
    if model_camera.model not in PERSPECTIVE_MODELS:
        raise ConfigError(
            f"views= renders perspective views for a model trained on them, but {what} was trained for a "
            f"{model_camera.model} camera ({model_camera.width}x{model_camera.height}); evaluate it without views= "
            f"(the models of views= have a {' or '.join(PERSPECTIVE_MODELS)} camera)"
        )
    if view_depth not in DEPTH_CONVENTIONS:
        raise ConfigError(f"view_depth={view_depth!r}: expected one of {', '.join(DEPTH_CONVENTIONS)}")
    try:
        views = PerspectiveViews(fisheye, model_camera, parse_views(spec))
    except ValueError as err:
        raise ConfigError(str(err)) from None
    coverage = views.coverage_fraction
    if require_coverage and coverage < 1.0:
        raise ConfigError(
            f"views={spec!r} through {what}'s {model_camera.model} camera leave {100 * (1 - coverage):.2f} % of the "
            "fisheye's valid pixels unseen, which would be scored without a prediction; add views (or use "
            "views=cube with a field of view of 90 deg or more)"
        )
    return PerspectivePredictor(inner, views, view_depth, spec)
