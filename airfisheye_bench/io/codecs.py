"""Encoders and decoders for the per-frame files: RGB, labels, depth, LiDAR points and visibility.

Every writer is atomic (temporary name + rename) and deterministic (the same array gives the same bytes), which the
resumable generator relies on. Every reader returns plain numpy arrays and raises
:class:`~airfisheye_bench.io.errors.DatasetFormatError` naming the file when the contents do not match.

Encodings (chosen by the file suffix):

============  =====================================================================================
RGB           ``.png`` (lossless) or ``.jpg`` / ``.jpeg``; ``uint8 [H, W, 3]``
labels        ``.png``, single-channel 8-bit; ``uint8 [H, W]`` raw ids, 255 = ignore
depth         ``.png``: 16-bit, ``round(range * scale)`` (``scale`` = 256 by default), 0 = invalid, ranges
              beyond ``65535 / scale`` saturate at 65535; ``.npy``: float32 range; ``.pfm``: float32 range.
              Decoded depth is float32 metres with 0 = invalid/sky.
LiDAR         ``.npy`` float32 ``[N, 4]``: x, y, z in the LiDAR frame (metres), raw semantic id
visibility    ``.npy`` bool ``[N]``
============  =====================================================================================

Decoding: the layouts the writers produce (8-bit RGB and grey PNG, 16-bit grey PNG, three-channel JPEG) are
decoded by ``torchvision.io`` (libpng / libjpeg-turbo): on one thread ~10% (PNG) to ~20% (JPEG) faster than PIL
(16-bit PNG: the same, zlib dominates), with the same pixels (PNG is lossless; for JPEG both run libjpeg-turbo
with its defaults: accurate integer IDCT, fancy upsampling). Every other layout (palette, grey-as-RGB, RGBA,
16-bit RGB, CMYK ...) and any file torchvision cannot decode goes through PIL, which converts it or rejects it
with the message it always gave. ``scripts/bench_decode.py`` measures both.
"""

from __future__ import annotations

import functools
import io
import re
import warnings
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import torch
from PIL import Image

from airfisheye_bench.atomic import atomic_write_bytes
from airfisheye_bench.io.errors import DatasetFormatError

#: Default depth PNG scale: ``value = round(range * 256)`` (KITTI convention).
DEPTH_PNG_SCALE = 256.0
#: PNG zlib level: fixed, so encodings are byte-identical between runs (3: as small as 6 on rendered images, 2x faster).
PNG_COMPRESS_LEVEL = 3
JPEG_QUALITY = 95

_RGB_SUFFIXES = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}
_DEPTH_SUFFIXES = (".png", ".npy", ".pfm")

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_JPEG_SOI = b"\xff\xd8\xff"
# PNG IHDR (bit depth, colour type) of the layouts the fast decoder handles: 8-bit RGB, 8-bit and 16-bit grey.
_PNG_RGB8, _PNG_GREY8, _PNG_GREY16 = (8, 2), (8, 0), (16, 0)
_TV_DEPRECATION = "The image decoding and encoding capabilities of TorchVision"


# ----------------------------------------------------------------------------------------------- helpers
def _check_array(
    name: str, arr: np.ndarray, ndim: int, dtype: type | None = None, channels: int | None = None
):
    if not isinstance(arr, np.ndarray):
        raise ValueError(f"{name} must be a numpy array, got {type(arr).__name__}")
    if arr.ndim != ndim or (channels is not None and arr.shape[-1] != channels):
        want = f"[H, W, {channels}]" if channels else ("[H, W]" if ndim == 2 else f"{ndim}-D")
        raise ValueError(f"{name} must have shape {want}, got {tuple(arr.shape)}")
    if dtype is not None and arr.dtype != dtype:
        raise ValueError(f"{name} must have dtype {np.dtype(dtype).name}, got {arr.dtype}")


def _suffix(path: Path, allowed, what: str) -> str:
    suffix = path.suffix.lower()
    if suffix not in allowed:
        raise ValueError(
            f"path {str(path)!r}: unsupported {what} suffix {suffix!r}; expected one of {sorted(allowed)}"
        )
    return suffix


