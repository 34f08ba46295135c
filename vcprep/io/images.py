"""Reading and writing images safely: one read of the bytes (hashed and decoded), header checks
before any large allocation, clear errors for missing/empty/truncated/corrupt files, and atomic
PNG writes (temp file in the same directory + rename)."""
from __future__ import annotations

import hashlib
import os
import struct
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from .png import encode_png

__all__ = ["LoadedImage", "read_image", "image_size", "read_text", "write_png", "write_bytes_atomic", "IMAGE_EXTENSIONS", "MAX_PIXELS",
           "image_size_from_header"]

# we report every decoding problem ourselves, as one Error: line; OpenCV's own log would add noise
cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
MAX_PIXELS = 120_000_000  # > the 15.4 Mpx full virtual camera; refuses absurd headers before decoding


@dataclass(frozen=True)
class LoadedImage:
    path: Path
    array: np.ndarray
    sha256: str

    @property
    def size(self) -> tuple[int, int]:
        return int(self.array.shape[1]), int(self.array.shape[0])


def image_size_from_header(data: bytes) -> tuple[int, int] | None:
    """(w, h) from a PNG IHDR or JPEG SOF header, or None when it cannot be read cheaply."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24 and data[12:16] == b"IHDR":
        w, h = struct.unpack(">II", data[16:24])
        return int(w), int(h)
    if data[:2] == b"\xff\xd8":
        i = 2
        n = len(data)
        while i + 9 < n:
            if data[i] != 0xFF:
                i += 1
                continue
            marker = data[i + 1]
            if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
                i += 2
                continue
            seg_len = struct.unpack(">H", data[i + 2:i + 4])[0]
            if marker in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF):
                h, w = struct.unpack(">HH", data[i + 5:i + 9])
                return int(w), int(h)
            i += 2 + seg_len
    return None


def read_image(path: str | Path, *, label: bool = False, data: bytes | None = None) -> LoadedImage:
    """Read an image (or a label image with ``label=True``) exactly as stored (bit depth and
    channels kept; a 4th alpha channel of a photo is dropped). ``data``: the file's bytes when
    the caller has already read them (``path`` then only names it). Raises :class:`InputError`."""
    path = Path(path)
    kind = "label" if label else "image"
    try:
        if data is None:
            data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{kind} file not found", path, "check the path") from None
    except IsADirectoryError:
        raise InputError(f"is a directory, expected an {kind} file", path, "give a file") from None
    except OSError as e:
        raise InputError(f"cannot read {kind}: {e.strerror or e}", path, "check the file's permissions") from None
    if not data:
        raise InputError(f"{kind} file is empty", path, "re-export or remove the file")
    size = image_size_from_header(data)
    if size is not None and (size[0] * size[1] > MAX_PIXELS or min(size) <= 0):
        raise InputError(f"{kind} header says {size[0]}x{size[1]} pixels, beyond the {MAX_PIXELS // 1_000_000} Mpx "
                         "this tool accepts", path, "the file is corrupt or not a road camera frame")
    if data[:2] == b"\xff\xd8" and not data.rstrip(b"\x00").endswith(b"\xff\xd9"):
        raise InputError(f"JPEG {kind} is truncated (no end-of-image marker)", path, "re-copy or re-export the file")
    if data[:8] == b"\x89PNG\r\n\x1a\n" and b"IEND" not in data[-16:]:
        raise InputError(f"PNG {kind} is truncated (no IEND chunk)", path, "re-copy or re-export the file")
    arr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if arr is None or arr.size == 0:
        raise InputError(f"cannot decode {kind} (corrupt or not an image)", path, "re-copy or re-export the file")
    if arr.ndim == 3:
        ch = arr.shape[2]
        if ch == 4 and not label:
            arr = np.ascontiguousarray(arr[..., :3])
        elif ch not in (3, 4) or (ch == 4 and label):
            raise InputError(f"{kind} has {ch} channels", path,
                             "give a greyscale or 3-channel colour image" if not label else "give a single-channel id image or a 3-channel colour label")
    if arr.dtype not in (np.uint8, np.uint16):
        raise InputError(f"{kind} has unsupported pixel type {arr.dtype}", path, "convert to 8- or 16-bit PNG")
    return LoadedImage(path, arr, hashlib.sha256(data).hexdigest())


def image_size(path: str | Path, kind: str = "image") -> tuple[int, int]:
    """(w, h) of an image file from its header, decoding it only when the header is not enough;
    a missing or unreadable file raises :class:`InputError`."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            size = image_size_from_header(f.read(262144))
    except FileNotFoundError:
        raise InputError(f"{kind} file not found", path, "check the path") from None
    except OSError as e:
        raise InputError(f"cannot read {kind}: {e.strerror or e}", path, "check the file") from None
    return size if size is not None else read_image(path, label=kind == "label").size


