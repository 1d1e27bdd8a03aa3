"""Light checks of the common config values, run before any long work (dataset generation, model building).

A wrong type or range in a Hydra override (``trainer.max_epochs=abc``, ``data.camera.size=abc``) would otherwise
surface minutes later, deep inside Lightning or the remap code, as a message that names neither the key nor the
fix. :func:`check_common_values` checks the keys a user sets most often and raises
:class:`~airfisheye_bench.errors.ConfigError` naming the key, the value given and what is expected. Keys absent
from the config are skipped, so the same table serves ``train.yaml``, ``evaluate.yaml`` and a run's ``data`` group.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.constants import LENS_MODELS
from airfisheye_bench.errors import ConfigError

_ABSENT = object()


@dataclass(frozen=True)
class ValueRule:
    """What one key accepts: an integer or number at least ``minimum``, or one of ``choices``; maybe null."""

    kind: str  # "int" | "number" | "choice"
    minimum: float | None = None
    choices: Sequence[str] = ()
    nullable: bool = False
    hint: str = ""

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is refused, or ``None`` when it is accepted."""
        if value is None:
            return None if self.nullable else "must be set"
        if self.kind == "choice":
            return None if value in self.choices else f"expected one of {', '.join(self.choices)}"
        numeric = (int,) if self.kind == "int" else (int, float)
        what = "an integer" if self.kind == "int" else "a number"
        if self.minimum is not None:
            what += f" >= {self.minimum:g}"
        if isinstance(value, bool) or not isinstance(value, numeric):
            return f"expected {what}"
        if self.minimum is not None and value < self.minimum:
            return f"expected {what}"
        return None


RULES: dict[str, ValueRule] = {
    "seed": ValueRule("int"),
    "trainer.max_epochs": ValueRule("int", minimum=-1, nullable=True, hint="-1: no limit"),
    "trainer.min_epochs": ValueRule("int", minimum=0, nullable=True),
    "trainer.max_steps": ValueRule("int", minimum=-1, nullable=True, hint="-1: no limit"),
    "trainer.accumulate_grad_batches": ValueRule("int", minimum=1),
    "trainer.check_val_every_n_epoch": ValueRule("int", minimum=1, nullable=True),
    "trainer.log_every_n_steps": ValueRule("int", minimum=1, nullable=True),
    "data.camera.size": ValueRule("int", minimum=8, nullable=True, hint="pixels, the served image side"),
    "data.camera.fov_deg": ValueRule("number", minimum=1, nullable=True, hint="degrees; null: the release's"),
    "data.camera.model": ValueRule(
        "choice", choices=LENS_MODELS, nullable=True, hint="null: the release's lens"
    ),
    "data.batch_size": ValueRule("int", minimum=1),
    "data.eval_batch_size": ValueRule("int", minimum=1, nullable=True),
    "data.num_workers": ValueRule("int", minimum=0),
    "data.max_depth": ValueRule("number", minimum=0, hint="metres"),
    "batch_size": ValueRule("int", minimum=1),  # evaluate.yaml's own loader
    "num_workers": ValueRule("int", minimum=0),
}
"""The checked keys (dotted, from the config root) and what each accepts."""


def check_common_values(cfg: DictConfig, rules: dict[str, ValueRule] | None = None) -> None:
    """Raise :class:`~airfisheye_bench.errors.ConfigError` for the first common key with a wrong type or range.

    Args:
        cfg: A composed config (``train.yaml``, ``evaluate.yaml``, or ``{"data": <a run's data group>}``).
        rules: The keys to check; :data:`RULES` by default.

    Example:
        >>> cfg = OmegaConf.create({"trainer": {"max_epochs": "abc"}, "data": {"camera": {"size": 64}}})
        >>> check_common_values(cfg)
        Traceback (most recent call last):
        ...
        airfisheye_bench.errors.ConfigError: trainer.max_epochs='abc': expected an integer >= -1 (-1: no limit)
        >>> check_common_values(OmegaConf.create({"data": {"camera": {"size": 64, "model": "equisolid"}}}))
    """
    for key, rule in (rules or RULES).items():
        value = OmegaConf.select(cfg, key, default=_ABSENT, throw_on_missing=False)
        if value is _ABSENT:
            continue
        problem = rule.problem(value)
        if problem is not None:
            hint = f" ({rule.hint})" if rule.hint else ""
            raise ConfigError(f"{key}={value!r}: {problem}{hint}")
