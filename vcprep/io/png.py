"""PNG encoding, deterministic: the same pixels give the same bytes in every process.

Building a store spends much of its time compressing PNGs, and a store is byte-identical however it
is built (one process, ``--jobs N``, shards, a killed build resumed): ``files_sha256``, ``store
verify`` and ``content.stamp`` rest on it. The PNG container is written directly (signature,
IHDR, one IDAT, IEND; PNG specification, ISO/IEC 15948) and deflated with libdeflate (PyPI
``deflate``, pinned in pyproject.toml): one call on the whole buffer, no state kept between calls,
and its stream is a function of the bytes, the level and the libdeflate version alone (its author:
no version has ever been non-deterministic; the output changes between versions, hence the pin).

Not ISA-L (``python-isal``): its stream depended on the process, not only on the bytes (the same
704 bytes at level 2 gave another LZ77 parse in 6 of 3000 fresh processes, never with address-space
randomisation off; two builds of one store then differed in a file about once in 100; issue 61).
Not zlib-ng either: faster only at a larger size (level 1: 282 KB for a store image), and its
matcher has read stale window bytes that changed the stream (zlib-ng issue 2100, 2026, since
fixed). Not the standard library's zlib (the writer of issues 61-68): deterministic but 2-5x slower.
benchmarks/speed/png_deflate.py measures them all on a store's content and checks the bytes in
fresh processes with a dirtied heap. On our 2-core machine, CamVid, a 688x350 store image:
libdeflate level 1 2.9 ms and 213 KB; zlib level 2 221 KB and 6.8 ms on a quiet machine (issue 69),
14.5 ms in that benchmark's run (load 13, where libdeflate kept its 2.9 ms); ISA-L (before issue 61)
2.3 ms and 241 KB.

Any PNG reader (OpenCV, Pillow, browsers) reads the files. Supported: uint8 and uint16, grey
(H, W) or (H, W, 1), BGR and BGRA (OpenCV order, stored as RGB and RGBA), per-row filter 'none',
'sub' or 'up' (the same filter on every row). ``level`` is libdeflate's level, 0-12 (0: stored).
"""
from __future__ import annotations

import struct

import cv2
import deflate
import numpy as np

DEFLATE = "libdeflate"  # deterministic (the module docstring says why not ISA-L, zlib-ng or zlib)
MAX_LEVEL = 12

__all__ = ["encode_png", "filtered_rows", "png_file", "DEFLATE", "FILTERS"]

SIGNATURE = b"\x89PNG\r\n\x1a\n"
FILTERS = {"none": 0, "sub": 1, "up": 2}  # PNG filter type byte of each row
_COLOUR_TYPE = {1: 0, 3: 2, 4: 6}  # channels -> grey, RGB, RGBA
_TO_RGB = {3: cv2.COLOR_BGR2RGB, 4: cv2.COLOR_BGRA2RGBA}  # OpenCV's channel order -> PNG's


def _chunk(kind: bytes, data) -> list:
    """The parts of one chunk: length, type, data, CRC-32 of type + data."""
    return [struct.pack(">I", len(data)), kind, data, struct.pack(">I", deflate.crc32(data, deflate.crc32(kind)))]


def encode_png(array: np.ndarray, filter: str = "none", level: int = 1) -> bytes:
    """The PNG file bytes of ``array`` (see the module doc). Raises ValueError for an array PNG
    cannot hold (dtype, shape, empty) or an unknown filter."""
    ihdr, raw = filtered_rows(array, filter)
    return png_file(ihdr, deflate.zlib_compress(raw, max(0, min(int(level), MAX_LEVEL))))


def png_file(ihdr: bytes, idat) -> bytes:
    """The PNG file of an IHDR payload and a zlib stream of the filtered rows."""
    return b"".join([SIGNATURE, *_chunk(b"IHDR", ihdr), *_chunk(b"IDAT", idat), *_chunk(b"IEND", b"")])


def filtered_rows(array: np.ndarray, filter: str = "none") -> tuple[bytes, np.ndarray]:
    """The IHDR payload of ``array`` and its rows as PNG stores them before deflate (colour order,
    byte order, each row's filter byte, then the filtered bytes), (H, 1 + W * bytes per pixel)
    uint8. Raises ValueError as :func:`encode_png`."""
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
    depth = a.dtype.itemsize * 8
    bpp = ch * a.dtype.itemsize  # bytes per pixel
    raw = np.empty((h, 1 + w * bpp), dtype=np.uint8)
    raw[:, 0] = FILTERS[filter]
    px = raw[:, 1:]
    if ch in _TO_RGB and depth == 8:  # reordered straight into the rows (a strided numpy copy is ~25x slower)
        out = cv2.cvtColor(a, _TO_RGB[ch], dst=px.reshape(h, w, ch))
        if not np.shares_memory(out, raw):  # (an OpenCV that allocated instead of writing into the rows)
            px[...] = out.reshape(h, w * bpp)
    else:
        if ch in _TO_RGB:
            a = cv2.cvtColor(a, _TO_RGB[ch])
        if depth == 16:  # network byte order
            a = a.astype(">u2")
        px[...] = a.view(np.uint8).reshape(h, w * bpp)
    if filter == "sub":  # each byte minus the same byte of the pixel to its left (mod 256)
        left = px[:, :-bpp].copy()
        px[:, bpp:] -= left
    elif filter == "up":  # each byte minus the same byte of the row above (mod 256)
        px[1:] -= px[:-1].copy()
    return struct.pack(">IIBBBBB", w, h, depth, _COLOUR_TYPE[ch], 0, 0, 0), raw
