"""OpenEXR float images read through the ``OpenEXR`` package (the Academy Software Foundation's bindings).

``OpenEXR`` is an optional dependency (``pip install -e ".[omni360]"``): only a dataset that stores EXR files needs
it, so it is imported when the first EXR is met, and its absence is one :class:`DatasetFormatError` line naming the
file and the extra to install.

Example:
    >>> depth = read_exr_channel("Depth_73.exr", ("R", "Y"))  # doctest: +SKIP
    >>> depth.dtype, depth.ndim                                # doctest: +SKIP
    (dtype('float32'), 2)
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from airfisheye_bench.io.errors import DatasetFormatError

__all__ = ["EXR_EXTRA", "read_exr_channel"]

#: The ``pyproject.toml`` extra that installs the EXR reader.
EXR_EXTRA = "omni360"


def read_exr_channel(path: str | Path, names: Sequence[str]) -> np.ndarray:
    """``float32 [H, W]``: the first channel of ``names`` that the EXR file at ``path`` has (half floats widened).

    Raises:
        DatasetFormatError: naming the file: ``OpenEXR`` not installed, the file missing or unreadable, or none of
            ``names`` among its channels.
    """
    path = Path(path)
    try:
        import OpenEXR  # optional (the omni360 extra): only EXR files need it
    except ImportError:
        raise DatasetFormatError(
            path,
            f'reading EXR needs the Python package OpenEXR, which is not installed: pip install -e ".[{EXR_EXTRA}]" '
            f'(or pip install "airfisheye-bench[{EXR_EXTRA}]")',
        ) from None
    if not path.is_file():
        raise DatasetFormatError(path, "missing")
    try:
        # separate_channels: R, G, B as their own planes (by default they come as one interleaved "RGB").
        with OpenEXR.File(str(path), separate_channels=True) as exr:
            channels = exr.channels()
            name = next((n for n in names if n in channels), None)
            if name is None:
                raise DatasetFormatError(
                    path, f"no channel {' or '.join(names)} (it has {', '.join(sorted(channels))})"
                )
            pixels = np.asarray(channels[name].pixels)
    except RuntimeError as err:  # the bindings raise RuntimeError for a file they cannot parse
        raise DatasetFormatError(path, f"unreadable EXR ({str(err).splitlines()[0]})") from None
    if pixels.ndim != 2:
        raise DatasetFormatError(path, f"channel {name} is not one plane (shape {pixels.shape})")
    return pixels.astype(np.float32, copy=False)