def _open_image(path: Path, data: np.ndarray | None = None) -> Image.Image:
    """Decode with PIL, from the file or from its bytes ``data`` when already read."""
    try:
        img = Image.open(path if data is None else io.BytesIO(data.tobytes()))
        img.load()
    except FileNotFoundError:
        raise DatasetFormatError(path, "file does not exist") from None
    except Exception as exc:  # PIL raises many types for corrupt data
        raise DatasetFormatError(path, f"cannot decode image ({exc})") from exc
    return img


# ------------------------------------------------------------------------------------ fast decoding
@functools.cache
def _torchvision_io() -> ModuleType | None:
    """``torchvision.io`` if its image decoders load (imported on first use), else ``None`` (PIL decodes).

    torchvision 0.29 deprecated these decoders in favour of TorchCodec; once they are removed, PIL decodes
    everything, with the same pixels.
    """
    probe = np.frombuffer(encode_label(np.zeros((1, 1), np.uint8)), dtype=np.uint8).copy()
    try:
        from torchvision import io as tvio  # a probe: a torchvision without its image extension fails here

        _quietly(tvio.decode_png, torch.from_numpy(probe), tvio.ImageReadMode.UNCHANGED)
    except Exception:  # a torchvision without its image extension
        return None
    return tvio


def _quietly(decode: Callable[..., torch.Tensor], *args: Any) -> torch.Tensor:
    """Call a torchvision decoder without its deprecation warning (one per call otherwise; costs ~6 us)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_TV_DEPRECATION, category=DeprecationWarning)
        return decode(*args)


def _read_file(path: Path) -> np.ndarray:
    """The bytes of ``path`` as a writable ``uint8`` array (what the torchvision decoders take)."""
    try:
        return np.fromfile(path, dtype=np.uint8)
    except FileNotFoundError:
        raise DatasetFormatError(path, "file does not exist") from None
    except OSError as exc:
        raise DatasetFormatError(path, f"cannot read the file ({exc})") from exc


def _png_layout(data: np.ndarray) -> tuple[int, int] | None:
    """``(bit depth, colour type)`` from a PNG's IHDR chunk; ``None`` if ``data`` is not a PNG."""
    if len(data) < 33 or data[:8].tobytes() != _PNG_SIGNATURE or data[12:16].tobytes() != b"IHDR":
        return None
    return int(data[24]), int(data[25])


def _decode_fast(data: np.ndarray, png: bool) -> torch.Tensor | None:
    """``[C, H, W]`` decoded by torchvision.io (PNG or JPEG, as stored); ``None`` if it cannot (then PIL)."""
    tvio = _torchvision_io()
    if tvio is None:
        return None
    decode = tvio.decode_png if png else tvio.decode_jpeg
    try:
        return _quietly(decode, torch.from_numpy(data), tvio.ImageReadMode.UNCHANGED)
    except RuntimeError:  # corrupt or unsupported: PIL decides, and names the file if it fails too
        return None


def _decode_png_as(data: np.ndarray, layout: tuple[int, int], channels: int) -> torch.Tensor | None:
    """The decoded PNG if it has exactly ``layout`` (bit depth, colour type) and ``channels``, else ``None``."""
    x = _decode_fast(data, png=True) if _png_layout(data) == layout else None
    return x if x is not None and x.shape[0] == channels else None


def _pil_bytes(img: Image.Image, fmt: str, jpeg_quality: int = JPEG_QUALITY) -> bytes:
    buf = io.BytesIO()
    if fmt == "PNG":
        img.save(buf, format="PNG", compress_level=PNG_COMPRESS_LEVEL, optimize=False)
    else:
        img.save(buf, format="JPEG", quality=jpeg_quality, subsampling=0)
    return buf.getvalue()


def npy_bytes(arr: np.ndarray) -> bytes:
    """Serialise ``arr`` as ``.npy`` bytes (no pickle)."""
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return buf.getvalue()


def load_npy(path: str | Path) -> np.ndarray:
    """Load a ``.npy`` file with ``allow_pickle=False``; errors name the file."""
    path = Path(path)
    try:
        return np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise DatasetFormatError(path, "file does not exist") from None
    except Exception as exc:
        raise DatasetFormatError(path, f"cannot read .npy ({exc})") from exc


