"""The PNG encoder (vcprep.io.png): every file it writes decodes, in OpenCV's libpng reader, to
exactly the array it was given, and its bytes are a function of the pixels (libdeflate's stream;
the same in fresh processes)."""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import zlib
from pathlib import Path

import deflate

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
@pytest.mark.parametrize("filt", sorted(png.FILTERS))
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
    raw = zlib.decompress(_idat(data))
    assert raw[:1 + 9] == bytes([0, 0, 0, 255, 0, 0, 255, 0, 0, 255])


def _idat(data: bytes) -> bytes:
    idat = data.index(b"IDAT")
    return data[idat + 4:idat + 4 + int.from_bytes(data[idat - 4:idat], "big")]


def test_compresses_and_the_stream_is_libdeflates_a_function_of_the_pixels():
    """Structured content compresses (a smooth gradient: far below raw size), and the IDAT is
    exactly libdeflate's zlib stream of the filtered rows at the level asked (decoded by the
    standard library's zlib, an independent inflater): the same pixels give the same bytes in every
    process, which byte-identical store builds rest on (ISA-L's stream depended on the process's
    memory layout: issue 61, vcprep.io.png)."""
    y, x = np.mgrid[0:200, 0:300]
    a = np.dstack([(x + y) % 256, (2 * x) % 256, (y // 3) % 256]).astype(np.uint8)
    assert len(encode_png(a, "sub", 1)) < a.nbytes / 10
    for filt in png.FILTERS:
        for level in (0, 1, 2, 6, 12):
            data = encode_png(a, filt, level)
            stream = _idat(data)
            assert stream == deflate.zlib_compress(zlib.decompress(stream), level)
            assert np.array_equal(_decode(data), a)


def _scene() -> dict[str, np.ndarray]:
    """Store-like content: a rendered road (BGR), its label, the same in 16 bits and with alpha."""
    from vcprep.camera import PRESETS
    from vcprep.synthetic import RoadScene, render_road

    img, road = render_road(PRESETS["camvid"].for_image_size((160, 120)), RoadScene(texture_seed=3), supersample=1)
    return {"bgr": img, "grey": road * 255, "grey16": img[..., 1].astype(np.uint16) * 257,
            "bgra16": np.dstack([img, road * 255]).astype(np.uint16) * 255}


# a fresh interpreter with a dirtied heap (random-size buffers of random bytes allocated, some freed)
# encodes the scene with every kind's settings and prints the SHA-256 of each file
_CHILD = """
import hashlib, json, os, random, sys
rnd = random.Random(int(sys.argv[1]))
keep = [bytearray(os.urandom(rnd.randrange(1, 1 << 20))) for _ in range(rnd.randrange(5, 30))][::2]
sys.path.insert(0, sys.argv[2])
from test_png import _scene
from vcprep.io import PNG_KINDS, encode_png
print(json.dumps({f"{k} {kind}": hashlib.sha256(encode_png(a, *PNG_KINDS[kind])).hexdigest()
                  for k, a in _scene().items() for kind in PNG_KINDS}))
"""


def test_two_processes_write_the_same_bytes():
    """Grey, BGR and 16-bit content with every kind's settings: two fresh processes (different heap
    contents, environment sizes, address-space layouts) write the bytes this one writes, and they
    decode to the pixels. (ISA-L differed in ~1 process of 500-3000, which no test of a few processes
    sees; benchmarks/speed/png_deflate.py runs hundreds.)"""
    mine = {f"{k} {kind}": hashlib.sha256(encode_png(a, *PNG_KINDS[kind])).hexdigest()
            for k, a in _scene().items() for kind in PNG_KINDS}
    for seed in (1, 2):
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[1]), os.environ.get("PYTHONPATH", "")]),
               "PNG_TEST_PAD": "x" * 3001 * seed}
        out = subprocess.run([sys.executable, "-c", _CHILD, str(seed), str(Path(__file__).parent)], env=env,
                             capture_output=True, text=True, check=True).stdout
        assert json.loads(out) == mine


@pytest.mark.parametrize("name", ["bgr", "grey", "grey16", "bgra16"])
def test_written_files_read_back_exactly_with_cv2_imread(name, tmp_path):
    a = _scene()[name]
    for kind in PNG_KINDS:
        p = tmp_path / f"{name}-{kind}.png"
        write_png(p, a, kind=kind)
        back = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        assert back.dtype == a.dtype and np.array_equal(back, a), (name, kind)


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
