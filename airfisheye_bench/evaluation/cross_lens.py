"""One model scored on many lenses: the cross-lens matrix and the robustness row (docs/evaluation.md, "Across
lenses").

``airfisheye-evaluate ckpt_path=<run> lenses=[...]`` scores a model on each lens of a list, on the same test
frames: the scene, the ground truth and the LiDAR are rendered through each lens from the same cube faces or
panoramas, so a change of score is the lens's alone. A test lens is

- a mapping of ``data.camera``'s lens keys (``{model, fov_deg, k}``, or ``{calibration, camera}``: a file the
  project reads, or a camera's flat dict), with an optional ``name`` and an optional ``perturb`` (``{focal: 1.02,
  principal_point_px: [dx, dy], distortion: [1.05]}``: that lens with other intrinsics, as another unit of it);
- ``trained``: the lens (or lens list) the model was trained on, as its run served it;
- a string naming a calibration file.

``robustness=true`` adds the robustness row: the trained lens (a list's first) with its focal length ×0.98 and
×1.02, its principal point moved by 1 % of the width along x and along y (both signs) and its first distortion
term ×0.95 and ×1.05 (lenses that have one): the spread of one lens design across units. It is reported as the
largest change of each metric from the unperturbed lens.

Each lens is served at the run's ``data.camera.size`` and ``fit``; ``seen`` marks a test lens that is one of the
run's training lenses (unjittered). The cross-lens gap of a metric is ``1 - other / own`` for metrics where higher is
better (mIoU, δ1: :attr:`MetricColumn.higher_is_better`) and ``other / own - 1`` where lower is (RMSE, AbsRel): the
fraction lost off the training lens.

Example:
    >>> [lens.name for lens in parse_test_lenses(["trained", {"model": "equisolid", "fov_deg": 180}])]
    ['trained', 'equisolid 180°']
    >>> parse_test_lenses([{"model": "equidistant", "fov_deg": 190, "perturb": {"focal": 1.02}}])[0].name
    'equidistant 190° (focal ×1.02)'
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

from airfisheye_bench.geometry.cameras import CameraModel, Perturbation

__all__ = [
    "LENS_SPEC_KEYS",
    "PERTURB_KEYS",
    "ROBUSTNESS",
    "TestLens",
    "cross_lens_gap",
    "largest_changes",
    "lens_data_config",
    "parse_test_lenses",
    "robustness_lenses",
]

#: The keys of a test lens mapping: ``data.camera``'s lens keys, a label, and a fixed perturbation.
LENS_SPEC_KEYS = ("name", "model", "fov_deg", "k", "calibration", "camera", "perturb")
#: The keys of a lens's ``perturb``.
PERTURB_KEYS = ("focal", "principal_point_px", "distortion")
#: The robustness row: focal factor, principal-point shift as a fraction of the width, first distortion factor.
ROBUSTNESS = {"focal": 0.02, "principal_point": 0.01, "distortion": 0.05}
#: The served-lens keys of ``data.camera`` a test lens replaces (``size`` and ``fit`` stay the run's).
_CAMERA_KEYS = ("model", "fov_deg", "k", "calibration", "camera", "lenses", "jitter")


@dataclass(frozen=True)
class TestLens:
    """One column of the matrix: a lens (``camera``: ``data.camera`` keys; empty for the trained lens) and an
    optional fixed perturbation."""

    name: str
    camera: Mapping[str, Any] = field(default_factory=dict)
    perturb: Perturbation | None = None

    @property
    def trained(self) -> bool:
        """The run's own lens (or lens list), unchanged."""
        return not self.camera and self.perturb is None

    def spec(self) -> dict[str, Any]:
        """What ``results.json`` records of the lens."""
        out: dict[str, Any] = dict(self.camera) if self.camera else {"trained": True}
        if self.perturb is not None:
            out["perturb"] = {
                "focal": self.perturb.focal,
                "principal_point_px": list(self.perturb.shift),
                "distortion": list(self.perturb.distortion),
            }
        return out


def parse_test_lenses(value: Any, option: str = "lenses") -> list[TestLens]:
    """``lenses=`` as given -> one :class:`TestLens` per entry, named uniquely.

    Raises:
        ValueError: one line naming ``lenses[i]`` and what was expected.
    """
    if isinstance(value, (DictConfig, ListConfig)):
        value = OmegaConf.to_container(value, resolve=True)
    if value is None:
        return []
    if isinstance(value, (str, Mapping)) or not isinstance(value, Sequence) or not value:
        raise ValueError(
            f"{option}: expected a non-empty list of lenses ([trained, {{model: equisolid, fov_deg: 180}}, "
            f"{{calibration: cam.yaml}}, ...]), got {value!r}"
        )
    lenses = [_parse_one(entry, f"{option}[{i}]") for i, entry in enumerate(value)]
    names = [lens.name for lens in lenses]
    for i, name in enumerate(names):
        if names.index(name) != i:
            raise ValueError(
                f"{option}[{i}]: the name {name!r} is taken by {option}[{names.index(name)}]; give a name:"
            )
    return lenses


