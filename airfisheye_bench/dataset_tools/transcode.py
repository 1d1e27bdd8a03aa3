"""Rewrite a dataset root into a new root with other per-frame file encodings (e.g. PNG -> JPEG + ``.npy``).

Decoding the RGB and depth cube faces of a sample (512^2, one core) costs ~31 ms from PNG and ~7 ms from RGB JPEG
with ``.npy`` depth (``docs/benchmarks.md``), so a PNG release converted once loads several times faster. RGB and
depth files (cube faces and pre-rendered fisheye, found through the ``layout`` templates of ``dataset.yaml``) are
decoded and re-encoded. Every other file (labels, LiDAR, visibility, calibration, poses, IMU, splits, anything else),
and RGB / depth files already in the target encoding, are hard-linked when ``link`` is true and the file system
allows it, else copied. ``dataset.yaml`` is rewritten with the new ``files`` encodings, and ``manifest.json`` is
recomputed when the source has one.

Depth: ``png16`` -> ``npy`` / ``pfm`` is lossless after decoding (the float32 values the reader returns), and
``npy`` -> ``png16`` gives the original 16-bit values back (``depth_scale`` is kept); other float depth written as
``png16`` is quantised to ``1 / depth_scale`` m. RGB to ``jpg`` is lossy (4:4:4 chroma, ``jpeg_quality``). Float
depth takes more disk than 16-bit PNG (4 bytes a pixel, uncompressed).

The new root is built in a hidden sibling folder (``.<dst name>.partial-<hex>``) and renamed to ``dst`` at the
end: ``dst`` either does not exist or is complete. Hard-linked files share their data with ``src``; the writers of
this project replace files atomically (new inode), so they never change the other root, but a tool that edits a
file in place would change both.

Command line (:func:`airfisheye_bench.cli.commands.transcode`; ``--help`` lists the options)::

    airfisheye-transcode src=/data/AirFisheye dst=/data/AirFisheye-jpg \\
        [rgb=jpg|png] [depth=npy|png16|pfm] [jpeg_quality=95] [workers=N] [link=true|false]

Example:
    >>> report = transcode_dataset("/data/afb-tiny", "/data/afb-tiny-jpg", workers=2)  # doctest: +SKIP
    >>> print(report.summary())                                                       # doctest: +SKIP
    /data/afb-tiny -> /data/afb-tiny-jpg: 144 files transcoded (472.0 KB -> 985.0 KB), 108 linked, 0 copied
"""

from __future__ import annotations

import fnmatch
import multiprocessing as mp
import os
import re
import shutil
import string
import uuid
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from airfisheye_bench.atomic import TEMP_GLOB
from airfisheye_bench.errors import OutputExistsError
from airfisheye_bench.io import codecs
from airfisheye_bench.io.dataset_spec import DATASET_YAML, DEPTH_ENCODINGS, RGB_ENCODINGS, FileEncodings
from airfisheye_bench.io.datasets.airfisheye import DatasetReader
from airfisheye_bench.io.layout import MANIFEST_NAME
from airfisheye_bench.io.manifest import create_manifest

#: Layout templates whose files carry a ``{modality}`` and an ``{ext}`` (the ones that can be re-encoded).
_ENCODED_TEMPLATES = ("cubemap", "fisheye")
#: Files that are never carried over: generator state and journal (the manifest and temporaries are also skipped).
_SKIPPED_PREFIX = ".airfisheye-"


@dataclass
class TranscodeReport:
    """What :func:`transcode_dataset` did.

    Attributes:
        src: The source root.
        dst: The new root.
        transcoded: RGB and depth files decoded and re-encoded.
        linked: Files hard-linked from ``src``.
        copied: Files copied unchanged (``link=False``, or a file system without hard links).
        bytes_before: Total size of the transcoded files in ``src``.
        bytes_after: Total size of the transcoded files in ``dst``.
    """

    src: Path
    dst: Path
    transcoded: int = 0
    linked: int = 0
    copied: int = 0
    bytes_before: int = 0
    bytes_after: int = 0

    def summary(self) -> str:
        """One line: counts and the size of the transcoded files before and after."""
        return (
            f"{self.src} -> {self.dst}: {self.transcoded} files transcoded "
            f"({_human(self.bytes_before)} -> {_human(self.bytes_after)}), "
            f"{self.linked} linked, {self.copied} copied"
        )


@dataclass(frozen=True)
class _Job:
    """One file to re-encode (paths as strings: jobs travel to worker processes)."""

    src: str
    dst: str
    modality: str  # "rgb" or "depth"
    suffix: str  # target suffix with the dot: ".jpg", ".png", ".npy", ".pfm"
    depth_scale: float
    jpeg_quality: int


