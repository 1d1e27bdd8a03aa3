"""The options of the small commands: a Hydra config per command, typed by a dataclass, and one ``--help``.

``airfisheye-inspect``, ``-transcode``, ``-leaderboard``, ``-export`` and ``-generate`` read ``key=value``
arguments in Hydra's override grammar, as ``airfisheye-train`` does: each command composes its file
``configs/<command>.yaml`` with Hydra's compose API, on top of a dataclass schema (:class:`Command`'s
``schema``) that gives every key its type and one-line description. The config is in struct mode, so an unknown
key is an error naming it; values convert by OmegaConf's rules (a boolean is ``true/false``, ``yes/no``,
``on/off`` or ``1/0``, the same everywhere), and a value of the wrong type is one line naming the key. No output
folder and no logging set-up: these commands only read their options.

See :mod:`airfisheye_bench.cli.commands` for the commands and an example.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.global_hydra import GlobalHydra
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException
from omegaconf import MISSING, DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from airfisheye_bench.constants import config_dir
from airfisheye_bench.errors import ConfigError

HELP_FLAGS = ("-h", "--help")


def option(help: str, type_name: str | None = None) -> Any:
    """A field of a command's schema: its one-line description; the default is in ``configs/<command>.yaml``.

    Args:
        help: The description ``--help`` prints.
        type_name: The type ``--help`` prints, where the annotation says less (``Any`` for "a path or a list").
    """
    return dataclasses.field(default=MISSING, metadata={"help": help, "type": type_name})


@dataclass(frozen=True)
class Command:
    """A small command: its config name, its typed options and the lines of its ``--help``.

    Attributes:
        name: The config ``configs/<name>.yaml`` (and the console script ``airfisheye-<name>``, unless ``usage``
            says otherwise).
        schema: A dataclass with one :func:`option` per key (its type and description).
        summary: What the command does, one line.
        usage: The command line with its required keys.
        extra: Keys the command takes besides its options (e.g. ``data.*``), as a predicate on the key.
        extra_help: A line of ``--help`` about those keys.
    """

    name: str
    schema: type
    summary: str
    usage: str
    extra: Callable[[str], bool] | None = None
    extra_help: str = ""


@dataclass(frozen=True)
class Parsed:
    """A command's composed options and its extra ``key -> value`` overrides (typed by Hydra's grammar)."""

    options: DictConfig
    extra: dict[str, Any]


def wants_help(argv: Sequence[str]) -> bool:
    """Whether the arguments ask for ``--help`` (or ``-h``)."""
    return any(arg in HELP_FLAGS for arg in argv)


def parse(command: Command, argv: Sequence[str]) -> Parsed:
    """Compose ``configs/<command>.yaml`` with the ``key=value`` arguments ``argv``.

    Raises:
        ConfigError: A malformed argument, an unknown key, a value of the wrong type or a required key left unset;
            the message names the key.
    """
    overrides, extra = [], {}
    for override in _parse_overrides(argv):
        key = override.key_or_group
        if override.is_delete():
            raise ConfigError(
                f"{override.input_line}: an option cannot be deleted; give {key}=<value> or leave it out"
            )
        if override.is_sweep_override():
            items = ",".join(map(str, getattr(override.value(), "list", ["a", "b"])))
            raise ConfigError(
                f"{override.input_line}: a comma list is a sweep in Hydra's grammar; write a list, {key}=[{items}]"
            )
        if command.extra is not None and command.extra(key):
            extra[key] = override.value()
        elif key.split(".")[0] in _fields(command.schema):
            overrides.append(override.input_line.lstrip("+"))
        else:
            raise ConfigError(
                f"unknown option {key!r} of {_program(command)}; its options: "
                f"{', '.join(_fields(command.schema))}{' (and ' + command.extra_help + ')' if command.extra_help else ''}"
                " (see --help)"
            )
    cfg = _compose(command, overrides)
    for name in _fields(command.schema):
        if OmegaConf.is_missing(cfg, name):
            raise ConfigError(f"{name}= is required: {_fields(command.schema)[name].metadata['help']}")
    return Parsed(cfg, extra)


def render_help(command: Command) -> str:
    """The ``--help`` text: usage, then every key with its type, default and description."""
    defaults = _compose(command, [])
    rows = []
    hints = typing.get_type_hints(command.schema)
    for name, f in _fields(command.schema).items():
        default = "(required)" if OmegaConf.is_missing(defaults, name) else _show(defaults[name])
        rows.append((name, f.metadata["type"] or _type_name(hints[name]), default, f.metadata["help"]))
    widths = [max(len(row[i]) for row in rows) for i in range(3)]
    lines = [command.summary, "", f"usage: {command.usage} [key=value ...]", ""]
    lines.append(f"options (key=value; defaults from configs/{command.name}.yaml):")
    lines += [f"  {n:{widths[0]}}  {t:{widths[1]}}  {d:{widths[2]}}  {h}".rstrip() for n, t, d, h in rows]
    if command.extra_help:
        lines.append(f"  {command.extra_help}")
    lines += ["", "Booleans: true/false, yes/no, on/off, 1/0. Lists: key=[a,b]."]
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------ helpers
def _program(command: Command) -> str:
    return command.usage.split(" ")[0]


def _fields(schema: type) -> dict[str, dataclasses.Field]:
    return {f.name: f for f in dataclasses.fields(schema)}


def _parse_overrides(argv: Sequence[str]) -> list:
    parser = OverridesParser.create()
    parsed = []
    for arg in argv:
        if "=" not in arg:
            raise ConfigError(f"arguments look like key=value, got {arg!r} (see --help)")
        try:
            parsed += parser.parse_overrides([arg])
        except HydraException as err:
            raise ConfigError(f"{arg}: not a key=value override ({str(err).splitlines()[0]})") from None
    return parsed


def _compose(command: Command, overrides: list[str]) -> DictConfig:
    """``configs/<command>.yaml`` over its schema, with ``overrides``; a failure names the key."""
    ConfigStore.instance().store(name=f"{command.name}_schema", node=command.schema)
    if GlobalHydra.instance().is_initialized():  # a command is a process of its own; tests call several
        GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3", job_name=command.name):
            return compose(config_name=command.name, overrides=overrides)
    except HydraException as err:
        cause = err.__cause__
        if not isinstance(cause, OmegaConfBaseException) or not getattr(cause, "full_key", None):
            raise
        key = str(cause.full_key)
        value = next((o.partition("=")[2] for o in reversed(overrides) if o.partition("=")[0] == key), "?")
        annotation = typing.get_type_hints(command.schema).get(key.split(".")[0])
        expected = _type_phrase(annotation) if annotation is not None else "a valid value"
        raise ConfigError(f"{key}={value}: expected {expected}") from None


def _optional(annotation: Any) -> tuple[Any, bool]:
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) in (typing.Union, types.UnionType) and type(None) in args:
        return next(a for a in args if a is not type(None)), True
    return annotation, False


def _type_name(annotation: Any) -> str:
    inner, optional = _optional(annotation)
    if typing.get_origin(inner) is list:
        name = f"list[{typing.get_args(inner)[0].__name__}]"
    else:
        name = inner.__name__
    return f"{name}|null" if optional else name


def _type_phrase(annotation: Any) -> str:
    inner, optional = _optional(annotation)
    phrases = {
        bool: "a boolean (true/false, yes/no, on/off, 1/0)",
        int: "an integer",
        float: "a number",
        str: "a string",
    }
    phrase = phrases.get(inner, "a list, e.g. [a,b]" if typing.get_origin(inner) is list else str(inner))
    return f"{phrase} or null" if optional else phrase


def _show(value: Any) -> str:
    if isinstance(value, DictConfig) or OmegaConf.is_list(value):
        value = OmegaConf.to_container(value)
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, list):
        return "[" + ",".join(map(str, value)) + "]"
    return str(value)
