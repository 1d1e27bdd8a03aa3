"""A dataset's content identity: independent of the encoder's bytes, sensitive to the data itself."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from airfisheye_bench.io.content import CONTENT_CACHE_NAME, content_identity, decoded_content
from airfisheye_bench.io.manifest import create_manifest, sha256_file

#: ``content_identity`` of ``airfisheye-generate preset=tiny seed=0``. It was the same for datasets generated here
#: with Pillow 10.4.0 and 13.0.0 and with torch's CPU kernels forced to ATEN_CPU_CAPABILITY=default and AVX512
#: (all four have identical files, manifest 87abfcb7). Change it only together with a deliberate change of the
#: generator's output (and regenerate the documented results that name it).
TINY_CONTENT_SHA256 = "58a2ef52d61733332523fca1951ad57e0ea7ab5fd0666f564a4a310c3d43519f"


def test_tiny_has_its_documented_content(tiny_dataset: Path) -> None:
    identity = content_identity(tiny_dataset, use_cache=False)
    assert identity["files"] == 253
    assert identity["content_sha256"] == TINY_CONTENT_SHA256, (
        "the generator's output for preset=tiny changed: if that is intended, update TINY_CONTENT_SHA256 and "
        "the results documented on the old data"
    )


@pytest.fixture
def tiny_copy(tiny_dataset: Path, tmp_path: Path) -> Path:
    root = tmp_path / "tiny"
    shutil.copytree(tiny_dataset, root)
    return root


def _some_png(root: Path, kind: str) -> Path:
    return sorted(root.rglob(f"fisheye/{kind}/*.png"))[0]


@pytest.mark.parametrize("kind", ["rgb", "depth", "seg"])
def test_reencoding_keeps_the_content_identity(tiny_copy: Path, kind: str) -> None:
    before = content_identity(tiny_copy, use_cache=False)
    manifest_before = sha256_file(tiny_copy / "manifest.json")
    path = _some_png(tiny_copy, kind)
    pixels = np.asarray(Image.open(path))
    old_bytes = path.read_bytes()
    Image.fromarray(pixels).save(path, compress_level=9)  # another zlib level: other bytes, same pixels
    assert path.read_bytes() != old_bytes
    create_manifest(tiny_copy)
    assert sha256_file(tiny_copy / "manifest.json") != manifest_before
    assert content_identity(tiny_copy, use_cache=False) == before


def test_a_changed_depth_changes_the_identity(tiny_copy: Path) -> None:
    before = content_identity(tiny_copy, use_cache=False)["content_sha256"]
    path = _some_png(tiny_copy, "depth")
    depth = np.asarray(Image.open(path)).copy()
    depth.flat[depth.size // 2] += 1  # 1/256 m at one pixel
    Image.fromarray(depth).save(path)
    assert content_identity(tiny_copy, use_cache=False)["content_sha256"] != before


def test_a_renamed_or_extra_file_changes_the_identity(tiny_copy: Path) -> None:
    before = content_identity(tiny_copy, use_cache=False)["content_sha256"]
    (tiny_copy / "splits" / "extra.txt").write_text("x\n")
    assert content_identity(tiny_copy, use_cache=False)["content_sha256"] != before


def test_the_cache_follows_the_manifest(tiny_copy: Path) -> None:
    first = content_identity(tiny_copy)
    assert (tiny_copy / CONTENT_CACHE_NAME).is_file()
    path = _some_png(tiny_copy, "seg")
    labels = np.asarray(Image.open(path)).copy()
    labels.flat[0] = (int(labels.flat[0]) + 1) % 20
    Image.fromarray(labels).save(path)
    assert content_identity(tiny_copy) == first  # manifest unchanged: the cached answer
    create_manifest(tiny_copy)
    assert content_identity(tiny_copy) != first  # a new manifest: hashed again


def test_structured_files_are_compared_parsed(tmp_path: Path) -> None:
    (tmp_path / "a.yaml").write_text("b: 1\na: [1, 2]\n")
    (tmp_path / "b.yaml").write_text("# a comment\na:\n- 1\n- 2\nb: 1\n")
    assert decoded_content(tmp_path / "a.yaml") == decoded_content(tmp_path / "b.yaml")