def read_text(path: str | Path, kind: str = "file", fix: str = "check the path") -> str:
    """A text file's contents; every failure raises :class:`InputError` naming the file."""
    path = Path(path)
    try:
        return path.read_text()
    except FileNotFoundError:
        raise InputError(f"{kind} not found", path, fix) from None
    except IsADirectoryError:
        raise InputError(f"is a directory, expected a {kind}", path, fix) from None
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read {kind}: {e.__class__.__name__}", path, "check the file and its permissions") from None


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` via a temp file in the same directory and ``os.replace``: a
    reader (or a crash) sees either the old file or the complete new one, never half of it."""
    path = Path(path)
    # .NAME.RANDOM.tmp (what store.temp_files finds after a crash), created exclusively with the
    # default permissions (umask), unlike mkstemp's 0600: a store on a shared file system stays
    # readable by its group
    tmp = path.parent / f".{path.name}.{os.urandom(6).hex()}.tmp"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    except OSError as e:
        raise _naming(e, path) from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(e, OSError):
            raise _naming(e, path) from None
        raise


def _naming(e: OSError, path: Path) -> OSError:
    """The same error (same errno, so the same OSError subclass) naming ``path``, the file the
    user asked for: a failed write (ENOSPC, EDQUOT, EIO) names no file, and the temp file's
    name would mean nothing to the user."""
    return OSError(e.errno, e.strerror or str(e), str(path))


# PNG settings per kind of content, (row filter, deflate level), chosen by measurement (CamVid
# frames and their 1/8 virtual-camera images, one thread; encoder: vcprep.io.png, libdeflate,
# deterministic; benchmarks/speed/png_deflate.py):
# - 'photo': 'sub' filter, level 1 - camera frames, 3.4 ms and 258 KB at 480x360 ('none': 314 KB;
#   'up': 252 KB, about as fast);
# - 'store': no filter, level 1 - virtual-camera images are mostly completion, pixels repeated along
#   rays, which LZ77 matching finds unfiltered: 2.9 ms and 213 KB at 688x350 ('sub': 217 KB, 'up':
#   233 KB; level 2: 197 KB, slower);
# - 'mask': no filter, level 2 - labels, valid masks and predictions (few values): 0.35 ms, 3 KB
#   (level 1 is slower here, 0.54 ms).
PNG_KINDS = {"photo": ("sub", 1), "store": ("none", 1), "mask": ("none", 2)}


def write_png(path: str | Path, array: np.ndarray, kind: str = "photo", level: int | None = None) -> str:
    """Encode ``array`` as PNG (:func:`vcprep.io.png.encode_png`, settings of ``kind`` from
    :data:`PNG_KINDS`; ``level`` overrides its deflate level, e.g. 3 for figures) and write it
    atomically. Returns the SHA-256 (hex) of the bytes written."""
    filt, default_level = PNG_KINDS[kind]
    try:
        data = encode_png(array, filt, default_level if level is None else level)
    except ValueError as e:
        raise InputError(f"cannot encode PNG: {e}", path, "write 8- or 16-bit grey, BGR or BGRA images") from None
    write_bytes_atomic(path, data)
    return hashlib.sha256(data).hexdigest()
