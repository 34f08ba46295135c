"""PNG encoding, deterministic: the same pixels give the same bytes in every process.

Building a store spends much of its time compressing PNGs, and a store is byte-identical however it
is built (one process, ``--jobs N``, shards, a killed build resumed): ``files_sha256``, ``store
verify`` and ``content.stamp`` rest on it. The PNG container is written directly (signature,
IHDR, one IDAT, IEND; PNG specification, ISO/IEC 15948) and deflated with the standard library's
zlib, whose stream is a function of the bytes, the level and the zlib version alone.

Not ISA-L (``python-isal``), although it deflates 3-6x faster at about the same size: its stream
depends on the process, not only on the bytes. The same 704 bytes compressed at level 2 in fresh
processes gave another stream (another LZ77 parse, the same pixels) in 6 of 3000 processes, never
with address-space randomisation off (``setarch -R``: 0 of 1300, stack offsets varied); its
streaming ``compressobj`` as well (1 in 3000); a 688x350 store image 2 in 3000 at level 1. Two
builds of one store then differ in a file about once in 100 (tests/test_camera_estimate.py,
tests/test_store_scale.py; issue 61). zlib level 2 on our 2-core machine, CamVid: a 688x350 store
image 6.8 ms and 220 KB (ISA-L 2.3 ms, 241 KB), a label 0.3 ms (0.05 ms), a 480x360 frame 8.6 ms
(2.6 ms).

Any PNG reader (OpenCV, Pillow, browsers) reads the files. Supported: uint8 and uint16, grey
(H, W) or (H, W, 1), BGR and BGRA (OpenCV order, stored as RGB and RGBA), per-row filter 'none' or
'sub' (the same filter on every row). ``level`` is the zlib deflate level, 0-9.
"""
from __future__ import annotations

import struct
import zlib

import cv2
import numpy as np

_deflate = zlib  # deterministic (the module docstring says why not ISA-L)
DEFLATE = "zlib"
MAX_LEVEL = 9

__all__ = ["encode_png", "DEFLATE", "FILTERS"]

SIGNATURE = b"\x89PNG\r\n\x1a\n"
FILTERS = {"none": 0, "sub": 1}  # PNG filter type byte of each row
_COLOUR_TYPE = {1: 0, 3: 2, 4: 6}  # channels -> grey, RGB, RGBA


def _chunk(kind: bytes, data) -> list:
    """The parts of one chunk: length, type, data, CRC-32 of type + data."""
    return [struct.pack(">I", len(data)), kind, data, struct.pack(">I", zlib.crc32(data, zlib.crc32(kind)))]


def encode_png(array: np.ndarray, filter: str = "none", level: int = 1) -> bytes:
    """The PNG file bytes of ``array`` (see the module doc). Raises ValueError for an array PNG
    cannot hold (dtype, shape, empty) or an unknown filter."""
    a = np.asarray(array)
    if a.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"PNG holds 8- or 16-bit integers, not {a.dtype}")
    ch = 1 if a.ndim == 2 else (a.shape[2] if a.ndim == 3 else 0)
    if ch not in _COLOUR_TYPE:
        raise ValueError(f"PNG holds grey, BGR or BGRA images, not shape {a.shape}")
    h, w = a.shape[:2]
    if not (0 < w < 2 ** 31 and 0 < h < 2 ** 31):
        raise ValueError(f"PNG cannot hold an image of shape {a.shape}")
    if filter not in FILTERS:
        raise ValueError(f"unknown PNG filter {filter!r}; use one of {', '.join(FILTERS)}")
    a = np.ascontiguousarray(a)  # (views, e.g. crops, are copied once)
    if ch == 3:
        a = cv2.cvtColor(a, cv2.COLOR_BGR2RGB)  # (a strided numpy copy is ~25x slower)
    elif ch == 4:
        a = cv2.cvtColor(a, cv2.COLOR_BGRA2RGBA)
    depth = a.dtype.itemsize * 8
    bpp = ch * a.dtype.itemsize  # bytes per pixel
    raw = np.empty((h, 1 + w * bpp), dtype=np.uint8)
    raw[:, 0] = FILTERS[filter]
    px = raw[:, 1:]
    if depth == 16:  # network byte order
        a = a.astype(">u2")
    px[...] = a.view(np.uint8).reshape(h, w * bpp)
    if filter == "sub":  # each byte minus the same byte of the pixel to its left (mod 256)
        left = px[:, :-bpp].copy()
        px[:, bpp:] -= left
    data = _deflate.compress(raw, min(int(level), MAX_LEVEL))
    ihdr = struct.pack(">IIBBBBB", w, h, depth, _COLOUR_TYPE[ch], 0, 0, 0)
    return b"".join([SIGNATURE, *_chunk(b"IHDR", ihdr), *_chunk(b"IDAT", data), *_chunk(b"IEND", b"")])
