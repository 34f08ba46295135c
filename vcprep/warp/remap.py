"""Warping images and labels between a physical camera and the virtual camera with one
``cv2.remap`` per image, using inverse maps that are built once per homography and cached.

Convention: a map for ``dst_H_src`` gives, for every destination pixel centre (u, v) (integers),
the source coordinate ``src_H_dst @ (u, v, 1)`` (pixel centres at integers, as OpenCV's remap
and warpPerspective use). A destination pixel is *valid* where that coordinate lies inside the
source image's outer pixel edges ``[-0.5, w - 0.5) x [-0.5, h - 0.5)``; valid coordinates in the
half-pixel rim are clamped to the edge pixel (= border replication), invalid ones are sent far
outside so that the constant border value applies (0 for images, 255 = ignore for labels).
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

__all__ = ["RemapMaps", "build_maps", "maps_from_coordinates", "warp_image", "warp_label", "maps_for", "clear_cache",
           "OUTSIDE"]

OUTSIDE = -64.0  # map value for destination pixels that have no source pixel


@dataclass(frozen=True)
class RemapMaps:
    """Precomputed inverse maps for one homography and one (source, destination) size pair.

    ``map_x``/``map_y`` float32 source coordinates (clamped / OUTSIDE as described above);
    ``linear`` fixed-point maps for bilinear remap; ``nearest`` rounded maps for labels;
    ``valid`` uint8 (1 where a source pixel landed).
    """

    map_x: np.ndarray
    map_y: np.ndarray
    linear: tuple[np.ndarray, np.ndarray]
    nearest: np.ndarray
    valid: np.ndarray

    @property
    def size(self) -> tuple[int, int]:
        return int(self.valid.shape[1]), int(self.valid.shape[0])

    @cached_property
    def roi(self) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1): bounding box of the destination pixels that sample the source at
        all (map_x >= 0); everything outside it is border value, so remap only this box."""
        inside = self.map_x >= 0
        rows = np.flatnonzero(inside.any(axis=1))
        cols = np.flatnonzero(inside.any(axis=0))
        if rows.size == 0:
            return (0, 0, 0, 0)
        return int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1

    @property
    def exact_maps(self) -> "RemapMaps":
        """The maps with float source coordinates for every pixel (these maps themselves)."""
        return self

    def remap_image(self, img: np.ndarray) -> np.ndarray:
        """Bilinear warp with the fixed-point maps (see :func:`warp_image`)."""
        return _remap(img, self, self.linear[0], self.linear[1], cv2.INTER_LINEAR, 0)

    def remap_label(self, label: np.ndarray, border_value: int) -> np.ndarray:
        """Nearest-neighbour warp (see :func:`warp_label`)."""
        return _remap(label, self, self.nearest, None, cv2.INTER_NEAREST, border_value)


