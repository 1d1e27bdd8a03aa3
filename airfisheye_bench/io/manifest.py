"""File checksums, dataset manifests (per-file SHA-256 and size), and :func:`verify` to check a dataset against them.

``manifest.json`` lives at the dataset root and lists every file of the dataset except itself and the preview
``contact_sheet.png`` (relative POSIX paths, sorted), so it is deterministic and two identical datasets have
identical manifests::

    {"format": "airfisheye-manifest/1", "algorithm": "sha256",
     "files": {"dataset.yaml": {"sha256": "...", "bytes": 1234}, ...}}

It works for any release in the layout, not only generated ones (:func:`create_manifest`).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

from airfisheye_bench.atomic import TEMP_GLOB, atomic_write_text
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.layout import CONTACT_SHEET_NAME, MANIFEST_NAME
from airfisheye_bench.io.progress_report import track

MANIFEST_FORMAT = "airfisheye-manifest/1"
#: Files that never belong in a manifest: the manifest, the contact sheet, generator state and temporaries.
_EXCLUDED_PREFIXES = (".airfisheye-",)


@dataclass(frozen=True)
class FileEntry:
    """Checksum and size of one file."""

    sha256: str
    bytes: int


def sha256_bytes(data: bytes) -> str:
    """Hex SHA-256 of ``data``.

    Example:
        >>> sha256_bytes(b"abc")[:16]
        'ba7816bf8f01cfea'
    """
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | Path, chunk_size: int = 1 << 20) -> str:
    """Hex SHA-256 of a file, read in ``chunk_size``-byte blocks (checkpoints are hundreds of MB).

    The one file checksum of the project: dataset manifests, and the checkpoint, weights and prediction files that
    results and exported models name.

    Example:
        >>> import tempfile
        >>> path = Path(tempfile.mkdtemp()) / "x.bin"
        >>> _ = path.write_bytes(b"abc")
        >>> sha256_file(path) == sha256_bytes(b"abc")
        True
    """
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk_size):
            h.update(block)
    return h.hexdigest()


def is_manifest_candidate(relpath: str) -> bool:
    """Whether a file (relative POSIX path) belongs in the manifest."""
    name = relpath.rsplit("/", 1)[-1]
    return (
        relpath not in (MANIFEST_NAME, CONTACT_SHEET_NAME)
        and not name.startswith(_EXCLUDED_PREFIXES)
        and not Path(name).match(TEMP_GLOB)
    )


def dataset_files(root: str | Path) -> list[str]:
    """All manifest candidates under ``root`` as sorted relative POSIX paths."""
    root = Path(root)
    rels = (p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file())
    return sorted(r for r in rels if is_manifest_candidate(r))


def write_manifest(root: str | Path, files: dict[str, FileEntry]) -> Path:
    """Atomically write ``root/manifest.json`` for ``files`` (relative path -> entry)."""
    root = Path(root)
    body = {
        "format": MANIFEST_FORMAT,
        "algorithm": "sha256",
        "files": {k: {"sha256": files[k].sha256, "bytes": int(files[k].bytes)} for k in sorted(files)},
    }
    path = root / MANIFEST_NAME
    atomic_write_text(path, json.dumps(body, indent=1, sort_keys=False) + "\n")
    return path


def read_manifest(root: str | Path) -> dict[str, FileEntry]:
    """Read ``root/manifest.json``; errors name the file."""
    path = Path(root) / MANIFEST_NAME
    try:
        body = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DatasetFormatError(path, "file does not exist (not a complete dataset?)") from None
    except json.JSONDecodeError as exc:
        raise DatasetFormatError(path, f"invalid JSON ({exc})") from None
    if (
        not isinstance(body, dict)
        or body.get("format") != MANIFEST_FORMAT
        or not isinstance(body.get("files"), dict)
    ):
        raise DatasetFormatError(path, f"not an {MANIFEST_FORMAT} manifest", key="format")
    out = {}
    for rel, entry in body["files"].items():
        try:
            out[rel] = FileEntry(str(entry["sha256"]), int(entry["bytes"]))
        except (KeyError, TypeError, ValueError):
            raise DatasetFormatError(path, "entry must have sha256 and bytes", key=f"files.{rel}") from None
    return out


def create_manifest(root: str | Path) -> Path:
    """Checksum every file under ``root`` and write ``manifest.json`` (for a dataset made by other means)."""
    root = Path(root)
    files = {
        rel: FileEntry(sha256_file(root / rel), (root / rel).stat().st_size) for rel in dataset_files(root)
    }
    return write_manifest(root, files)


@dataclass
class VerifyReport:
    """Outcome of :func:`verify`.

    Attributes:
        checked: Number of files compared.
        missing: Files in the manifest but not on disk.
        corrupted: Files whose size or checksum differs.
        unexpected: Files on disk that the manifest does not list.
    """

    checked: int = 0
    missing: list[str] = field(default_factory=list)
    corrupted: list[str] = field(default_factory=list)
    unexpected: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not (self.missing or self.corrupted or self.unexpected)

    def summary(self, limit: int = 10) -> str:
        """Human-readable result listing up to ``limit`` problem files per kind."""
        if self.ok:
            return f"OK: {self.checked} files match the manifest"
        lines = [f"FAILED: {self.checked} files checked"]
        for name in ("missing", "corrupted", "unexpected"):
            items = getattr(self, name)
            if items:
                more = f" (+{len(items) - limit} more)" if len(items) > limit else ""
                lines.append(f"  {name} ({len(items)}): {', '.join(items[:limit])}{more}")
        return "\n".join(lines)


def verify(root: str | Path, check_unexpected: bool = True, progress: bool = False) -> VerifyReport:
    """Check every file of a dataset against its ``manifest.json``.

    Args:
        root: Dataset root.
        check_unexpected: Also report files that the manifest does not list.
        progress: Show a progress bar.

    Example:
        >>> import tempfile, pathlib
        >>> root = pathlib.Path(tempfile.mkdtemp()); (root / "a.txt").write_text("x")
        1
        >>> _ = create_manifest(root); verify(root).ok
        True
        >>> (root / "a.txt").write_text("y"); verify(root).corrupted
        1
        ['a.txt']
    """
    root = Path(root)
    entries = read_manifest(root)
    report = VerifyReport()
    for rel, entry in track(sorted(entries.items()), len(entries), "verify", "file", progress):
        path = root / rel
        report.checked += 1
        if not path.is_file():
            report.missing.append(rel)
        elif path.stat().st_size != entry.bytes or sha256_file(path) != entry.sha256:
            report.corrupted.append(rel)
    if check_unexpected:
        report.unexpected = [rel for rel in dataset_files(root) if rel not in entries]
    return report
