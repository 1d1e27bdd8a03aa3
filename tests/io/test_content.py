"""A dataset's content identity: independent of the encoder's bytes, sensitive to the data itself."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

try:  # numpy's table of CPU features (numpy 2; numpy 1 kept it in numpy.core)
    from numpy._core import _multiarray_umath as _umath
except ImportError:  # pragma: no cover
    from numpy.core import _multiarray_umath as _umath

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


#: Generate ``tiny`` and print its content identity, in a process whose math libraries take their plainest paths.
_GENERATE_AND_IDENTIFY = """
import json, sys
from airfisheye_bench.io.content import content_identity
from airfisheye_bench.synth.writer import generate_dataset
print(json.dumps(content_identity(generate_dataset("tiny", sys.argv[1], workers=1, progress=False))))
"""


def _scalar_kernels_env() -> dict[str, str]:
    """Environment that turns off the CPU-specific vector kernels this machine would use: torch's (the default,
    unvectorised build of each operator), numpy's dispatched SIMD paths (down to its baseline) and MKL's
    CPU-dependent code paths."""
    env = dict(os.environ)
    env["ATEN_CPU_CAPABILITY"] = "default"
    env["NPY_DISABLE_CPU_FEATURES"] = " ".join(
        f for f in _umath.__cpu_dispatch__ if _umath.__cpu_features__.get(f)
    )
    env["MKL_CBWR"] = "COMPATIBLE"
    return env


def test_tiny_does_not_depend_on_the_cpus_vector_kernels(tmp_path: Path) -> None:
    """The same content with the vector kernels of this CPU turned off: the data must not depend on which SIMD
    path (AVX2, AVX-512, none) a machine's torch, numpy and MKL take."""
    out = subprocess.run(
        [sys.executable, "-c", _GENERATE_AND_IDENTIFY, str(tmp_path / "tiny")],
        env=_scalar_kernels_env(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    identity = json.loads(out.stdout.strip().splitlines()[-1])
    assert identity["content_sha256"] == TINY_CONTENT_SHA256


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
