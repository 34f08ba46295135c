"""The PNG encoder (vcprep.io.png): every file it writes decodes, in OpenCV's libpng reader, to
exactly the array it was given."""
from __future__ import annotations

import zlib

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vcprep.io import png
from vcprep.errors import InputError
from vcprep.io import PNG_KINDS, write_png
from vcprep.io import encode_png


def _decode(data: bytes) -> np.ndarray:
    out = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    assert out is not None, "libpng rejected the file"
    return out


SHAPES = [(1, 1), (1, 7), (9, 1), (35, 68), (35, 68, 1), (35, 68, 3), (35, 68, 4), (1, 1, 3)]


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("filt", ["none", "sub"])
def test_round_trip_through_libpng(shape, dtype, filt):
    rng = np.random.default_rng(hash((shape, filt)) & 0xFFFF)
    a = rng.integers(0, np.iinfo(dtype).max + 1, shape, dtype=dtype)
    for level in range(4):
        out = _decode(encode_png(a, filt, level))
        assert out.dtype == dtype and np.array_equal(out.reshape(a.shape), a), (shape, dtype, filt, level)


@settings(max_examples=60, deadline=None)
@given(h=st.integers(1, 40), w=st.integers(1, 40), ch=st.sampled_from([1, 3, 4]), sixteen=st.booleans(),
       filt=st.sampled_from(sorted(png.FILTERS)), seed=st.integers(0, 2 ** 31 - 1))
def test_round_trip_property(h, w, ch, sixteen, filt, seed):
    dtype = np.uint16 if sixteen else np.uint8
    a = np.random.default_rng(seed).integers(0, np.iinfo(dtype).max + 1, (h, w, ch), dtype=dtype)
    out = _decode(encode_png(a, filt, 1))
    assert np.array_equal(out.reshape(h, w, ch), a)


def test_views_are_encoded_as_their_values():
    a = np.random.default_rng(1).integers(0, 256, (30, 40, 4), dtype=np.uint8)
    for view in (a[::2, 1::3, :3], a[5:20, ::-1, 1], a[..., :3].transpose(1, 0, 2)):
        assert np.array_equal(_decode(encode_png(view)).reshape(view.shape), view)


def test_colour_order_is_opencvs(tmp_path):
    """BGR in, BGR out of cv2.imread; and the file really stores RGB (a pure-blue BGR pixel is
    (0, 0, 255) in the PNG's first row)."""
    a = np.zeros((2, 3, 3), np.uint8)
    a[..., 0] = 255  # blue
    data = encode_png(a)
    assert np.array_equal(_decode(data), a)
    idat = data.index(b"IDAT")
    n = int.from_bytes(data[idat - 4:idat], "big")
    raw = zlib.decompress(data[idat + 4:idat + 4 + n])
    assert raw[:1 + 9] == bytes([0, 0, 0, 255, 0, 0, 255, 0, 0, 255])


def test_compresses_and_the_stream_is_zlibs_a_function_of_the_pixels():
    """Structured content compresses (a smooth gradient: far below raw size), and the IDAT is
    exactly the standard library's zlib stream of the filtered rows: the same pixels give the same
    bytes in every process, which byte-identical store builds rest on (ISA-L's stream depended on
    the process's memory layout: issue 61, vcprep.io.png)."""
    y, x = np.mgrid[0:200, 0:300]
    a = np.dstack([(x + y) % 256, (2 * x) % 256, (y // 3) % 256]).astype(np.uint8)
    assert len(encode_png(a, "sub", 2)) < a.nbytes / 10
    for filt in png.FILTERS:
        for level in (1, 2, 6):
            data = encode_png(a, filt, level)
            idat = data.index(b"IDAT")
            stream = data[idat + 4:idat + 4 + int.from_bytes(data[idat - 4:idat], "big")]
            assert stream == zlib.compress(zlib.decompress(stream), level)
            assert np.array_equal(_decode(data), a)


@pytest.mark.parametrize("arr, needle", [
    (np.zeros((4, 4), np.float32), "8- or 16-bit"),
    (np.zeros((4, 4, 2), np.uint8), "grey, BGR or BGRA"),
    (np.zeros((0, 4), np.uint8), "cannot hold"),
    (np.zeros(4, np.uint8), "grey, BGR or BGRA"),
])
def test_bad_arrays_are_refused(arr, needle, tmp_path):
    with pytest.raises(ValueError, match=needle):
        encode_png(arr)
    with pytest.raises(InputError, match="cannot encode PNG") as e:
        write_png(tmp_path / "x.png", arr)
    assert "x.png" in str(e.value)
    assert not list(tmp_path.iterdir())  # nothing written
    with pytest.raises(ValueError, match="unknown PNG filter"):
        encode_png(np.zeros((2, 2), np.uint8), "paeth")


def test_write_png_kinds_and_hash(tmp_path):
    import hashlib

    a = np.random.default_rng(0).integers(0, 256, (20, 30, 3), dtype=np.uint8)
    for kind in PNG_KINDS:
        p = tmp_path / f"{kind}.png"
        sha = write_png(p, a, kind=kind)
        assert sha == hashlib.sha256(p.read_bytes()).hexdigest()
        assert np.array_equal(cv2.imread(str(p), cv2.IMREAD_UNCHANGED), a)
