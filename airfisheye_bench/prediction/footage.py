"""A user's own footage, frame by frame: a folder of images or a video file (``airfisheye-predict input=``).

A folder holds images (:data:`IMAGE_SUFFIXES`, any case) directly in it, predicted in the order of their names; a
frame is named by its file's stem (so ``a.png`` and ``a.jpg`` in one folder are refused: their outputs would
collide). A video (:data:`VIDEO_SUFFIXES`) is read through imageio's FFmpeg plugin, the optional ``video`` extra
(``pip install "airfisheye-bench[video]"``); its frames are named ``frame_000000``, ``frame_000001``, ...

Image headers are read before any frame is decoded (:meth:`Footage.sizes`), so a frame the model cannot serve is
refused before the first prediction; a file whose header or pixels cannot be read is a one-line
:class:`~airfisheye_bench.errors.InputFileError` naming it.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from omegaconf import OmegaConf
from PIL import Image, UnidentifiedImageError

from airfisheye_bench.config_checks import check_extras
from airfisheye_bench.errors import InputFileError, MissingFileError
from airfisheye_bench.specs.formats import RANGE

__all__ = [
    "IMAGE_SUFFIXES",
    "VIDEO_SUFFIXES",
    "Footage",
    "open_footage",
    "read_sparse",
]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v")
#: The packages of the ``video`` extra (``pyproject.toml``): imageio and its FFmpeg binary.
VIDEO_PACKAGES = ("imageio", "imageio_ffmpeg")


@dataclass(frozen=True)
class Footage:
    """Frames of a folder of images or of a video.

    Attributes:
        path: The folder or the video file.
        kind: ``images`` or ``video``.
        files: The image files in frame order (a folder), else empty.
        count: Number of frames (a video's is estimated from its duration and frame rate; ``None``: unknown).
    """

    path: Path
    kind: str
    files: tuple[Path, ...] = field(default=())
    count: int | None = None

    def sizes(self) -> Iterator[tuple[str, tuple[int, int]]]:
        """``(frame name, (width, height))`` of every frame, from the headers (a video's frames share one size)."""
        if self.kind == "video":
            yield "frame_000000", _video_size(self.path)
            return
        for path in self.files:
            try:
                with Image.open(path) as image:
                    yield path.stem, image.size
            except (OSError, UnidentifiedImageError, SyntaxError) as err:
                raise InputFileError(f"{path}: not a readable image ({_reason(err)})") from None

    def frames(self) -> Iterator[tuple[str, np.ndarray]]:
        """``(frame name, uint8 RGB [H, W, 3])`` in order."""
        if self.kind == "video":
            yield from _video_frames(self.path)
            return
        for path in self.files:
            yield path.stem, read_image(path)


def open_footage(path: str | Path) -> Footage:
    """The footage at ``path`` (``input=``): a folder of images, or a video file.

    Raises:
        MissingFileError: no such file or folder.
        InputFileError: a folder without images, two images of one name, or a file that is not a video.
        ConfigError: a video, but the ``video`` extra is not installed.

    Example:
        >>> import tempfile
        >>> folder = Path(tempfile.mkdtemp())
        >>> for name in ("b", "a"):
        ...     Image.new("RGB", (8, 6)).save(folder / f"{name}.png")
        >>> footage = open_footage(folder)
        >>> footage.kind, footage.count, list(footage.sizes())
        ('images', 2, [('a', (8, 6)), ('b', (8, 6))])
        >>> open_footage(folder / "nowhere")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        airfisheye_bench.errors.MissingFileError: input=.../nowhere does not exist; give a folder of images or a video file
    """
    path = Path(path).expanduser()
    if path.is_dir():
        files = sorted(
            p
            for p in path.iterdir()
            if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".") and p.is_file()
        )
        if not files:
            raise InputFileError(
                f"input={path}: no images ({', '.join(IMAGE_SUFFIXES)}) in the folder; give a folder of frames "
                "or a video file"
            )
        stems: dict[str, Path] = {}
        for p in files:
            if p.stem in stems:
                raise InputFileError(
                    f"input={path}: {stems[p.stem].name} and {p.name} are one frame name ({p.stem}); their "
                    "predictions would overwrite each other, keep one"
                )
            stems[p.stem] = p
        return Footage(path, "images", tuple(files), len(files))
    if path.is_file():
        if path.suffix.lower() not in VIDEO_SUFFIXES:
            raise InputFileError(
                f"input={path}: not a folder of images or a video file ({', '.join(VIDEO_SUFFIXES)})"
            )
        for package in VIDEO_PACKAGES:  # a look-up only: one line naming the extra
            check_extras(OmegaConf.create({"input": str(path)}), {"input": ((package,), "video")})
        return Footage(path, "video", count=_video_count(path))
    raise MissingFileError(f"input={path} does not exist; give a folder of images or a video file")


def read_image(path: Path) -> np.ndarray:
    """An image file as ``uint8 RGB [H, W, 3]`` (grey and palette images are expanded, alpha is dropped).

    Raises:
        InputFileError: the file cannot be decoded (the message names it).
    """
    try:
        with Image.open(path) as image:
            return np.asarray(image.convert("RGB")).copy()
    except (OSError, UnidentifiedImageError, SyntaxError, ValueError) as err:
        raise InputFileError(f"{path}: not a readable image ({_reason(err)})") from None


def read_sparse(folder: Path, name: str, shape: tuple[int, int]) -> torch.Tensor:
    """The sparse range map of frame ``name`` from ``sparse=``: ``<name>.npy`` (metres) or ``<name>.png`` (16-bit,
    range * 256), ``[1, H, W]`` float32 at the model's image size ``shape`` ``(H, W)``, 0 = no point.

    Raises:
        MissingFileError: neither file exists.
        InputFileError: both exist, or the file is of another size or type, or holds negative or non-finite values.
    """
    candidates = [folder / f"{name}{suffix}" for suffix in RANGE.suffixes]
    present = [p for p in candidates if p.is_file()]
    if not present:
        raise MissingFileError(
            f"sparse={folder}: no {' or '.join(p.name for p in candidates)} for frame {name} (one sparse range "
            "map per frame, named as the frame)"
        )
    if len(present) > 1:
        raise InputFileError(f"sparse={folder}: both {present[0].name} and {present[1].name}; keep one")
    path = present[0]
    problem = RANGE.check(path, shape)
    if problem is None:
        try:
            depth = RANGE.decode(path).float().reshape(1, *shape)
        except (OSError, ValueError) as err:
            problem = f"not readable ({_reason(err)})"
        else:
            if not bool(torch.isfinite(depth).all()) or bool((depth < 0).any()):
                problem = "holds negative or non-finite values (range in metres, 0 where there is no point)"
    if problem is not None:
        raise InputFileError(
            f"{path}: {problem}; a sparse range map is the model's image ({shape[1]} wide, {shape[0]} high), as "
            "16-bit PNG (range * 256) or float .npy (metres)"
        )
    return depth


# -------------------------------------------------------------------------------------------------- video
def _video_meta(path: Path) -> dict:
    import imageio.v3 as iio  # the optional `video` extra: only video input needs it

    try:
        return iio.immeta(path, plugin="FFMPEG")
    except (
        Exception
    ) as err:  # imageio raises OSError, RuntimeError or its own errors for a file FFmpeg refuses
        raise InputFileError(f"{path}: not a readable video ({_reason(err)})") from None


def _video_size(path: Path) -> tuple[int, int]:
    width, height = _video_meta(path)["size"]
    return int(width), int(height)


def _video_count(path: Path) -> int | None:
    """The frame count from the duration and frame rate (a container's own count is often missing)."""
    meta = _video_meta(path)
    count = float(meta.get("duration") or 0) * float(meta.get("fps") or 0)
    return round(count) if math.isfinite(count) and count > 0 else None


def _video_frames(path: Path) -> Iterator[tuple[str, np.ndarray]]:
    import imageio.v3 as iio  # the optional `video` extra: only video input needs it

    index = 0
    try:
        for frame in iio.imiter(path, plugin="FFMPEG"):
            yield f"frame_{index:06d}", np.ascontiguousarray(frame[..., :3])
            index += 1
    except Exception as err:  # FFmpeg stopping on a damaged stream: imageio's errors, OSError or RuntimeError
        raise InputFileError(f"{path}: frame {index} cannot be decoded ({_reason(err)})") from None
    if index == 0:
        raise InputFileError(f"{path}: the video holds no frames")


def _reason(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return text[0] if text else type(err).__name__
