"""AirSim360 / Omni360-X on disk: the scene folders, the frames of a scene and its files, and their decoders.

Read from github:Insta360-Research-Team/AirSim360 (``data/demo_sample/README.md``, ``PANORAMIC_DATA_FORMAT.md``,
``scripts/read_demo_ground_truth.py``, ``depth/check_depth.py``, ``instance/README.md``,
``instance/read_instance_labels_example.py``; the root ``README.md``'s Omni360-Scene section). A scene folder holds
one folder per modality, in either of two namings:

=============  ====================  =============================================  ========================================
modality       demo sample           Omni360-Scene release (``<p>``: scene prefix)  files (one stem per frame)
=============  ====================  =============================================  ========================================
panorama RGB   ``panorama/``         ``<p>_Raw/`` (or ``<p>_Raw_Part1/``, ...)      ``<stem>.png|jpg``: equirectangular RGB
depth          ``depth/``            ``<p>_Depth/``                                 ``<stem>`` or ``Depth_<n>`` (for
                                                                                    ``panorama_<n>``) ``.h5|.exr|.npy``
semantic       ``semantic/``         ``<p>_seg_panorama/``                          ``<stem>.png``: class id in alpha
instance       ``instance/``         ``<p>_instance_panorama/``                     ``<stem>.png``: alpha class, RGB instance
class list     ``semantic_lists_<env>.txt``  ``<p>_semantic_list`` (any extension)  :mod:`.omni360_labels`
=============  ====================  =============================================  ========================================

Depth is the Euclidean distance from the optical centre along the pixel's ray (range, not z), metres, up to
1000 m: HDF5 dataset ``/depth`` (float32 metres; the legacy ``uint16`` carries ``depth_range_m`` and means
``value / 65535 * depth_range_m``), the EXR's R channel (``Y`` for a one-channel file, as the demo reader takes it),
or a ``.npy`` array (first channel). The far plane (>= 1000 m: sky) and non-finite values are "no depth" (0).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.exr import EXR_EXTRA, read_exr_channel

__all__ = [
    "DEPTH_EXTS",
    "FAR_PLANE_M",
    "PANORAMA_EXTS",
    "Scene",
    "depth_candidates",
    "find_scenes",
    "image_size",
    "natural_key",
    "read_alpha",
    "read_depth",
    "read_instance",
    "read_panorama",
]

PANORAMA_EXTS = (".png", ".jpg", ".jpeg")
LABEL_EXTS = (".png",)
#: Depth encodings, in the order they are looked for when a frame has several.
DEPTH_EXTS = (".h5", ".exr", ".npy")
#: The renderer's maximum range: depth at or beyond it is the far plane (sky), not a surface.
FAR_PLANE_M = 1000.0

#: Folder roles -> (the demo's name, the release's pattern on the lower-cased name).
_FOLDERS: dict[str, tuple[str, re.Pattern[str]]] = {
    "panorama": ("panorama", re.compile(r"^.+_raw(_part\d+)?$")),
    "depth": ("depth", re.compile(r"^.+_depth(_panorama)?$")),
    "semantic": ("semantic", re.compile(r"^.+_seg_panorama$")),
    "instance": ("instance", re.compile(r"^.+_instance_panorama$")),
}
_CLASS_LIST = (re.compile(r"^semantic_lists_.+\.txt$"), re.compile(r"^.+_semantic_list(\..+)?$"))
_PANORAMA_N = re.compile(r"^panorama_(\d+)$", re.IGNORECASE)
_DIGITS = re.compile(r"(\d+)")


def natural_key(stem: str) -> tuple:
    """Sort key that orders the numbers in a name by value (``panorama_9`` before ``panorama_10``).

    Example:
        >>> sorted(["panorama_10", "panorama_9", "panorama_100"], key=natural_key)
        ['panorama_9', 'panorama_10', 'panorama_100']
    """
    return tuple((0, int(p), "") if p.isdigit() else (1, 0, p) for p in _DIGITS.split(stem) if p)


def depth_candidates(stem: str) -> list[str]:
    """The depth file names a frame's depth may have, in the order they are looked for.

    Example:
        >>> depth_candidates("panorama_73")[:4]
        ['panorama_73.h5', 'panorama_73.exr', 'panorama_73.npy', 'Depth_73.h5']
    """
    stems = [stem]
    match = _PANORAMA_N.match(stem)
    if match:
        stems.append(f"Depth_{match.group(1)}")
    return [s + ext for s in stems for ext in DEPTH_EXTS]


@dataclass(frozen=True)
class Scene:
    """One scene folder: its modality folders (``None`` when absent), its class list and its frames.

    Attributes:
        name: The folder's name (the sample ids' first part).
        folder: The scene folder.
        panorama: The panorama folders (the release splits some scenes' into parts).
        depth, semantic, instance: The modality folders, or ``None``.
        class_list: The class list file, or ``None``.
        frames: Stem -> panorama file, in natural order of the stems.
    """

    name: str
    folder: Path
    panorama: tuple[Path, ...]
    depth: Path | None
    semantic: Path | None
    instance: Path | None
    class_list: Path | None
    frames: dict[str, Path]

    def file_names(self, folder: Path | None) -> dict[str, Path]:
        """File name -> file of ``folder``'s files (empty without the folder): one listing, looked up per frame."""
        return {} if folder is None else _listing(folder)


def find_scenes(root: Path) -> list[Scene]:
    """The scenes under ``root``: ``root`` itself when it has a panorama folder, else its sub-folders that have one
    (sorted by name).

    Raises:
        DatasetFormatError: naming ``root`` when no scene is found, or a scene folder with two folders of one
            modality, two class lists, a frame stored twice, or no panorama image.
    """
    if _role_folders(root)["panorama"]:
        return [_scene(root)]
    scenes = [
        _scene(folder)
        for folder in sorted(p for p in root.iterdir() if p.is_dir())
        if _role_folders(folder)["panorama"]
    ]
    if not scenes:
        raise DatasetFormatError(
            root,
            "no Omni360 scene: expected <scene>/panorama/<stem>.png (AirSim360's demo sample) or "
            "<scene>/<prefix>_Raw/panorama_<n>.png (Omni360-Scene), with the root or its sub-folders as scenes",
        )
    return scenes


def _role_folders(folder: Path) -> dict[str, list[Path]]:
    found: dict[str, list[Path]] = {role: [] for role in _FOLDERS}
    for path in sorted(folder.iterdir()):
        if not path.is_dir():
            continue
        lower = path.name.lower()
        for role, (demo, pattern) in _FOLDERS.items():
            if lower == demo or pattern.match(lower):
                found[role].append(path)
    return found


def _scene(folder: Path) -> Scene:
    roles = _role_folders(folder)
    single: dict[str, Path | None] = {}
    for role in ("depth", "semantic", "instance"):
        if len(roles[role]) > 1:
            names = ", ".join(p.name for p in roles[role])
            raise DatasetFormatError(folder, f"two {role} folders ({names}); keep one")
        single[role] = roles[role][0] if roles[role] else None
    lists = sorted(
        p for p in folder.iterdir() if p.is_file() and any(rx.match(p.name.lower()) for rx in _CLASS_LIST)
    )
    if len(lists) > 1:
        raise DatasetFormatError(folder, f"two class lists ({', '.join(p.name for p in lists)}); keep one")
    frames: dict[str, Path] = {}
    for part in roles["panorama"]:
        for path in _listing(part).values():
            if path.suffix.lower() not in PANORAMA_EXTS:
                continue
            if path.stem in frames:
                raise DatasetFormatError(
                    path, f"frame {path.stem} is stored twice (also {frames[path.stem]})"
                )
            frames[path.stem] = path
    if not frames:
        raise DatasetFormatError(
            roles["panorama"][0], f"no panorama image ({'|'.join(e[1:] for e in PANORAMA_EXTS)})"
        )
    return Scene(
        name=folder.name,
        folder=folder,
        panorama=tuple(roles["panorama"]),
        depth=single["depth"],
        semantic=single["semantic"],
        instance=single["instance"],
        class_list=lists[0] if lists else None,
        frames={stem: frames[stem] for stem in sorted(frames, key=natural_key)},
    )


def _listing(folder: Path) -> dict[str, Path]:
    """The files of ``folder`` by name (``os.scandir``: no ``stat`` per file, for folders of 10^5 frames)."""
    with os.scandir(folder) as entries:
        return {e.name: folder / e.name for e in entries if e.is_file()}


# ------------------------------------------------------------------------------------------------- decoders
def _open(path: Path) -> Image.Image:
    try:
        return Image.open(path)
    except FileNotFoundError:
        raise DatasetFormatError(path, "missing") from None
    except OSError as err:
        raise DatasetFormatError(path, f"unreadable image ({err})") from None


def image_size(path: Path) -> tuple[int, int]:
    """``(width, height)`` from an image's header."""
    with _open(path) as img:
        return img.size


def read_panorama(path: Path) -> np.ndarray:
    """``uint8 [H, W, 3]`` RGB (an alpha channel, as renderers often write, is dropped)."""
    with _open(path) as img:
        try:
            return np.array(
                img.convert("RGB") if img.mode != "RGB" else img
            )  # writable: torch takes it as is
        except OSError as err:
            raise DatasetFormatError(path, f"unreadable image ({err})") from None


def _rgba(path: Path) -> np.ndarray:
    with _open(path) as img:
        if img.mode not in ("RGBA", "LA"):
            raise DatasetFormatError(
                path, f"expected a PNG with an alpha channel (the class id), got mode {img.mode}"
            )
        try:
            return np.asarray(img.convert("RGBA"))
        except OSError as err:
            raise DatasetFormatError(path, f"unreadable image ({err})") from None


def read_alpha(path: Path) -> np.ndarray:
    """``uint8 [H, W]``: the class id of a semantic (or instance) PNG, its alpha channel."""
    return np.ascontiguousarray(_rgba(path)[..., 3])


def read_instance(path: Path) -> np.ndarray:
    """``int64 [H, W]``: an instance PNG's ``(A, R, G, B)`` as one id, ``A << 24 | R << 16 | G << 8 | B`` (the
    demo's unique key of an object; its class is ``id >> 24``); 0 where alpha is 0 (background)."""
    rgba = _rgba(path).astype(np.int64)
    ids = (rgba[..., 3] << 24) | (rgba[..., 0] << 16) | (rgba[..., 1] << 8) | rgba[..., 2]
    return np.where(rgba[..., 3] > 0, ids, 0)


def read_depth(path: Path) -> np.ndarray:
    """``float32 [H, W]`` range in metres of a ``.h5`` / ``.exr`` / ``.npy`` depth file, 0 = no depth.

    Raises:
        DatasetFormatError: naming the file: unreadable, not one plane, negative values, a missing reader package.
    """
    suffix = path.suffix.lower()
    if suffix == ".h5":
        depth = _read_h5(path)
    elif suffix == ".exr":
        depth = read_exr_channel(path, ("R", "Y"))
    elif suffix == ".npy":
        try:
            depth = np.load(path, allow_pickle=False)
        except FileNotFoundError:
            raise DatasetFormatError(path, "missing") from None
        except (OSError, ValueError) as err:
            raise DatasetFormatError(path, f"unreadable .npy ({err})") from None
        if depth.ndim == 3:  # the demo reader takes the first channel of a multi-channel array
            depth = depth[..., 0]
    else:
        raise DatasetFormatError(path, f"unknown depth encoding; expected one of {', '.join(DEPTH_EXTS)}")
    if depth.ndim != 2 or not np.issubdtype(depth.dtype, np.number):
        raise DatasetFormatError(path, f"expected one plane of numbers, got {depth.dtype} {depth.shape}")
    depth = depth.astype(np.float32, copy=False)
    valid = np.isfinite(depth)
    if (depth[valid] < 0).any():
        raise DatasetFormatError(
            path, "negative depth (expected range in metres, 0 or the far plane for none)"
        )
    return np.where(valid & (depth < FAR_PLANE_M), depth, np.float32(0.0)).astype(np.float32, copy=False)


def _read_h5(path: Path) -> np.ndarray:
    try:
        import h5py  # optional (the omni360 extra): only HDF5 depth needs it
    except ImportError:
        raise DatasetFormatError(
            path,
            f'reading HDF5 needs the Python package h5py, which is not installed: pip install -e ".[{EXR_EXTRA}]" '
            f'(or pip install "airfisheye-bench[{EXR_EXTRA}]")',
        ) from None
    try:
        with h5py.File(path, "r") as h5:
            if "depth" not in h5 or not isinstance(h5["depth"], h5py.Dataset):
                raise DatasetFormatError(path, f"no dataset /depth (it has {sorted(h5)})")
            data = h5["depth"]
            array = np.asarray(data)
            if array.dtype == np.uint16:  # the legacy quantised form
                if "depth_range_m" not in data.attrs:
                    raise DatasetFormatError(
                        path, "uint16 depth without its depth_range_m attribute", key="/depth"
                    )
                scale = float(np.asarray(data.attrs["depth_range_m"]).reshape(-1)[0]) / 65535.0
                array = array.astype(np.float32) * np.float32(scale)
    except FileNotFoundError:
        raise DatasetFormatError(path, "missing") from None
    except OSError as err:
        raise DatasetFormatError(path, f"unreadable HDF5 ({err})") from None
    return np.squeeze(array, axis=-1) if array.ndim == 3 and array.shape[-1] == 1 else array
