"""``ValueRule``: what one config key accepts (type, range, choices, must-exist), and the one-line reason a value is
refused. The table of rules is :data:`airfisheye_bench.config_checks.RULES`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import DictConfig

from airfisheye_bench.errors import ConfigError, MissingFileError

_KINDS = ("int", "number", "bool", "choice", "file", "folder", "path", "custom")


@dataclass(frozen=True)
class ValueRule:
    """What one key accepts.

    Attributes:
        kind: ``int``, ``number`` (int or float), ``bool``, ``choice`` (one of ``choices``), ``file`` / ``folder``
            / ``path`` (an existing file, folder, or either) or ``custom`` (``check`` says).
        minimum: Smallest accepted number (``int`` / ``number``).
        maximum: Largest accepted number.
        choices: The accepted values of a ``choice``; a callable defers a costly import until the key is checked.
        nullable: Whether ``null`` is accepted.
        keywords: Values a ``file`` / ``folder`` / ``path`` also accepts as they are (``ckpt_path=last``).
        check: For ``custom``: the reason a value is refused, or ``None``; called with the value and the values of
            ``uses``.
        uses: Other keys whose values ``check`` needs (``data.occlusion_options`` is read with
            ``data.occlusion``); an absent key reads as ``None``.
        when: Checked only when this returns true for the whole config (e.g. not when resuming).
        hint: What the value means, appended to the message.

    Example:
        >>> ValueRule("int", minimum=1).problem(0)
        'expected an integer >= 1'
        >>> ValueRule("choice", choices=("png", "npy")).problem("tiff")
        'expected one of png, npy'
        >>> ValueRule("bool").problem("yes"), ValueRule("number", maximum=1).problem(0.5)
        ('expected true or false', None)
    """

    kind: str
    minimum: float | None = None
    maximum: float | None = None
    choices: Sequence[Any] | Callable[[], Sequence[Any]] = ()
    nullable: bool = False
    keywords: Sequence[str] = ()
    check: Callable[..., str | None] | None = None
    uses: Sequence[str] = ()
    when: Callable[[DictConfig], bool] | None = None
    hint: str = ""

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise ValueError(f"kind must be one of {_KINDS}, got {self.kind!r}")

    def enforce(self, key: str, value: Any, *used: Any) -> None:
        """Raise for a ``value`` of ``key`` that this rule refuses: ``<key>=<value>: <problem> (<hint>)``.

        Raises:
            ConfigError: the value is refused (a ``ValueError``).
            MissingFileError: the file or folder it names does not exist (a ``FileNotFoundError``).

        Example:
            >>> ValueRule("int", minimum=1, hint="per process").enforce("data.batch_size", 0)
            Traceback (most recent call last):
            ...
            airfisheye_bench.errors.ConfigError: data.batch_size=0: expected an integer >= 1 (per process)
        """
        problem = self.problem(value, *used)
        if problem is not None:
            hint = f" ({self.hint})" if self.hint else ""
            error = MissingFileError if problem.startswith("no such") else ConfigError
            raise error(f"{key}={value!r}: {problem}{hint}")

    def problem(self, value: Any, *used: Any) -> str | None:
        """Why ``value`` is refused, or ``None`` when it is accepted (``used``: the values of :attr:`uses`)."""
        if value is None:
            return None if self.nullable else "must be set"
        if self.kind == "choice":
            choices = self.choices() if callable(self.choices) else self.choices
            return None if value in choices else f"expected one of {', '.join(map(str, choices))}"
        if self.kind == "bool":
            return None if isinstance(value, bool) else "expected true or false"
        if self.kind in ("file", "folder", "path"):
            return self._path_problem(value)
        if self.kind == "custom":
            return self.check(value, *used) if self.check is not None else None
        return self._number_problem(value)

    def _number_problem(self, value: Any) -> str | None:
        numeric = (int,) if self.kind == "int" else (int, float)
        what = "an integer" if self.kind == "int" else "a number"
        if self.minimum is not None and self.maximum is not None:
            what += f" in [{self.minimum:g}, {self.maximum:g}]"
        elif self.minimum is not None:
            what += f" >= {self.minimum:g}"
        elif self.maximum is not None:
            what += f" <= {self.maximum:g}"
        if isinstance(value, bool) or not isinstance(value, numeric):
            return f"expected {what}"
        if (self.minimum is not None and value < self.minimum) or (
            self.maximum is not None and value > self.maximum
        ):
            return f"expected {what}"
        return None

    def _path_problem(self, value: Any) -> str | None:
        if value in self.keywords:
            return None
        path = Path(str(value)).expanduser()
        if self.kind == "file" and not path.is_file():
            return "is a folder, expected a file" if path.is_dir() else "no such file"
        if self.kind == "folder" and not path.is_dir():
            return "is a file, expected a folder" if path.exists() else "no such folder"
        if self.kind == "path" and not path.exists():
            return "no such file or folder"
        return None