# ------------------------------------------------------------------------------------------------- RGB
def encode_rgb(rgb: np.ndarray, suffix: str = ".png", jpeg_quality: int = JPEG_QUALITY) -> bytes:
    """Encode ``uint8 [H, W, 3]`` as PNG or JPEG bytes (by ``suffix``; JPEG with 4:4:4 chroma at ``jpeg_quality``)."""
    _check_array("rgb", rgb, 3, np.uint8, 3)
    fmt = _RGB_SUFFIXES[_suffix(Path("x" + suffix), _RGB_SUFFIXES, "RGB")]
    return _pil_bytes(Image.fromarray(np.ascontiguousarray(rgb), mode="RGB"), fmt, jpeg_quality)


def write_rgb(path: str | Path, rgb: np.ndarray) -> None:
    """Write an RGB image; the format follows the suffix (``.png``, ``.jpg``, ``.jpeg``).

    Example:
        >>> import tempfile, pathlib, numpy as np
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "rgb.png"
        >>> img = np.zeros((4, 6, 3), np.uint8); img[1, 2] = (10, 20, 30)
        >>> write_rgb(p, img)
        >>> bool((read_rgb(p) == img).all())
        True
    """
    path = Path(path)
    atomic_write_bytes(path, encode_rgb(rgb, path.suffix))


def read_rgb(path: str | Path) -> np.ndarray:
    """Read an RGB image as ``uint8 [H, W, 3]`` (grey or RGBA files are converted)."""
    path = Path(path)
    data = _read_file(path)
    if data[:3].tobytes() == _JPEG_SOI:
        x = _decode_fast(data, png=False)
        x = x if x is not None and x.shape[0] == 3 else None  # grey or CMYK JPEG: PIL converts
    else:
        x = _decode_png_as(data, _PNG_RGB8, 3)
    if x is not None:
        return x.permute(1, 2, 0).numpy()  # the decoder's own HWC buffer: no copy
    img = _open_image(path, data)
    if img.mode != "RGB":
        img = img.convert("RGB")
    return np.asarray(img, dtype=np.uint8).copy()


# ---------------------------------------------------------------------------------------------- labels
def encode_label(label: np.ndarray) -> bytes:
    """Encode ``uint8 [H, W]`` ids as a single-channel 8-bit PNG."""
    _check_array("label", label, 2, np.uint8)
    return _pil_bytes(Image.fromarray(np.ascontiguousarray(label), mode="L"), "PNG")


def write_label(path: str | Path, label: np.ndarray) -> None:
    """Write raw semantic ids (``uint8 [H, W]``) as an 8-bit PNG."""
    path = Path(path)
    _suffix(path, {".png"}, "label")
    atomic_write_bytes(path, encode_label(label))


def read_label(path: str | Path) -> np.ndarray:
    """Read an 8-bit label PNG (greyscale or palette indices) as ``uint8 [H, W]``."""
    path = Path(path)
    data = _read_file(path)
    x = _decode_png_as(data, _PNG_GREY8, 1)  # palette files go through PIL: torchvision expands them to RGB
    if x is not None:
        return x[0].numpy()
    img = _open_image(path, data)
    if img.mode not in ("L", "P"):
        raise DatasetFormatError(
            path, f"label image must be single-channel 8-bit (mode L or P), got mode {img.mode}"
        )
    return np.asarray(img, dtype=np.uint8).copy()


# ----------------------------------------------------------------------------------------------- depth
def encode_depth(depth: np.ndarray, suffix: str = ".png", scale: float = DEPTH_PNG_SCALE) -> bytes:
    """Encode a float range map ``[H, W]`` (metres, 0/NaN/inf/negative = invalid).

    Args:
        depth: Range in metres.
        suffix: ``.png`` (16-bit, ``round(range * scale)``), ``.npy`` or ``.pfm`` (float32).
        scale: Quantisation of the 16-bit PNG.
    """
    _check_array("depth", depth, 2)
    if not np.issubdtype(depth.dtype, np.floating):
        raise ValueError(f"depth must be a float array, got dtype {depth.dtype}")
    if not scale > 0:
        raise ValueError(f"scale must be positive, got {scale}")
    suffix = _suffix(Path("x" + suffix), _DEPTH_SUFFIXES, "depth")
    d = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0).astype(np.float32)
    if suffix == ".png":
        q = np.minimum(np.rint(d.astype(np.float64) * scale), 65535).astype(np.uint16)
        return _pil_bytes(Image.fromarray(q), "PNG")
    if suffix == ".npy":
        return npy_bytes(d)
    return _pfm_bytes(d)