def source_coordinates(src_H_dst: np.ndarray, dst_size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact (float64) source coordinates of every destination pixel centre, and the sign mask
    of the homogeneous scale (False beyond the line that maps to infinity)."""
    W, H = dst_size
    M = np.asarray(src_H_dst, dtype=np.float64)
    u = np.arange(W, dtype=np.float64)[None, :]
    v = np.arange(H, dtype=np.float64)[:, None]
    den = M[2, 0] * u + (M[2, 1] * v + M[2, 2])
    front = den > 0
    inv = 1.0 / np.where(front, den, 1.0)
    x = (M[0, 0] * u + (M[0, 1] * v + M[0, 2])) * inv
    y = (M[1, 0] * u + (M[1, 1] * v + M[1, 2])) * inv
    return x, y, front


def build_maps(dst_H_src: np.ndarray, src_size: tuple[int, int], dst_size: tuple[int, int],
               oriented: bool = False) -> RemapMaps:
    """Remap maps that warp a ``src_size`` image into ``dst_size`` through ``dst_H_src``.
    ``oriented``: the matrix's homogeneous sign already says which destination pixels lie in front
    (positive scale of ``inv(dst_H_src) @ (u, v, 1)``); else the middle of the destination is taken
    to be in front."""
    M = np.linalg.inv(np.asarray(dst_H_src, dtype=np.float64))
    if not oriented and M[2] @ np.array([dst_size[0] / 2, dst_size[1] / 2, 1.0]) < 0:
        M = -M  # homogeneous sign: make the middle of the destination 'in front'
    x, y, front = source_coordinates(M, dst_size)
    w, h = src_size
    valid = front & (x >= -0.5) & (x < w - 0.5) & (y >= -0.5) & (y < h - 0.5)
    return maps_from_coordinates(x, y, valid, src_size)


def maps_from_coordinates(x: np.ndarray, y: np.ndarray, valid: np.ndarray, src_size: tuple[int, int]) -> RemapMaps:
    """:class:`RemapMaps` from the source coordinates (x, y) of every destination pixel and where
    they are ``valid`` (clamped to the source's edge pixels there, :data:`OUTSIDE` elsewhere)."""
    w, h = src_size
    map_x = np.where(valid, np.clip(x, 0, w - 1), OUTSIDE).astype(np.float32)
    map_y = np.where(valid, np.clip(y, 0, h - 1), OUTSIDE).astype(np.float32)
    linear = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
    nearest = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2, nninterpolation=True)[0]
    return RemapMaps(map_x, map_y, linear, nearest, valid.astype(np.uint8))


_CACHE: "OrderedDict[tuple, RemapMaps]" = OrderedDict()
_CACHE_MAX = 8


def maps_for(dst_H_src: np.ndarray, src_size: tuple[int, int], dst_size: tuple[int, int],
             oriented: bool = False) -> RemapMaps:
    """:func:`build_maps` with a small LRU cache keyed by the exact matrix and sizes (all images
    of one camera share one homography in between-camera mode, so maps are built once)."""
    H = np.ascontiguousarray(dst_H_src, dtype=np.float64)
    key = (H.tobytes(), tuple(src_size), tuple(dst_size), oriented)
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        return hit
    maps = build_maps(H, src_size, dst_size, oriented)
    _CACHE[key] = maps
    if len(_CACHE) > _CACHE_MAX:
        _CACHE.popitem(last=False)
    return maps


def clear_cache() -> None:
    """Forget the maps :func:`maps_for` keeps, so the next call builds them afresh (a benchmark's
    cold start)."""
    _CACHE.clear()


def _remap(img: np.ndarray, maps: RemapMaps, m1, m2, interp: int, border_value) -> np.ndarray:
    """cv2.remap restricted to ``maps.roi`` (the rest is ``border_value``): a physical camera
    usually covers a fraction of the virtual view, so this skips most of the work."""
    W, H = maps.size
    x0, y0, x1, y1 = maps.roi
    if (x0, y0, x1, y1) == (0, 0, W, H):
        return cv2.remap(img, m1, m2, interp, borderMode=cv2.BORDER_CONSTANT, borderValue=border_value)
    out = np.full((H, W) + img.shape[2:], border_value, dtype=img.dtype)
    if x1 > x0 and y1 > y0:
        cv2.remap(img, m1[y0:y1, x0:x1], None if m2 is None else m2[y0:y1, x0:x1], interp,
                  dst=out[y0:y1, x0:x1], borderMode=cv2.BORDER_CONSTANT, borderValue=border_value)
    return out


def is_bgr8(img: np.ndarray) -> bool:
    """8-bit 3-channel (the fused completion pass runs these through BGRA)."""
    return img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3


def warp_image(img: np.ndarray, maps: RemapMaps, exact: bool = False) -> np.ndarray:
    """Bilinear warp of an image (any channels/depth, up to 4 channels); uncovered pixels are 0.

    ``exact=True`` uses one remap with the float maps of every pixel (no fixed-point maps, no
    fast path): the reference the fast paths (e.g. :class:`vcprep.warp.completion.CompletionMaps`)
    are tested against."""
    if exact:
        ref = maps.exact_maps
        return _remap(img, ref, ref.map_x, ref.map_y, cv2.INTER_LINEAR, 0)
    return maps.remap_image(img)


def warp_label(label: np.ndarray, maps: RemapMaps, border_value: int = 255) -> np.ndarray:
    """Nearest-neighbour warp of a label (values are never mixed); uncovered -> ``border_value``."""
    return maps.remap_label(label, border_value)
