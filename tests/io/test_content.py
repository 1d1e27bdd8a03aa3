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

#: ``content_identity`` of ``airfisheye-generate preset=tiny seed=0`` (generator version 2). Measured on an Intel Xeon
#: with AVX-512 (numpy 2.4.6, torch 2.14.1), with its vector kernels on and, in every combination tried, off
#: (``test_the_data_do_not_depend_on_the_cpus_vector_kernels``). Change it only together with a deliberate change of the
#: generator's output (and regenerate the documented results that name it).
TINY_CONTENT_SHA256 = "8b04c5ffd0972aa0f6ffa39f5403c430dbb133c857ee9fa64e8a30348148d20f"
#: ``synth.writer.sample_identity("quickstart")``: the metadata and first frame of each environment's first flight, on
#: the same machine; the quick-start record's data must agree with it on every machine.
QUICKSTART_SAMPLE_SHA256 = "b3f3195facad0ddaef8b1883bedc592f6a9a1ca7235cccabf2fd08bf0cd5b00b"


def test_tiny_has_its_documented_content(tiny_dataset: Path) -> None:
    identity = content_identity(tiny_dataset, use_cache=False)
    assert identity["files"] == 253
    assert identity["content_sha256"] == TINY_CONTENT_SHA256, (
        "the generator's output for preset=tiny changed: if that is intended, update TINY_CONTENT_SHA256 and "
        "the results documented on the old data"
    )


#: Generate ``tiny`` and the ``quickstart`` sample; print both identities, in the environment the test gives.
_GENERATE_AND_IDENTIFY = """
import json, sys
from airfisheye_bench.io.content import content_identity
from airfisheye_bench.synth.writer import generate_dataset, sample_identity
tiny = content_identity(generate_dataset("tiny", sys.argv[1], workers=1, progress=False))["content_sha256"]
quickstart = sample_identity("quickstart") if sys.argv[2] == "1" else None
print(json.dumps({"tiny": tiny, "quickstart": quickstart}))
"""


def _identities(tmp_path: Path, env: dict[str, str], quickstart: bool) -> dict[str, str | None]:
    out = subprocess.run(
        [sys.executable, "-c", _GENERATE_AND_IDENTIFY, str(tmp_path / "tiny"), "1" if quickstart else "0"],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def _numpy_levels() -> list[str]:
    """This CPU's numpy dispatch targets (e.g. ``X86_V3``, ``X86_V4``, ``AVX512_ICL``), lowest first."""
    return [f for f in _umath.__cpu_dispatch__ if _umath.__cpu_features__.get(f)]


def _scalar_kernels_env() -> dict[str, str]:
    """The CPU-specific vector kernels this machine would use, turned off: torch's (the default, unvectorised build
    of each operator), numpy's dispatched SIMD paths (down to its baseline) and MKL's CPU-dependent code paths (its
    compatible mode, close to the path it takes on AMD CPUs)."""
    return {
        "ATEN_CPU_CAPABILITY": "default",
        "NPY_DISABLE_CPU_FEATURES": " ".join(_numpy_levels()),
        "MKL_CBWR": "COMPATIBLE",
    }


@pytest.mark.integration
def test_tiny_does_not_depend_on_the_cpus_vector_kernels(tmp_path: Path) -> None:
    """The same content with the vector kernels of this CPU turned off: the data must not depend on which SIMD
    path (AVX2, AVX-512, none) a machine's torch, numpy and MKL take."""
    assert _identities(tmp_path, _scalar_kernels_env(), quickstart=False)["tiny"] == TINY_CONTENT_SHA256


@pytest.mark.slow
def test_the_data_do_not_depend_on_the_cpus_vector_kernels(tmp_path: Path) -> None:
    """``tiny`` and the ``quickstart`` sample under each numpy dispatch level this CPU offers (each level turned
    off in turn, from the highest), torch's default and AVX2 kernels and MKL's compatible mode: one identity each,
    the one named above (measured on an AVX-512 machine, so a machine without AVX-512 checks against it too)."""
    levels = _numpy_levels()
    envs = [{}] + [{"NPY_DISABLE_CPU_FEATURES": " ".join(levels[i:])} for i in reversed(range(len(levels)))]
    envs += [{"ATEN_CPU_CAPABILITY": "avx2", "MKL_CBWR": "AVX2"}, _scalar_kernels_env()]
    for i, env in enumerate(envs):
        identity = _identities(tmp_path / str(i), env, quickstart=True)
        assert identity == {"tiny": TINY_CONTENT_SHA256, "quickstart": QUICKSTART_SAMPLE_SHA256}, env


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
