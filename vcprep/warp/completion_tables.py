"""The fill table of the projective completion (:mod:`vcprep.warp.completion`): which table angle
every uncovered store pixel takes (:class:`AngleIndex`), the source points of each angle
(:class:`AngleFill`), the row bands each pass covers, and the small LRU caches that share them
between items of one geometry."""
from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from .completion_rays import _build_rays, _Rays

TABLE_ARC = 0.5        # px: angular step of the fill table, as arc length at the farthest store pixel
TABLE_COLS = 4096      # the fill table's row length (remap coordinates must fit in int16)
BAND_ROWS = 48         # rows per band of the fused pass (see _bands): fewer calls on small stores, tight bands on large
CHUNK_PIXELS = 1 << 18  # pixels per chunk of the fused pass on packed (BGRA) images: 1 MiB, stays in cache
_CACHE_MAX = 4  # entries each LRU cache keeps


@dataclass(frozen=True)
class AngleIndex:
    """Which fill-table angle every uncovered store pixel takes, for one (homography, sizes,
    centre); shared by every item with that geometry (all images of a camera in between-camera
    mode), whatever their labels.

    ``n`` angles ``phi_k = 2 pi k / n`` (arc step <= ``TABLE_ARC`` px at the farthest store
    pixel), laid out in a (rows, ``TABLE_COLS``) table; ``index`` (int16, (H, W, 2)) is the nearest
    remap map into it: ``(k % TABLE_COLS, k // TABLE_COLS)`` for uncovered pixels, (-1, -1) for
    covered ones (left alone by ``BORDER_TRANSPARENT``). ``covered_rects`` / ``fill_rects``:
    (y0, y1, x0, x1) bands that hold every covered / uncovered pixel, so each pass skips most of
    the other's pixels."""

    n: int
    index: np.ndarray
    covered_rects: tuple[tuple[int, int, int, int], ...]
    fill_rects: tuple[tuple[int, int, int, int], ...]

    @property
    def shape(self) -> tuple[int, int]:
        return (self.n + TABLE_COLS - 1) // TABLE_COLS, min(self.n, TABLE_COLS)

    def table(self, values: np.ndarray, dtype=np.float32) -> np.ndarray:
        """``values`` (one per angle) laid out as the (rows, cols) table (tail padded)."""
        r, c = self.shape
        out = np.empty(r * c, dtype=dtype)
        out[:self.n] = values
        out[self.n:] = values[-1] if self.n else 0
        return out.reshape(r, c)

    def chunks(self, packed: bool) -> tuple[tuple[int, int, tuple, tuple], ...]:
        """(r0, r1, covered rects, fill rects) in rows r0..r1, for the fused pass: the whole store in
        one chunk, or, for ``packed`` images larger than 2 ``CHUNK_PIXELS``, whole bands of about
        ``CHUNK_PIXELS`` rows (the covered rects are band-aligned, so each lies in one chunk; the
        fill rects are cut at the chunk's rows)."""
        H, W = self.index.shape[:2]
        rows = H if not packed or H * W <= 2 * CHUNK_PIXELS else max(1, CHUNK_PIXELS // (W * BAND_ROWS)) * BAND_ROWS
        key = f"_chunks_{rows}"  # cached on the (frozen) instance
        hit = self.__dict__.get(key)
        if hit is None:
            hit = self.__dict__[key] = tuple(
                (r0, min(H, r0 + rows), tuple(r for r in self.covered_rects if r0 <= r[0] < r0 + rows),
                 tuple((max(y0, r0), min(y1, r0 + rows), x0, x1) for y0, y1, x0, x1 in self.fill_rects
                       if y0 < r0 + rows and y1 > r0))
                for r0 in range(0, H, rows))
        return hit

    @property
    def flat(self) -> np.ndarray:
        """(H, W) int32 table position of every pixel (0 for covered ones), built on first use:
        the index of a flat gather (:func:`vcprep.warp.completion._fill`)."""
        hit = self.__dict__.get("_flat")
        if hit is None:
            ix = self.index.view(np.int32)[..., 0]
            k = (self.index[..., 0].astype(np.int32) + self.index[..., 1].astype(np.int32) * TABLE_COLS)
            hit = self.__dict__["_flat"] = np.where(ix == -1, np.int32(0), k)
        return hit

    def k(self, uncovered: np.ndarray) -> np.ndarray:
        """The table angle index of every pixel of the boolean mask ``uncovered``."""
        ix = self.index[uncovered]
        return ix[:, 0].astype(np.int64) + ix[:, 1].astype(np.int64) * TABLE_COLS


@dataclass(frozen=True)
class AngleFill:
    """Source points of the fill table (from :func:`_exit_table`), (rows, cols) float32 each:
    where the image samples (bilinear) and where the label samples (nearest) for every angle."""

    image_x: np.ndarray
    image_y: np.ndarray
    label_x: np.ndarray
    label_y: np.ndarray


def _lru(cache: OrderedDict, key: tuple, build):
    """``cache[key]``, built by ``build()`` on a miss; keeps the ``_CACHE_MAX`` most recent."""
    hit = cache.get(key)
    if hit is not None:
        cache.move_to_end(key)
        return hit
    out = cache[key] = build()
    if len(cache) > _CACHE_MAX:
        cache.popitem(last=False)
    return out


_RAYS: "OrderedDict[tuple, _Rays]" = OrderedDict()


def _rays(n: int, J: np.ndarray, c_src: np.ndarray, src_size, key: tuple) -> _Rays:
    """The :class:`_Rays` of the ``n`` table angles (LRU-cached under ``key``)."""
    return _lru(_RAYS, key, lambda: _build_rays(n, J, c_src, src_size))


def _bands(valid: np.ndarray) -> tuple[tuple, tuple]:
    """Row bands covering every covered pixel (covered_rects) and every uncovered one (fill_rects).

    Per band of ``BAND_ROWS``-ish rows: the covered pixels lie in [first covered column, last + 1)
    of the band's rows that have any
    and, as the covered region meets every row in one run (the image of a rectangle is convex),
    the uncovered ones left of the largest first column or right of the smallest last column.
    Checked, not assumed: if a band's fill rectangles miss an uncovered pixel the band is filled
    whole."""
    H, W = valid.shape
    cov = valid.astype(bool)
    any_ = cov.any(axis=1)
    first = np.where(any_, cov.argmax(axis=1), W)
    last = np.where(any_, W - 1 - cov[:, ::-1].argmax(axis=1), -1)
    rows = BAND_ROWS
    covered, fill = [], []
    for y0 in range(0, H, rows):
        y1 = min(H, y0 + rows)
        a = any_[y0:y1]
        if not a.any():
            fill.append((y0, y1, 0, W))
            continue
        f, l_ = first[y0:y1][a], last[y0:y1][a]
        rows_in = np.flatnonzero(a)  # the band's rows that hold covered pixels (a band can overhang the region)
        covered.append((y0 + int(rows_in[0]), y0 + int(rows_in[-1]) + 1, int(f.min()), int(l_.max()) + 1))
        if not a.all():
            fill.append((y0, y1, 0, W))
            continue
        parts = [(y0, y1, 0, int(f.max())), (y0, y1, int(l_.min()) + 1, W)]
        parts = [r for r in parts if r[3] > r[2]]
        reach = np.zeros((y1 - y0, W), dtype=bool)
        for _, _, x0, x1 in parts:
            reach[:, x0:x1] = True
        fill.extend(parts if (reach | cov[y0:y1]).all() else [(y0, y1, 0, W)])
    merged: list[tuple[int, int, int, int]] = []
    for r in fill:  # join vertically adjacent rectangles with the same columns
        if merged and merged[-1][1] == r[0] and merged[-1][2:] == r[2:]:
            merged[-1] = (merged[-1][0], r[1], r[2], r[3])
        else:
            merged.append(r)
    return tuple(covered), tuple(merged)


_ANGLES: "OrderedDict[tuple, AngleIndex]" = OrderedDict()


def _angle_index(valid: np.ndarray, centre: tuple[float, float], key: tuple) -> AngleIndex:
    """The :class:`AngleIndex` of ``valid`` seen from ``centre`` (LRU-cached under ``key``)."""
    return _lru(_ANGLES, key, lambda: _build_angle_index(valid, centre))


def _build_angle_index(valid: np.ndarray, centre: tuple[float, float]) -> AngleIndex:
    H_, W_ = valid.shape
    far = max(math.hypot(cx - centre[0], cy - centre[1]) for cx in (0, W_ - 1) for cy in (0, H_ - 1))
    n = int(max(1024, math.ceil(2 * math.pi * far / TABLE_ARC)))
    every = _all_angles((H_, W_), np.float32(centre[0]), np.float32(centre[1]), n)
    # covered pixels -> (-1, -1): one int32 word per pixel (the two int16 of the pair)
    index = np.where(valid == 1, np.int32(-1), every.view(np.int32)[..., 0]).view(np.int16).reshape(H_, W_, 2)
    covered, fill = _bands(valid)
    return AngleIndex(n, index, covered, fill)


_ALL_ANGLES: "OrderedDict[tuple, np.ndarray]" = OrderedDict()


def _all_angles(shape: tuple[int, int], cx: np.float32, cy: np.float32, n: int) -> np.ndarray:
    """The fill-table index of EVERY store pixel of ``shape`` seen from (cx, cy) with ``n``
    angles (read-only; :func:`_build_angle_index` marks the covered ones). It does not depend on
    the pose: every image's VP maps to the virtual camera's, so per-image poses (within-camera
    correction, a video) share it and only the covered mask changes (LRU-cached by the exact
    float32 centre it is computed from)."""

    def build() -> np.ndarray:
        du = np.arange(shape[1], dtype=np.float32)[None, :] - cx
        dv = np.arange(shape[0], dtype=np.float32)[:, None] - cy
        angle = np.arctan2(dv, du)  # float32 numpy: ~3e-7 rad (cv2.phase: ~2e-4, too coarse far out)
        k = np.rint(angle * np.float32(n / (2 * math.pi))).astype(np.int32) % n
        index = np.empty(shape + (2,), dtype=np.int16)
        index[..., 0] = k % TABLE_COLS
        index[..., 1] = k // TABLE_COLS
        index.setflags(write=False)
        return index

    return _lru(_ALL_ANGLES, (tuple(shape), cx.tobytes(), cy.tobytes(), int(n)), build)