def transcode_dataset(
    src: str | Path,
    dst: str | Path,
    rgb: str = "jpg",
    depth: str = "npy",
    jpeg_quality: int = 95,
    workers: int = 1,
    link: bool = True,
) -> TranscodeReport:
    """Write a copy of the dataset root ``src`` to ``dst`` with RGB and depth files in other encodings.

    Args:
        src: Source dataset root (holds ``dataset.yaml``).
        dst: New root; must not exist, and must not be ``src`` or lie inside it. Missing parent folders are
            created.
        rgb: RGB encoding of ``dst``: ``jpg`` or ``png``.
        depth: Depth encoding of ``dst``: ``npy``, ``png16`` or ``pfm`` (``png16`` keeps ``depth_scale``).
        jpeg_quality: JPEG quality (1-100, 4:4:4 chroma) when RGB is re-encoded to ``jpg``; RGB files that already
            are JPEG are carried over unchanged.
        workers: Processes that encode files; ``1`` runs in this process. The output does not depend on it.
        link: Hard-link the files that are not re-encoded (fall back to copying where the file system refuses);
            ``False`` copies them.

    Returns:
        What was done (:class:`TranscodeReport`).

    Raises:
        DatasetFormatError: ``src`` has no valid ``dataset.yaml``, or a source file cannot be decoded (the
            message names the file).
        FileExistsError: ``dst`` exists.
        ValueError: Invalid arguments, or ``dst`` is ``src`` or inside it.
    """
    if rgb not in RGB_ENCODINGS:
        raise ValueError(f"rgb must be one of {list(RGB_ENCODINGS)}, got {rgb!r}")
    if depth not in DEPTH_ENCODINGS:
        raise ValueError(f"depth must be one of {list(DEPTH_ENCODINGS)}, got {depth!r}")
    if isinstance(jpeg_quality, bool) or not isinstance(jpeg_quality, int) or not 1 <= jpeg_quality <= 100:
        raise ValueError(f"jpeg_quality must be an integer in [1, 100], got {jpeg_quality!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    src, dst = Path(src), Path(dst)
    spec = DatasetReader(src).spec  # validates src and its dataset.yaml (errors name the file and key)
    _check_destination(src, dst)

    old = spec.files
    new = FileEncodings(rgb=rgb, seg=old.seg, depth=depth, depth_scale=old.depth_scale)
    patterns = [_template_regex(spec.layout[name]) for name in _ENCODED_TEMPLATES]
    report = TranscodeReport(src, dst)
    jobs: list[_Job] = []
    others: list[tuple[Path, Path]] = []  # carried over as they are: linked or copied

    tmp = dst.parent / f".{dst.name}.partial-{uuid.uuid4().hex[:12]}"
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp.mkdir()
    try:
        written: dict[str, str] = {}  # output path -> the source file it comes from
        for rel in _source_files(src):
            target = _classify(rel, patterns, spec.layout, old, new)
            rel_out = rel if target is None else target[1]
            if rel_out in written:  # e.g. a stray 000.jpg next to 000.png when transcoding to jpg
                raise ValueError(
                    f"{src / written[rel_out]} and {src / rel} would both be written to {rel_out!r} in dst; "
                    "remove one of them from src"
                )
            written[rel_out] = rel
            if target is None or rel_out == rel:
                others.append((src / rel, tmp / rel))
            else:
                suffix = "." + new.extension(target[0])
                jobs.append(
                    _Job(str(src / rel), str(tmp / rel_out), target[0], suffix, new.depth_scale, jpeg_quality)
                )

        for before, after in _run_jobs(jobs, workers):
            report.transcoded += 1
            report.bytes_before += before
            report.bytes_after += after
        for a, b in others:
            b.parent.mkdir(parents=True, exist_ok=True)
            if link and _hard_link(a, b):
                report.linked += 1
            else:
                shutil.copy2(a, b)
                report.copied += 1

        note = f"(transcoded from rgb {old.rgb} / depth {old.depth})"
        description = f"{spec.description} {note}" if spec.description else note
        spec.with_updates(files=new, description=description).save(tmp / DATASET_YAML)
        if (src / MANIFEST_NAME).is_file():
            create_manifest(tmp)
        if os.path.lexists(dst):
            raise OutputExistsError(f"dst {str(dst)!r} appeared while transcoding; the result was discarded")
        os.replace(tmp, dst)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return report


# ----------------------------------------------------------------------------------------------- helpers
def _check_destination(src: Path, dst: Path) -> None:
    src_real, dst_real = src.resolve(), dst.resolve()
    if dst_real == src_real:
        raise ValueError(f"dst {str(dst)!r} is the source root {str(src)!r}; choose a new folder")
    if src_real in dst_real.parents:
        raise ValueError(
            f"dst {str(dst)!r} lies inside the source root {str(src)!r}; choose a folder outside it"
        )
    if os.path.lexists(dst):
        raise OutputExistsError(
            f"dst {str(dst)!r} already exists; choose a new folder (it is never overwritten)"
        )


def _source_files(src: Path) -> list[str]:
    """Relative POSIX paths of the files to carry over, sorted (``dataset.yaml`` is written anew)."""
    out = []
    for folder, dirs, names in os.walk(src):
        dirs.sort()
        for name in names:
            rel = (Path(folder) / name).relative_to(src).as_posix()
            if (
                rel in (DATASET_YAML, MANIFEST_NAME)
                or name.startswith(_SKIPPED_PREFIX)
                or fnmatch.fnmatchcase(name, TEMP_GLOB)
            ):
                continue
            out.append(rel)
    return sorted(out)


def _template_regex(template: str) -> re.Pattern:
    """``{env}/{traj}/fisheye/{modality}/{frame}.{ext}`` -> a regex with one named group per placeholder.

    Literal parts are escaped; a placeholder used twice must match the same text twice. ``ext`` holds no dot, the
    others no ``/``.
    """
    parts, seen = [], set()
    for literal, name, _, _ in string.Formatter().parse(template):
        parts.append(re.escape(literal))
        if not name:
            continue
        if name in seen:
            parts.append(f"(?P={name})")
        else:
            seen.add(name)
            parts.append(f"(?P<{name}>[^/.]+)" if name == "ext" else f"(?P<{name}>[^/]+)")
    return re.compile("".join(parts))


def _classify(
    rel: str, patterns: list[re.Pattern], layout: dict[str, str], old: FileEncodings, new: FileEncodings
) -> tuple[str, str] | None:
    """``(modality, new relative path)`` of an RGB or depth file in the source encoding, else ``None``."""
    for name, pattern in zip(_ENCODED_TEMPLATES, patterns, strict=True):
        match = pattern.fullmatch(rel)
        if match is None:
            continue
        fields = match.groupdict()
        modality = fields.get("modality")
        if modality not in ("rgb", "depth") or fields.get("ext") != old.extension(modality):
            continue
        fields["ext"] = new.extension(modality)
        return modality, layout[name].format(**fields)
    return None


def _hard_link(a: Path, b: Path) -> bool:
    try:
        os.link(a, b)
    except OSError:  # another file system, or one without hard links
        return False
    return True


def _run_jobs(jobs: list[_Job], workers: int) -> list[tuple[int, int]]:
    """``(bytes before, bytes after)`` per job, in job order; chunks go to ``workers`` processes."""
    workers = min(workers, len(jobs))
    if workers <= 1:
        return _encode_chunk(jobs)
    size = max(1, -(-len(jobs) // (workers * 4)))  # ~4 chunks per worker: balanced, little overhead
    chunks = [jobs[i : i + size] for i in range(0, len(jobs), size)]
    out: list[tuple[int, int]] = []
    # spawn: no fork of a process that already runs torch / OpenMP threads.
    with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
        futures = [pool.submit(_encode_chunk, chunk) for chunk in chunks]
        try:
            for future in futures:
                out += future.result()
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)  # no worker writes while the caller cleans up
            raise
    return out


def _encode_chunk(jobs: list[_Job]) -> list[tuple[int, int]]:
    return [_encode_file(job) for job in jobs]


def _encode_file(job: _Job) -> tuple[int, int]:
    """Decode ``job.src``, write it encoded as ``job.suffix`` to ``job.dst``; returns both sizes in bytes."""
    src, dst = Path(job.src), Path(job.dst)
    if job.modality == "rgb":
        data = codecs.encode_rgb(codecs.read_rgb(src), job.suffix, job.jpeg_quality)
    else:
        data = codecs.encode_depth(codecs.read_depth(src, scale=job.depth_scale), job.suffix, job.depth_scale)
    dst.parent.mkdir(parents=True, exist_ok=True)
    dst.write_bytes(data)
    return src.stat().st_size, len(data)


def _human(n: int) -> str:
    if n < 1000:
        return f"{n} B"
    size = n / 1000
    for unit in ("KB", "MB"):
        if size < 1000:
            return f"{size:.1f} {unit}"
        size /= 1000
    return f"{size:.1f} GB"
