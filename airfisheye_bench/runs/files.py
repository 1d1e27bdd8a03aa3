"""The files a run keeps beside its checkpoints: the command's log file, written only once the run directory is
(:func:`run_log`); ``metrics.csv`` cut back to a checkpoint's rows on a resume (:func:`keep_metric_rows`); and the
numbered copy a replaced file is kept as (:func:`numbered_sibling`).
"""

from __future__ import annotations

import contextlib
import logging
import logging.handlers
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

from hydra.core.hydra_config import HydraConfig

from airfisheye_bench.atomic import atomic_write_text


def numbered_sibling(path: Path) -> Path:
    """The first free ``<stem>.<n><suffix>`` next to ``path`` (n = 1, 2, ...): where a replaced file is kept.

    Example:
        >>> import tempfile
        >>> folder = Path(tempfile.mkdtemp())
        >>> _ = (folder / "config.1.yaml").write_text("")
        >>> numbered_sibling(folder / "config.yaml").name
        'config.2.yaml'
    """
    n = 1
    while (candidate := path.with_name(f"{path.stem}.{n}{path.suffix}")).exists():
        n += 1
    return candidate


def keep_metric_rows(path: Path, rows: int) -> None:
    """Cut ``metrics.csv`` back to its header and first ``rows`` rows: the ones a checkpoint had logged.

    Rows written after that checkpoint, by the killed process, are logged again by the resumed one.

    Example:
        >>> import tempfile
        >>> p = Path(tempfile.mkdtemp()) / "metrics.csv"
        >>> _ = p.write_text("step,loss\\r\\n0,1.5\\r\\n1,1.2\\r\\n2,0.9\\r\\n")
        >>> keep_metric_rows(p, 2)
        >>> p.read_text().splitlines()
        ['step,loss', '0,1.5', '1,1.2']
    """
    if not path.is_file():
        return
    lines = path.read_text().splitlines(keepends=True)
    if len(lines) > rows + 1:
        atomic_write_text(path, "".join(lines[: rows + 1]))


#: The format of log lines when no handler gives one (Hydra's job logging: ``[time][logger][level] - message``).
LOG_FORMAT = "[%(asctime)s][%(name)s][%(levelname)s] - %(message)s"


@contextlib.contextmanager
def run_log(output_dir: Path) -> Iterator[Callable[[], None]]:
    """Write the command's log to ``<run>/<job name>.log`` (``train.log``, ``evaluate.log``) while active; yields
    ``open_log``.

    Until ``open_log()`` is called the records are held in memory: the checks and the building of the data and
    model log lines too, but a refused command writes nothing into the run directory. ``open_log()``, called once
    the command writes its run directory, writes the held records to the file, then every later one (Hydra's own
    file handler is switched off in ``configs/hydra/default.yaml`` and ``configs/evaluate.yaml``). Outside a Hydra
    application (a library caller) nothing is attached.
    """
    if not HydraConfig.initialized():
        yield lambda: None
        return
    root = logging.getLogger()
    console = next((h for h in root.handlers if h.formatter is not None), None)
    # Never flushed on its own (no capacity or level reached): open_log hands the records to the file.
    held = logging.handlers.MemoryHandler(sys.maxsize, logging.CRITICAL + 1, flushOnClose=False)
    root.addHandler(held)
    handlers: list[logging.Handler] = []

    def open_log() -> None:
        output_dir.mkdir(parents=True, exist_ok=True)
        handler = logging.FileHandler(output_dir / f"{HydraConfig.get().job.name}.log")
        handler.setFormatter(console.formatter if console else logging.Formatter(LOG_FORMAT))
        root.removeHandler(held)
        held.setTarget(handler)
        held.flush()
        root.addHandler(handler)
        handlers.append(handler)

    try:
        yield open_log
    finally:
        root.removeHandler(held)
        held.close()
        for handler in handlers:
            root.removeHandler(handler)
            handler.close()
