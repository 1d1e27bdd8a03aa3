"""OCamCalib ``calib_results.txt`` (Scaramuzza's toolbox, ``export_data.m``): five ``#`` comment headers, each
followed by its values.

Layout (the toolbox's ``export_data.m`` and the C reader ``get_ocam_model`` of ``ocam_functions.cpp``, which
reads it line by line):

1. ``#polynomial coefficients for the DIRECT mapping function (ocam_model.ss ...)``: ``N a0 a1 ... a(N-1)``
   (``cam2world``, constant term first).
2. ``#polynomial coefficients for the inverse mapping function (ocam_model.invpol ...)``: ``M p0 ... p(M-1)``
   (``world2cam``, constant term first: ``rho = sum p_i theta^i``).
3. ``#center: "row" and "column", starting from 0 (C convention)``: ``xc yc`` (row, column).
4. ``#affine parameters "c", "d", "e"``: ``c d e``.
5. ``#image size: "height" and "width"``: ``height width``.

OCamCalib's image frame is (row, column): ``world2cam`` returns ``row = c x + d y + xc``, ``col = e x + y + yc``.
Here ``cx`` is the column (``yc``) and ``cy`` the row (``xc``); ``c, d, e`` and the polynomials keep OCamCalib's
meaning. OCamCalib v3.0's ``export_data.m`` writes the centre minus one (MATLAB's 1-based pixels to C's 0-based)
under a header that says "starting from 0 (C convention)": such a centre is used as it is. A header that names
MATLAB's ``ocam_model.xc`` without saying "starting from 0" is read as MATLAB's 1-based centre and moved by -1.

Example:
    >>> text = '''#polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). These are used by cam2world
    ...
    ... 3 -2.7e+02 0.0 1.0e-03
    ...
    ... #polynomial coefficients for the inverse mapping function (ocam_model.invpol in MATLAB). These are used by world2cam
    ...
    ... 2 400.0 250.0
    ...
    ... #center: "row" and "column", starting from 0 (C convention)
    ...
    ... 479.5 639.0
    ...
    ... #affine parameters "c", "d", "e"
    ...
    ... 1.0 0.0 0.0
    ...
    ... #image size: "height" and "width"
    ...
    ... 960 1280
    ... '''
    >>> camera, _ = _read(Fields("calib_results.txt", _document(text, None)))
    >>> camera["cx"], camera["cy"], camera["world2cam"]
    (639.0, 479.5, [400.0, 250.0])
"""

from __future__ import annotations

from typing import Any

from airfisheye_bench.geometry.cameras import Ocam
from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CameraEntry, Fields

__all__ = ["FORMAT"]

_SECTIONS = ("ss", "invpol", "center", "affine", "image_size")
_SIGNATURE = "polynomial coefficients for the direct mapping function"


def _detect(text: str, doc: Any) -> bool:
    return _SIGNATURE in text.lower()


def _document(text: str, doc: Any) -> dict[str, Any]:
    """``{ss, invpol, center, affine, image_size: [numbers]}`` and ``center_header``, in the file's order."""
    headers: list[str] = []
    values: list[list[Any]] = []
    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith("#"):
            headers.append(stripped)
            values.append([])
        elif stripped and values:
            for token in stripped.split():
                try:
                    values[-1].append(float(token))
                except ValueError:
                    values[-1].append(token)
    out: dict[str, Any] = dict(zip(_SECTIONS, values, strict=False))
    if len(headers) >= 3:
        out["center_header"] = headers[2]
    return out


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    return {"0": _read}


def _polynomial(f: Fields, key: str) -> list[float]:
    values = f.numbers(key)
    if (
        not values
        or not float(values[0]).is_integer()
        or int(values[0]) != len(values) - 1
        or len(values) < 2
    ):
        raise f.error(key, "expected the coefficient count N followed by N coefficients")
    return values[1:]


def _read(f: Fields) -> tuple[dict[str, Any], dict]:
    cam2world = _polynomial(f, "ss")
    world2cam = _polynomial(f, "invpol")
    row, col = f.numbers("center", 2)
    header = str(f.data.get("center_header", "")).lower()
    if "starting from 0" not in header and "matlab" in header:
        row, col = row - 1.0, col - 1.0  # MATLAB's 1-based pixel indices
    c, d, e = f.numbers("affine", 3)
    height, width = f.numbers("image_size", 2)
    return (
        Ocam.flat_dict(
            f.whole("image_size", width),
            f.whole("image_size", height),
            cx=col,
            cy=row,
            c=c,
            d=d,
            e=e,
            cam2world=cam2world,
            world2cam=world2cam,
        ),
        {},
    )


FORMAT = CalibrationFormat(
    name="ocamcalib",
    summary="OCamCalib calib_results.txt (ss and invpol polynomials, centre (row, col), affine c d e, image size)",
    source="OCamCalib toolbox export_data.m (v3.0: centre written 0-based) and ocam_functions.cpp "
    "(get_ocam_model, world2cam, cam2world)",
    detect=_detect,
    cameras=_cameras,
    document=_document,
)
