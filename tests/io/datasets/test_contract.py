"""The reader contract (``airfisheye_bench/io/datasets/base.py``, :class:`DatasetSource`): every registered format
implements it, and the dataset uses nothing of a reader that the contract does not declare, so a new reader cannot
miss a hook silently (``docs/design.md``, "Adding a dataset").

The dataset's uses are read from its source (``reader.<name>`` / ``self.reader.<name>`` in the dataset and the
oracle it hands its reader to, ``source.<name>`` in ``airfisheye-inspect``), nothing imported or run; a reader's
hooks are compared with the contract's by signature.
"""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

from airfisheye_bench.io.datasets import DATASET_FORMATS
from airfisheye_bench.io.datasets.base import DatasetSource

ROOT = Path(__file__).resolve().parents[3]
#: The modules that hold a reader and what they call it.
USERS = {
    "datamodules/dataset.py": "reader",
    "datamodules/serving_lidar.py": "reader",
    "datamodules/serving_remaps.py": "reader",
    "datamodules/oracle.py": "reader",
    "airfisheye_bench/dataset_tools/inspect_source.py": "source",
}
#: The members of the contract that have a default (the rest are abstract: every reader defines them).
HOOKS = (
    "modalities",
    "depth_from_points",
    "parallax_free",
    "pano_rotation",
    "fisheye",
    "cubemap",
    "equirect",
    "cast_scan",
    "deskew",
    "depth_points",
    "lidar_visible",
)
#: What every reader sets itself (annotated on the contract, no value there).
ATTRIBUTES = ("format", "OPTIONS", "root", "spec")
IMAGES = ("fisheye", "cubemap", "equirect")


def declared() -> set[str]:
    """The public members of the contract: its methods and properties, and its annotated attributes."""
    names = {n for n in vars(DatasetSource) if not n.startswith("_")}
    return names | set(DatasetSource.__annotations__)


def reader_uses(path: str, name: str) -> dict[str, int]:
    """``<name>.<member>`` and ``self.<name>.<member>`` in ``path``: member -> the first line it is used on."""
    tree = ast.parse((ROOT / path).read_text(encoding="utf-8"))
    uses: dict[str, int] = {}
    for node in ast.walk(tree):
        if not isinstance(node, ast.Attribute):
            continue
        owner = node.value
        plain = isinstance(owner, ast.Name) and owner.id == name
        on_self = (
            isinstance(owner, ast.Attribute)
            and owner.attr == name
            and isinstance(owner.value, ast.Name)
            and owner.value.id == "self"
        )
        if plain or on_self:
            uses.setdefault(node.attr, node.lineno)
    return uses


def probes(path: str, name: str) -> list[int]:
    """Lines of ``path`` where ``getattr`` / ``hasattr`` look a member up on the reader instead of using it."""
    tree = ast.parse((ROOT / path).read_text(encoding="utf-8"))
    calls = [
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id in ("getattr", "hasattr")
        and node.args
    ]
    return [call.lineno for call in calls if name in _names(call.args[0])]


def _names(node: ast.AST) -> set[str]:
    """The names and attribute names in an expression (``self.reader`` -> ``{"self", "reader"}``)."""
    return {n.id for n in ast.walk(node) if isinstance(n, ast.Name)} | {
        n.attr for n in ast.walk(node) if isinstance(n, ast.Attribute)
    }


@pytest.mark.parametrize("path", sorted(USERS))
def test_the_dataset_uses_only_what_the_contract_declares(path: str) -> None:
    uses = reader_uses(path, USERS[path])
    assert uses, f"{path} names its reader {USERS[path]!r} no more: update USERS"
    undeclared = {n: line for n, line in uses.items() if n not in declared()}
    assert not undeclared, (
        f"{path} uses reader members that airfisheye_bench/io/datasets/base.py (DatasetSource) does not declare: "
        + ", ".join(f"{n} (line {line})" for n, line in sorted(undeclared.items()))
    )
    lines = probes(path, USERS[path])
    assert not lines, (
        f"{path}: getattr/hasattr probes the reader on lines {lines}: declare the hook in base.py"
    )


def test_every_hook_is_declared_with_a_default_and_a_docstring() -> None:
    assert set(HOOKS) | set(ATTRIBUTES) <= declared()
    abstract = DatasetSource.__abstractmethods__
    assert not abstract & set(HOOKS), "a hook needs a default"
    for name in sorted(declared() - set(ATTRIBUTES)):
        member = inspect.getattr_static(DatasetSource, name)
        if callable(member) or isinstance(member, property):
            assert inspect.getdoc(getattr(DatasetSource, name)), f"DatasetSource.{name} has no docstring"
        else:  # an attribute with a default: documented in the class docstring
            assert f"{name}:" in (DatasetSource.__doc__ or ""), (
                f"DatasetSource's docstring does not say {name}"
            )
    # The dataset uses every hook: one it never calls would be a promise the contract does not keep.
    used = {n for path, name in USERS.items() for n in reader_uses(path, name)}
    assert set(HOOKS) - {"modalities"} <= used, set(HOOKS) - used  # modalities: through modalities_of


@pytest.mark.parametrize("format", sorted(DATASET_FORMATS))
def test_every_registered_reader_implements_the_contract(format: str) -> None:
    cls = DATASET_FORMATS[format]
    assert issubclass(cls, DatasetSource), f"{cls.__name__} does not subclass DatasetSource"
    assert not inspect.isabstract(cls), f"{cls.__name__} misses {sorted(cls.__abstractmethods__)}"
    assert cls.format == format and isinstance(cls.OPTIONS, dict)
    assert any(getattr(cls, k) is not getattr(DatasetSource, k) for k in IMAGES), (
        f"{cls.__name__} serves no image"
    )
    if cls.depth_from_points:
        assert cls.depth_points is not DatasetSource.depth_points, (
            f"{cls.__name__}: depth_from_points, no depth_points"
        )
    # Each method it overrides takes what the dataset passes (the contract's positional arguments).
    for name in sorted(declared() - set(ATTRIBUTES)):
        base, own = inspect.getattr_static(DatasetSource, name), inspect.getattr_static(cls, name)
        if own is base or not callable(getattr(DatasetSource, name, None)) or isinstance(base, property):
            continue
        arguments = len(inspect.signature(getattr(DatasetSource, name)).parameters) - 1  # without self
        bound = getattr(cls, name) if isinstance(own, (classmethod, staticmethod)) else own
        skip = 0 if isinstance(own, (classmethod, staticmethod)) else 1
        try:
            inspect.signature(bound).bind(*([None] * (arguments + skip)))
        except TypeError as err:
            pytest.fail(f"{cls.__name__}.{name} does not take the contract's arguments: {err}")


@pytest.mark.parametrize("format", sorted(DATASET_FORMATS))
def test_every_format_has_a_config_listing_its_options(format: str) -> None:
    """``configs/data/<format>.yaml`` selects the format and lists every option with its default."""
    from tests.helpers.configs import compose_train

    cfg = compose_train(["task=seg", f"data={format}"])
    assert cfg.data.format == format
    assert dict(cfg.data.format_options or {}) == DATASET_FORMATS[format].OPTIONS


def test_docs_list_every_hook_in_adding_a_dataset() -> None:
    text = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    section = text.split("### Adding a dataset", 1)[1].split("\n### ", 1)[0]
    for name in sorted(declared()):
        assert f"`{name}" in section, f'docs/design.md, "Adding a dataset", does not list {name}'