def write_depth(path: str | Path, depth: np.ndarray, scale: float = DEPTH_PNG_SCALE) -> None:
    """Write a range map; the encoding follows the suffix (``.png`` 16-bit, ``.npy``, ``.pfm``).

    Example:
        >>> import tempfile, pathlib, numpy as np
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "d.png"
        >>> write_depth(p, np.array([[0.0, 1.5], [np.inf, 100.25]], np.float32))
        >>> read_depth(p).tolist()
        [[0.0, 1.5], [0.0, 100.25]]
    """
    path = Path(path)
    atomic_write_bytes(path, encode_depth(depth, path.suffix, scale))


def read_depth(path: str | Path, scale: float = DEPTH_PNG_SCALE) -> np.ndarray:
    """Read a range map as ``float32 [H, W]`` metres (0 = invalid)."""
    path = Path(path)
    suffix = _suffix(path, _DEPTH_SUFFIXES, "depth")
    if suffix == ".png":
        data = _read_file(path)
        x = _decode_png_as(data, _PNG_GREY16, 1)
        if x is not None:  # uint16 -> float32 in one pass (the same values as astype, then divide)
            return np.divide(x[0].numpy(), np.float32(scale), dtype=np.float32)
        img = _open_image(path, data)
        if img.mode not in ("I;16", "I;16B", "I", "I;16L"):
            raise DatasetFormatError(path, f"depth PNG must be 16-bit single-channel, got mode {img.mode}")
        return (np.asarray(img).astype(np.float32) / np.float32(scale)).astype(np.float32)
    if suffix == ".npy":
        d = load_npy(path)
        if d.ndim != 2 or not np.issubdtype(d.dtype, np.floating):
            raise DatasetFormatError(path, f"depth .npy must be a 2-D float array, got {d.dtype} {d.shape}")
        return d.astype(np.float32, copy=False)
    return read_pfm(path)


# ------------------------------------------------------------------------------------------------- PFM
def _pfm_bytes(d: np.ndarray) -> bytes:
    h, w = d.shape
    # PFM stores rows bottom-to-top; a negative scale marks little-endian data.
    header = f"Pf\n{w} {h}\n-1.0\n".encode("ascii")
    return header + np.ascontiguousarray(np.flipud(d), dtype="<f4").tobytes()


def write_pfm(path: str | Path, image: np.ndarray) -> None:
    """Write a single-channel float32 PFM (rows stored bottom-to-top, little-endian)."""
    _check_array("image", image, 2)
    atomic_write_bytes(path, _pfm_bytes(np.asarray(image, np.float32)))


