"""``CameraConfig``: the fisheye a dataset serves (``data.camera``), resolved against the dataset's calibrated camera
(docs/design.md, "Serving a sample" and "Calibration files")."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.cameras import CameraModel, Pinhole, camera_from_dict, ideal_camera
from airfisheye_bench.geometry.lens_draws import LENS_KEYS, LensJitter, parse_lenses
from airfisheye_bench.geometry.serving import ServedCamera, serve_camera
from airfisheye_bench.io.calibration_files import load_camera


@dataclass(frozen=True)
class CameraConfig:
    """The fisheye the models see. ``None`` fields take the release's calibrated camera.

    Args:
        size: Output width and height in pixels (the paper trains at 512); ``None``: the camera's own size.
        model: Lens model (``equidistant``, ``equisolid``, ``stereographic``, ``orthographic``, ``kannala_brandt``,
            or ``pinhole``: perspective views, as a model trained on ordinary images takes).
        fov_deg: Field of view in degrees (the image circle; ``pinhole``: across the width, 90 when unset).
        k: Kannala-Brandt coefficients.
        calibration: A calibration file (any format of :mod:`airfisheye_bench.io.calibration_files`) whose lens
            is served instead of the release's (``source=cubemap``), or that camera's flat dict (what an ONNX
            model's data config carries in its place).
        camera: Which camera of a calibration file with several (a name or a 0-based index).
        fit: ``pad`` or ``crop``: how a non-square camera becomes the ``size x size`` image
            (:mod:`airfisheye_bench.geometry.serving`).
        lenses: A list of lens specs (:func:`~airfisheye_bench.geometry.lens_draws.parse_lenses`), each served at
            ``size`` and ``fit`` instead of the lens of the keys above: a training sample draws one per epoch.
        jitter: ``{focal, principal_point_px, distortion}``: each training sample's lens perturbed
            (:class:`~airfisheye_bench.geometry.lens_draws.LensJitter`).
    """

    size: int | None = None
    model: str | None = None
    fov_deg: float | None = None
    k: tuple[float, float, float, float] | None = None
    calibration: str | dict | None = None
    camera: str | int | None = None
    fit: str = "pad"
    lenses: Sequence[Mapping[str, Any]] | None = None
    jitter: Mapping[str, float] | None = None

    @cached_property
    def lens_jitter(self) -> LensJitter | None:
        """The parsed ``jitter`` (``None`` without).

        Raises:
            ConfigError: naming ``data.camera.jitter`` and the key.
        """
        try:
            return LensJitter.parse(self.jitter)
        except ValueError as err:
            raise ConfigError(str(err)) from None

    @property
    def draws_lenses(self) -> bool:
        """Whether samples may be served through different lenses (a list, or jitter)."""
        return self.lenses is not None or self.jitter is not None

    @cached_property
    def served_lenses(self) -> tuple[tuple[CameraConfig, ...], tuple[float, ...]]:
        """``(one config per served lens, their sampling weights)``: the list's lenses at ``size`` and ``fit``, each
        calibration file read once, now; without a list, this config alone.

        Raises:
            ConfigError: a bad spec or file, naming ``data.camera.lenses[i]`` and its key; a list beside the keys of
                one lens.
        """
        try:
            parsed = parse_lenses(self.lenses)
        except ValueError as err:
            raise ConfigError(str(err)) from None
        if parsed is None:
            return (self,), (1.0,)
        given = [k for k in LENS_KEYS if k != "weight" and getattr(self, k) is not None]
        if given:
            raise ConfigError(
                f"data.camera.lenses gives the lenses: drop data.camera.{given[0]} (a lens's keys go in its spec)"
            )
        configs = []
        for i, spec in enumerate(parsed[0]):
            config = replace(self, lenses=None, jitter=None, **spec)
            try:
                _ = config.lens
            except ConfigError as err:
                raise ConfigError(str(err).replace("data.camera.", f"data.camera.lenses[{i}].")) from None
            configs.append(config)
        return tuple(configs), parsed[1]

    @cached_property
    def lens(self) -> CameraModel | None:
        """The camera of ``calibration`` at its own size (``None`` without one), read from the file once: the
        datamodule asks first (a bad file is refused before any data is generated), and every split and source
        it opens serves this same lens.

        Raises:
            ConfigError: naming ``data.camera.calibration``, the file, its key and what is supported.
        """
        if self.calibration is None:
            return None
        try:
            if isinstance(self.calibration, Mapping):
                return camera_from_dict(dict(self.calibration))
            return load_camera(self.calibration, self.camera, option="data.camera.camera")
        except (ValueError, OSError) as err:
            raise ConfigError(f"data.camera.calibration: {err}") from None

    def describe(self, served: ServedCamera) -> str | None:
        """The log line of a camera :meth:`resolve` served: a calibration file's lens, or a non-square camera
        padded or cropped; ``None`` for the release's lens at a size that keeps its aspect, or an ideal lens."""
        if self.calibration is not None:
            where = self.calibration if isinstance(self.calibration, str) else "the model's metadata"
            return f"camera from {where}: {served.describe()}"
        return f"camera: {served.describe()}" if served.fit is not None else None

    def resolve(self, calibrated: CameraModel, source: str) -> ServedCamera:
        """The camera to serve (and how it maps onto the calibrated sensor), given the release's calibrated
        fisheye (each split resolves it: the datamodule logs :meth:`describe` once)."""
        lens_changed = any(v is not None for v in (self.model, self.fov_deg, self.k))
        lens = self.lens
        if lens is not None:
            if lens_changed:
                raise ConfigError(
                    "data.camera.calibration gives the lens: drop data.camera.model / fov_deg / k (they describe "
                    "an ideal lens instead)"
                )
            if source == "fisheye":
                raise ConfigError(
                    "data.camera.calibration needs data.source=cubemap (the pre-rendered fisheye files have the "
                    "release's lens)"
                )
            return serve_camera(lens, self.size, self.fit)
        size = self.size or calibrated.width
        if not lens_changed:
            square = calibrated.width == calibrated.height
            exact = (size * calibrated.height) % calibrated.width == 0
            if source == "fisheye" and not exact:
                raise ConfigError(
                    f"data.camera.size={size}: the pre-rendered {calibrated.width}x{calibrated.height} fisheye files "
                    "keep their aspect ratio only at a width whose height is a whole number; pick such a size or "
                    "use data.source=cubemap (a square image, padded or cropped by data.camera.fit)"
                )
            if square or exact:
                # The aspect ratio is kept exactly (the pre-rendered files are resampled to it).
                resized = calibrated.resized(size, size * calibrated.height // calibrated.width)
                return ServedCamera(resized, calibrated, size / calibrated.width, (0.0, 0.0), None)
            return serve_camera(calibrated, size, self.fit)
        if source == "fisheye":
            raise ValueError(
                "camera.model/fov_deg/k can only change with source=cubemap (the pre-rendered fisheye files have a "
                "fixed lens); drop them or set data.source=cubemap"
            )
        model = self.model or calibrated.model
        fov_deg = self.fov_deg if self.fov_deg is not None else calibrated.fov_deg
        if fov_deg is None or (model == Pinhole.model and self.fov_deg is None):
            # The release's fisheye field of view is no pinhole's: a pinhole takes its own default (90 deg).
            fov_deg = Pinhole.defaults["fov_deg"] if model == Pinhole.model else 190.0
        k = (
            self.k
            if self.k is not None
            else (getattr(calibrated, "k", None) if model == "kannala_brandt" else None)
        )
        try:
            camera = ideal_camera(size, size, fov_deg=fov_deg, model=model, k=k)
        except ValueError as err:
            raise ConfigError(f"data.camera.model={model}, data.camera.fov_deg={fov_deg:g}: {err}") from None
        return ServedCamera(camera, camera, 1.0, (0.0, 0.0), None)


__all__ = ["CameraConfig"]
