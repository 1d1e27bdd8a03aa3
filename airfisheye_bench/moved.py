"""Import paths of modules that moved in 0.2, kept working for one release with a ``DeprecationWarning``.

:data:`MOVED` maps each old dotted path to its new one (a package maps its submodules too:
``airfisheye_bench.benchmarks.paired`` is ``airfisheye_bench.studies.paired``). Importing an old path returns the
module at the new one, the same object, so that ``isinstance`` checks, patches and pickles by name keep working;
``CHANGELOG.md`` lists the moves. The table and its finder go in the next release.

>>> import warnings
>>> with warnings.catch_warnings(record=True) as caught:
...     warnings.simplefilter("always")
...     from airfisheye_bench.benchmarks import paired
>>> paired.__name__, caught[0].category.__name__
('airfisheye_bench.studies.paired', 'DeprecationWarning')
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings
from importlib.machinery import ModuleSpec
from types import ModuleType

#: Old dotted path -> new dotted path (0.2: each room named for what it holds; docs/design.md, "Layers").
MOVED: dict[str, str] = {
    "airfisheye_bench.benchmarks": "airfisheye_bench.studies",
    "airfisheye_bench.evaluation.predict": "airfisheye_bench.prediction.predict",
    "airfisheye_bench.evaluation.footage": "airfisheye_bench.prediction.footage",
    "airfisheye_bench.evaluation.footage_inputs": "airfisheye_bench.prediction.footage_inputs",
    "airfisheye_bench.io.reader": "airfisheye_bench.io.datasets.airfisheye",
    "airfisheye_bench.io.inspect": "airfisheye_bench.dataset_tools.inspect",
    "airfisheye_bench.io.inspect_scans": "airfisheye_bench.dataset_tools.inspect_scans",
    "airfisheye_bench.io.inspect_source": "airfisheye_bench.dataset_tools.inspect_source",
    "airfisheye_bench.io.transcode": "airfisheye_bench.dataset_tools.transcode",
    "datamodules.airfisheye": "datamodules.datamodule",
}


def new_path(old: str) -> str | None:
    """Where module ``old`` lives now (``None``: it did not move)."""
    for prefix, target in MOVED.items():
        if old == prefix or old.startswith(prefix + "."):
            return target + old[len(prefix) :]
    return None


class _Alias(importlib.abc.Loader):
    """Loads an old path as the module at its new path."""

    def __init__(self, target: str) -> None:
        self.target = target

    def create_module(self, spec: ModuleSpec) -> None:
        return None  # a throwaway module: exec_module puts the real one in its place

    def exec_module(self, module: ModuleType) -> None:
        # The import system returns what sys.modules holds under the name once this returns.
        sys.modules[module.__name__] = importlib.import_module(self.target)


class MovedModuleFinder(importlib.abc.MetaPathFinder):
    """Finds the old paths of :data:`MOVED` (first on ``sys.meta_path``, so an old path never finds a stale
    file)."""

    def find_spec(self, fullname: str, path: object = None, target: object = None) -> ModuleSpec | None:
        new = new_path(fullname)
        if new is None:
            return None
        warnings.warn(
            f"{fullname} moved to {new}; the old import path goes in the next release (CHANGELOG.md)",
            DeprecationWarning,
            stacklevel=2,
        )
        return importlib.util.spec_from_loader(fullname, _Alias(new))


def install() -> None:
    """Put the finder first on ``sys.meta_path`` (once; the package's ``__init__`` calls it)."""
    if not any(isinstance(finder, MovedModuleFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, MovedModuleFinder())