def read_pfm(path: str | Path) -> np.ndarray:
    """Read a PFM file (``Pf`` grey or ``PF`` colour) as float32 ``[H, W]`` or ``[H, W, 3]``."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise DatasetFormatError(path, "file does not exist") from None
    match = re.match(rb"(P[fF])\s+(\d+)\s+(\d+)\s+([-+0-9.eE]+)\s", raw)
    if match is None:
        raise DatasetFormatError(path, "not a PFM file (expected a 'Pf'/'PF' header)")
    channels = 1 if match.group(1) == b"Pf" else 3
    w, h, scale = int(match.group(2)), int(match.group(3)), float(match.group(4))
    data = raw[match.end() :]
    count = w * h * channels
    if len(data) < 4 * count:
        raise DatasetFormatError(path, f"PFM data truncated: expected {4 * count} bytes, got {len(data)}")
    arr = np.frombuffer(data[: 4 * count], dtype="<f4" if scale < 0 else ">f4").reshape(h, w, channels)
    arr = np.flipud(arr).astype(np.float32)
    return arr[..., 0].copy() if channels == 1 else arr.copy()


# ------------------------------------------------------------------------------------------- LiDAR
def write_lidar(path: str | Path, points: np.ndarray) -> None:
    """Write a LiDAR scan: float32 ``[N, 4]`` = x, y, z (LiDAR frame, metres), raw semantic id."""
    if not isinstance(points, np.ndarray) or points.ndim != 2 or points.shape[1] != 4:
        raise ValueError(f"points must be a numpy array [N, 4], got {getattr(points, 'shape', type(points))}")
    atomic_write_bytes(path, npy_bytes(points.astype(np.float32, copy=False)))


def read_lidar(path: str | Path) -> np.ndarray:
    """Read a LiDAR scan as float32 ``[N, 4]`` (x, y, z, raw id)."""
    pts = load_npy(path)
    if pts.ndim != 2 or pts.shape[1] != 4 or pts.dtype != np.float32:
        raise DatasetFormatError(
            path, f"LiDAR scan must be float32 [N, 4], got {pts.dtype} {list(pts.shape)}"
        )
    return pts


def write_visibility(path: str | Path, visible: np.ndarray) -> None:
    """Write per-point visibility flags (bool ``[N]``)."""
    if not isinstance(visible, np.ndarray) or visible.ndim != 1 or visible.dtype != np.bool_:
        raise ValueError(
            f"visible must be a bool numpy array [N], got {getattr(visible, 'dtype', type(visible))}"
        )
    atomic_write_bytes(path, npy_bytes(visible))


def read_visibility(path: str | Path, num_points: int | None = None) -> np.ndarray:
    """Read per-point visibility flags (bool ``[N]``); checks ``N`` against ``num_points`` when given."""
    return _read_per_point(path, np.bool_, "visibility", "flags", num_points)


def read_beams(path: str | Path, num_points: int | None = None) -> np.ndarray:
    """Read the beam of every LiDAR point (int32 ``[N]``, ``channel * N_PC + column``); checks ``N`` if given."""
    return _read_per_point(path, np.int32, "beams", "beams", num_points)


def _read_per_point(
    path: str | Path, dtype: type, what: str, unit: str, num_points: int | None
) -> np.ndarray:
    """A ``[N]`` array of ``dtype`` with one entry per LiDAR point (``N == num_points`` when given)."""
    values = load_npy(path)
    if values.ndim != 1 or values.dtype != dtype:
        name = np.dtype(dtype).name
        raise DatasetFormatError(path, f"{what} must be {name} [N], got {values.dtype} {list(values.shape)}")
    if num_points is not None and values.shape[0] != num_points:
        raise DatasetFormatError(path, f"has {values.shape[0]} {unit} but the scan has {num_points} points")
    return values


SCAN_PHASE_HEADER = "frame,phase_rad"


def encode_scan_phases(frames: list[str], phases: np.ndarray) -> bytes:
    """``lidar_scan.csv``: one ``frame,phase_rad`` line per frame (the scan's azimuth phase, 17 digits).

    Example:
        >>> encode_scan_phases(["000000"], np.array([0.5])).decode()
        'frame,phase_rad\\n000000,0.5\\n'
    """
    lines = [SCAN_PHASE_HEADER] + [f"{f},{float(p)!r}" for f, p in zip(frames, phases, strict=True)]
    return ("\n".join(lines) + "\n").encode()


def read_scan_phases(path: str | Path) -> dict[str, float]:
    """Read ``lidar_scan.csv`` -> ``{frame: phase_rad}``; errors name the file and line."""
    path = Path(path)
    lines = path.read_text(encoding="utf-8").splitlines()
    if not lines or lines[0].strip() != SCAN_PHASE_HEADER:
        raise DatasetFormatError(path, f"must start with the header {SCAN_PHASE_HEADER!r}")
    out: dict[str, float] = {}
    for n, line in enumerate(lines[1:], start=2):
        try:
            frame, phase = line.split(",")
            out[frame] = float(phase)
        except ValueError:
            raise DatasetFormatError(path, f"line {n}: expected 'frame,phase_rad', got {line!r}") from None
    return out
