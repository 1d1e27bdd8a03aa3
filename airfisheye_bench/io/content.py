"""A dataset's identity by its content: a SHA-256 over the decoded arrays of its files, not over their bytes.

``manifest.json`` (:mod:`airfisheye_bench.io.manifest`) checksums the files as written, which is what a copy must
match; but the same pixels written by another PNG encoder or zlib (e.g. another Pillow version) give other bytes and
so another manifest. :func:`content_identity` hashes what the files hold (pixels, depths, points, parsed YAML), so
two installations that generate the same data agree on it, and it changes when the generator's output changes.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
from pathlib import Path

import numpy as np
import yaml
from PIL import Image

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.io import codecs
from airfisheye_bench.io.layout import MANIFEST_NAME
from airfisheye_bench.io.manifest import dataset_files, sha256_file
from airfisheye_bench.io.progress_report import track

__all__ = ["CONTENT_CACHE_NAME", "CONTENT_FORMAT", "content_identity", "decoded_content"]

CONTENT_FORMAT = "airfisheye-content/1"
#: Where :func:`content_identity` caches its answer inside the dataset (left out of the manifest by its prefix).
CONTENT_CACHE_NAME = ".airfisheye-content.json"
_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def decoded_content(path: str | Path) -> tuple[str, bytes]:
    """What a dataset file holds, independent of how it was encoded: ``(description, bytes)``.

    Images are decoded (PIL) to their pixel array, ``.npy`` and ``.pfm`` to their array, YAML and JSON parsed and
    written back canonically; other files are their bytes. The description names the kind, dtype and shape, so two
    arrays with the same bytes but another shape differ.

    Example:
        >>> import tempfile
        >>> folder = Path(tempfile.mkdtemp())
        >>> pixels = (np.arange(48, dtype=np.uint8) * 5).reshape(4, 4, 3)
        >>> Image.fromarray(pixels).save(folder / "a.png", compress_level=1)
        >>> Image.fromarray(pixels).save(folder / "b.png", compress_level=9)
        >>> (folder / "a.png").read_bytes() == (folder / "b.png").read_bytes()
        False
        >>> decoded_content(folder / "a.png") == decoded_content(folder / "b.png")
        True
        >>> decoded_content(folder / "a.png")[0]
        'image RGB uint8 (4, 4, 3)'
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in _IMAGE_SUFFIXES:
        with Image.open(path) as img:
            mode = img.mode
            array = np.asarray(img)
        return f"image {mode} {_array_text(array)}", _array_bytes(array)
    if suffix == ".npy":
        array = np.load(path, allow_pickle=False)
        return f"npy {_array_text(array)}", _array_bytes(array)
    if suffix == ".pfm":
        array = codecs.read_pfm(path)
        return f"pfm {_array_text(array)}", _array_bytes(array)
    if suffix in (".yaml", ".yml", ".json"):
        text = path.read_text(encoding="utf-8")
        data = yaml.safe_load(text) if suffix != ".json" else json.loads(text)
        return "structured", json.dumps(data, sort_keys=True, separators=(",", ":")).encode("utf-8")
    return "bytes", path.read_bytes()


def _array_text(array: np.ndarray) -> str:
    return f"{array.dtype.newbyteorder('<').str if array.dtype.byteorder == '>' else array.dtype.name} {array.shape}"


def _array_bytes(array: np.ndarray) -> bytes:
    if array.dtype.byteorder == ">":
        array = array.astype(array.dtype.newbyteorder("<"))
    return np.ascontiguousarray(array).tobytes()


def content_identity(root: str | Path, use_cache: bool = True, progress: bool = False) -> dict[str, object]:
    """The identity of a dataset's content: SHA-256 over every file's decoded arrays (:func:`decoded_content`).

    Unlike ``manifest.json``, whose checksums are of the encoded files, it does not change when the same pixels,
    depths and points are written by another PNG encoder or zlib (Pillow version): two installations that generate
    the same data agree on it, and it changes when the generator's output really changes. The answer is cached in
    ``root/.airfisheye-content.json`` next to the SHA-256 of the manifest it was computed for (a dataset whose
    manifest changed is hashed again; without a manifest nothing is cached).

    Returns:
        ``{"format": "airfisheye-content/1", "content_sha256": hex, "files": count}``.

    Example:
        >>> import tempfile
        >>> a, b = Path(tempfile.mkdtemp()), Path(tempfile.mkdtemp())
        >>> _ = (a / "x.txt").write_text("x"), (b / "x.txt").write_text("x")
        >>> content_identity(a) == content_identity(b), content_identity(a)["files"]
        (True, 1)
    """
    root = Path(root)
    manifest = root / MANIFEST_NAME
    manifest_sha = sha256_file(manifest) if manifest.is_file() else None
    cache = root / CONTENT_CACHE_NAME
    if use_cache and manifest_sha is not None and cache.is_file():
        try:
            cached = json.loads(cache.read_text(encoding="utf-8"))
            if cached.get("manifest_sha256") == manifest_sha and cached.get("format") == CONTENT_FORMAT:
                return {k: cached[k] for k in ("format", "content_sha256", "files")}
        except (OSError, ValueError, KeyError):
            pass  # an unreadable cache is recomputed
    files = dataset_files(root)
    h = hashlib.sha256(CONTENT_FORMAT.encode("ascii"))
    for rel in track(files, len(files), "content", "file", progress):
        description, data = decoded_content(root / rel)
        h.update(f"\n{rel}\n{description}\n{len(data)}\n".encode())
        h.update(data)
    identity: dict[str, object] = {
        "format": CONTENT_FORMAT,
        "content_sha256": h.hexdigest(),
        "files": len(files),
    }
    if manifest_sha is not None:
        with contextlib.suppress(OSError):  # a read-only dataset: computed again next time
            atomic_write_text(
                cache, json.dumps({**identity, "manifest_sha256": manifest_sha}, indent=1) + "\n"
            )
    return identity