def _parse_one(entry: Any, where: str) -> TestLens:
    if entry == "trained":
        return TestLens("trained")
    if isinstance(entry, str):
        return TestLens(Path(entry).stem, {"calibration": entry})
    if not isinstance(entry, Mapping):
        raise ValueError(f"{where}: expected trained, a calibration file or a mapping, got {entry!r}")
    unknown = sorted(set(map(str, entry)) - set(LENS_SPEC_KEYS))
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r}; expected some of {', '.join(LENS_SPEC_KEYS)}")
    camera = {k: entry[k] for k in LENS_SPEC_KEYS[1:-1] if entry.get(k) is not None}
    if "calibration" in camera and set(camera) & {"model", "fov_deg", "k"}:
        raise ValueError(f"{where}: a calibration gives the lens; drop model / fov_deg / k")
    perturb = _parse_perturb(entry.get("perturb"), f"{where}.perturb")
    base = _name(camera) if camera else "trained"
    name = entry.get("name") or (f"{base} ({perturb.describe()})" if perturb else base)
    return TestLens(str(name), camera, perturb)


def _parse_perturb(value: Any, where: str) -> Perturbation | None:
    if value is None:
        return None
    if not isinstance(value, Mapping):
        raise ValueError(f"{where}: expected {{focal, principal_point_px, distortion}}, got {value!r}")
    unknown = sorted(set(map(str, value)) - set(PERTURB_KEYS))
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r}; expected some of {', '.join(PERTURB_KEYS)}")
    focal = value.get("focal", 1.0)
    if not _number(focal) or focal <= 0:
        raise ValueError(f"{where}.focal={focal!r}: expected a factor > 0")
    shift = value.get("principal_point_px", (0.0, 0.0))
    shift = (shift, shift) if _number(shift) else shift
    if not (isinstance(shift, Sequence) and len(shift) == 2 and all(_number(s) for s in shift)):
        raise ValueError(f"{where}.principal_point_px={shift!r}: expected pixels [dx, dy] (or one for both)")
    distortion = value.get("distortion", ())
    distortion = (distortion,) if _number(distortion) else distortion
    if not (isinstance(distortion, Sequence) and all(_number(d) for d in distortion)):
        raise ValueError(
            f"{where}.distortion={distortion!r}: expected factors of the distortion terms, in order"
        )
    return Perturbation(float(focal), (float(shift[0]), float(shift[1])), tuple(float(d) for d in distortion))


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _name(camera: Mapping[str, Any]) -> str:
    calibration = camera.get("calibration")
    if isinstance(calibration, str):
        which = camera.get("camera")
        return Path(calibration).stem + (f" ({which})" if which is not None else "")
    if isinstance(calibration, Mapping):
        return str(calibration.get("model", "calibrated"))
    fov = camera.get("fov_deg")
    return f"{camera.get('model', 'lens')}" + (f" {fov:g}°" if fov is not None else "")


def robustness_lenses(camera: CameraModel) -> list[TestLens]:
    """The robustness row of ``camera`` (a run's trained lens): :data:`ROBUSTNESS`'s changes, one at a time."""
    focal = ROBUSTNESS["focal"]
    px = round(ROBUSTNESS["principal_point"] * camera.width, 6)
    changes = [
        Perturbation(focal=1.0 - focal),
        Perturbation(focal=1.0 + focal),
        Perturbation(shift=(-px, 0.0)),
        Perturbation(shift=(px, 0.0)),
        Perturbation(shift=(0.0, -px)),
        Perturbation(shift=(0.0, px)),
    ]
    if camera.distortion_params:
        d = ROBUSTNESS["distortion"]
        changes += [Perturbation(distortion=(1.0 - d,)), Perturbation(distortion=(1.0 + d,))]
    return [TestLens(f"trained ({p.describe()})", {}, p) for p in changes]


def lens_data_config(data: DictConfig, camera: Mapping[str, Any] | CameraModel) -> DictConfig:
    """The run's data configuration serving another lens: ``camera`` (``data.camera`` lens keys, or a camera
    served as its flat dict) replaces the run's lens keys; size and fit stay."""
    data = OmegaConf.create(OmegaConf.to_container(data, resolve=False))
    keys = {"calibration": camera.to_dict()} if isinstance(camera, CameraModel) else dict(camera)
    served = dict(data.get("camera") or {})
    for key in _CAMERA_KEYS:
        served[key] = None
    served.update(keys)
    data.camera = served
    return data


def largest_changes(own: Mapping[str, float], rows: Sequence[Mapping[str, float]]) -> dict[str, float]:
    """The largest absolute change of each metric over ``rows`` from ``own`` (the robustness row's summary)."""
    return {
        key: max(abs(row[key] - value) for row in rows)
        for key, value in own.items()
        if rows and all(key in row and math.isfinite(row[key]) for row in rows) and math.isfinite(value)
    }


def cross_lens_gap(own: float, other: float, higher_is_better: bool) -> float:
    """The fraction of a metric lost off the training lens (module docstring): 0 when nothing is lost, negative
    when the other lens scores better."""
    if own == 0:
        return math.nan
    return 1.0 - other / own if higher_is_better else other / own - 1.0
