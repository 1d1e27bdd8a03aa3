"""The LZF decompressor behind PCD ``DATA binary_compressed``: golden streams of liblzf itself, round trips through
a greedy compressor (tests/helpers/pcl_files.py), and one error per corrupt stream."""

from __future__ import annotations

import numpy as np
import pytest

from airfisheye_bench.io.lzf import lzf_decompress
from tests.helpers.pcl_files import lzf_compress

# liblzf 3.6's lzf_compress (as bundled by python-lzf 0.2.6: lzf.compress(data)), the reference encoder PCL's
# io/src/lzf.cpp derives from. The last one holds a long back-reference (0xe0 0xff: 264 bytes at offset 1).
GOLDEN = [
    (b"abcabcabcabc" * 3, b"\x03abca\xe0\x15\x02\x01bc"),
    (
        b"the quick brown fox jumps over the lazy dog; the quick brown fox",
        b"\x1fthe quick brown fox jumps over t \x1e\x08lazy dog;`\r\xe0\x04,\x01ox",
    ),
    (
        np.arange(8, dtype="<f4").repeat(6).tobytes() + bytes(300),
        b"\x01\x00\x00\xe0\x0f\x00\x01\x80?\xe0\r\x03\x01\x00@\xe0\r\x03\x00@ \x17\xe0\x0b\x03\x00\x80 \x17\xe0\x0b"
        b"\x03\x00\xa0 \x17\xe0\x0b\x03\x00\xc0 \x17\xe0\x0b\x03\x00\xe0 \x17\xe0\x0b\x03\xe0\xff\x00\xe0\x17\x00"
        b"\x01\x00\x00",
    ),
]


@pytest.mark.parametrize(("plain", "packed"), GOLDEN)
def test_liblzf_streams(plain: bytes, packed: bytes) -> None:
    assert lzf_decompress(packed, len(plain)) == plain


def test_round_trips() -> None:
    rng = np.random.default_rng(0)
    scan = rng.normal(0.0, 20.0, (3, 4000)).astype("<f4")  # a scan's x, y, z planes: few long matches
    cases = [
        b"",
        b"a",
        bytes(5000),  # one literal, then overlapping references 264 bytes long: deep copy chains
        rng.integers(0, 4, 20000, dtype=np.uint8).tobytes(),  # short matches everywhere
        rng.integers(0, 256, 3000, dtype=np.uint8).tobytes(),  # incompressible: literal runs of 32
        scan.tobytes() + np.repeat(np.arange(32, dtype="<u2"), 125).tobytes(),
        (b"0123456789" * 1000)[:9999],
    ]
    for plain in cases:
        packed = lzf_compress(plain)
        assert lzf_decompress(packed, len(plain)) == plain
    assert len(lzf_compress(bytes(5000))) < 100  # the compressor does compress: the references are exercised


@pytest.mark.parametrize(
    ("packed", "size", "message"),
    [
        (b"\x03abc", 4, "truncated"),  # a literal run of 4 with 3 bytes
        (b"\xe0\x01", 10, "truncated"),  # a long reference without its offset byte
        (b"\x00a\x20\x05", 4, "before the start"),  # offset 6 with one byte written
        (b"\x02abc", 5, "decodes to 3 bytes, expected 5"),
    ],
)
def test_a_corrupt_stream_is_one_error(packed: bytes, size: int, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        lzf_decompress(packed, size)
