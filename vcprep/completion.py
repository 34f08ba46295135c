"""Completion of the virtual image (paper §4.3): fill every store pixel that no source pixel
covers, fused with the warp: one inverse map (store pixel -> source point), applied in one pass.

Methods (:data:`METHODS`):

- ``projective`` (the paper's): polar coordinates centred on the road VP in store coordinates;
  an uncovered pixel takes the value where the ray from the VP through it leaves the covered
  region, linearly interpolated in angle along the region's boundary.
- ``zero``: image 0, label 0 (not road) -- the paper's zero-padding ablation.
- ``replicate``: the value of the nearest covered store pixel (border replication in the
  virtual image) -- the paper's pixel-replication ablation.
- ``none``: the bare warp (image 0, label 255 = ignore).

Why one remap is enough: the homography ``virt_H_src`` maps lines to lines and the VP to the VP,
so the ray from the VP ``c`` through an uncovered store pixel ``p`` is the image of a ray from
``c_src = src_H_virt c`` in the source. Its source direction is ``J (p - c)`` with ``J`` the
Jacobian of ``src_H_virt`` at ``c`` (exact: a homography maps a ray from ``c`` onto a ray from
``c_src``), and the point where the store ray leaves the covered region is the image of the
point where the source ray leaves the source region. So every uncovered store pixel gets a
*source* coordinate, like the covered ones (``map_x``/``map_y``). As that coordinate depends only
on the ray's angle, it is kept as a 1-D table of angles, and applying the maps remaps the covered
pixels and looks the uncovered ones up in the table sampled once per image
(:class:`CompletionMaps`): each pixel is computed once, and only the covered ones interpolate.

Labels are completed from LABEL_RIM (8) px inside the image edge: a ray that leaves through the
edge takes its label where it leaves the rectangle inset by 8 px on every side
(:func:`label_exit_points`). Annotations often carry a thin rim that disagrees with the rows
just inside it (KITTI road's ``gt_image_2`` marks its last 4-5 rows "not road" even under the
road); sampled at the edge itself, that rim would fill the whole region below a frame. The
image keeps the exact edge exit (its pixels there are real); ``replicate`` clamps its label
points into the same inset rectangle.

The covered region is the source rectangle (pixel centres ``[0, w-1] x [0, h-1]``) minus the
label's ignore pixels that touch the image border (an ego-vehicle bonnet, a rectification
border). A ray's exit point is the exact ray/rectangle intersection, unless the ray meets such
pixels first: then it is looked up in a table of the region's boundary pixels next to them,
sorted by angle; the image point interpolates linearly in angle between boundary pixels and
steps 1 px inward (so bilinear sampling never reaches into the ignore pixels); the label takes
the boundary pixel nearest in angle (values are never mixed). Ignore pixels inside the covered region keep their warped
value (the bonnet stays ignore). Ignore holes that do not touch the border are not boundary.

VP outside the covered region (a bad estimate, or a VP above the source image): rays from an
outside point do not leave the region once, so the rays are centred instead on the covered
pixel nearest to the VP, moved 10 % of the way toward the region's centroid (strictly inside).
The result says so (``vp_inside=False``, ``centre``), and stores record it.

Conventions as in :mod:`vcprep.warp`: (x, y) = (u, v), pixel centres at integers, maps are
store pixel -> source pixel.
"""
from __future__ import annotations

import hashlib
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from .errors import GeometryError, InputError
from .labels import IGNORE
from .warp import RemapMaps, maps_for

__all__ = ["METHODS", "COMPLETION_VERSION", "LABEL_RIM", "CompletionMaps", "check_method", "border_ignore",
           "completion_maps", "complete_maps", "clear_cache", "exit_points_rectangle", "label_exit_points", "store_vp"]

METHODS = ("projective", "zero", "replicate", "none")
COMPLETION_VERSION = "completion-v3"  # bump when completed outputs of identical inputs would change
# v3: labels are sampled LABEL_RIM px inside the image edge (annotation rims, e.g. KITTI's bottom rows)
INSET = 1.0            # px the image map steps inward from a cut (ignore) boundary
LABEL_RIM = 8          # source px: completed labels never take their value from this band along the image edge
FALLBACK_TOWARD = 0.1  # VP outside: move the nearest covered pixel this far toward the centroid
TABLE_ARC = 0.5        # px: angular step of the fill table, as arc length at the farthest store pixel
TABLE_COLS = 4096      # the fill table's row length (remap coordinates must fit in int16)
BAND_ROWS = 48         # rows per band of the fused pass (see _bands): fewer calls on small stores, tight bands on large


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


class CompletionMaps:
    """Warp + completion of one item, built once per (homography, sizes, method, VP, border-ignore
    mask) and applied to its image and label.

    ``valid`` is 1 only where a source pixel landed. ``label_border``: label value for pixels left
    uncovered (255 for 'none', 0 for 'zero'). ``centre``: the store point the projective rays
    start from (the VP, or the fallback when ``vp_inside`` is False).

    Applying them (``warp_image`` / ``warp_label``): 'none' and 'zero' are the bare warp; 'replicate'
    is one remap of completed maps; 'projective' is one pass over the pixels in two parts that never
    overlap: the covered pixels are remapped from the source (bilinear), the uncovered ones are
    looked up (nearest in angle) in a table of the source sampled (bilinear) at the exit point of
    each of ``n`` angles; the table is so fine (<= ``TABLE_ARC`` px of arc at the farthest pixel)
    that this is the continuous definition sampled below pixel resolution. ``map_x``/``map_y``
    (computed on first use) are the same source points per pixel, so ``warp_image(exact=True)``
    -- one remap of every pixel -- is the reference the fast path is tested against.
    """

    def __init__(self, base: RemapMaps, method: str, label_border: int, centre: tuple[float, float] | None = None,
                 vp_inside: bool = True, full: RemapMaps | None = None, angles: AngleIndex | None = None,
                 fill: AngleFill | None = None):
        self.base, self.method, self.label_border = base, method, label_border
        self.centre, self.vp_inside = centre, vp_inside
        self.valid = base.valid
        self._full, self.angles, self.fill = full, angles, fill

    @property
    def size(self) -> tuple[int, int]:
        return self.base.size

    @property
    def note(self) -> str | None:
        """A sentence for the user when the result is not the plain method (VP outside)."""
        if self.method == "projective" and not self.vp_inside:
            return (f"VP outside the covered region; completion rays start at the nearest covered point "
                    f"({self.centre[0]:.1f}, {self.centre[1]:.1f}) instead")
        return None

    @cached_property
    def exact_maps(self) -> RemapMaps:
        """Float source coordinates of every store pixel (image: bilinear; ``nearest``: label)."""
        if self._full is not None:
            return self._full
        if self.fill is None:
            return self.base
        unc = self.valid == 0
        k = self.angles.k(unc)
        coords = []
        for tx, ty in ((self.fill.image_x, self.fill.image_y), (self.fill.label_x, self.fill.label_y)):
            mx, my = self.base.map_x.copy(), self.base.map_y.copy()
            mx[unc] = tx.ravel()[k]
            my[unc] = ty.ravel()[k]
            coords.append((mx, my))
        return _finish(*coords[0], *coords[1], self.valid)

    # the per-pixel maps of :class:`RemapMaps`, from the exact maps (built on first use)
    map_x = property(lambda self: self.exact_maps.map_x)
    map_y = property(lambda self: self.exact_maps.map_y)
    linear = property(lambda self: self.exact_maps.linear)
    nearest = property(lambda self: self.exact_maps.nearest)
    roi = property(lambda self: self.exact_maps.roi)

    def remap_image(self, img: np.ndarray) -> np.ndarray:
        if self.fill is None:
            return (self._full or self.base).remap_image(img)
        return self._fused(img, self.base.linear, cv2.INTER_LINEAR, 0, self.fill.image_x, self.fill.image_y)

    def remap_label(self, label: np.ndarray, border_value: int) -> np.ndarray:
        if self.fill is None:
            return (self._full or self.base).remap_label(label, border_value)
        return self._fused(label, (self.base.nearest, None), cv2.INTER_NEAREST, border_value,
                           self.fill.label_x, self.fill.label_y)

    def _fused(self, src, maps, interp, border_value, table_x, table_y) -> np.ndarray:
        # 8-bit BGR goes through BGRA so that the fill copies one 32-bit word per pixel (~1.5x
        # faster than 3 bytes); the conversions cost less than that saves
        packed = src.dtype == np.uint8 and src.ndim == 3 and src.shape[2] == 3
        if packed:
            src = cv2.cvtColor(src, cv2.COLOR_BGR2BGRA)
        W, H = self.size
        out = _scratch((H, W, 4)) if packed else np.empty((H, W) + src.shape[2:], dtype=src.dtype)
        m1, m2 = maps
        for y0, y1, x0, x1 in self.angles.covered_rects:
            cv2.remap(src, m1[y0:y1, x0:x1], None if m2 is None else m2[y0:y1, x0:x1], interp,
                      dst=out[y0:y1, x0:x1], borderMode=cv2.BORDER_CONSTANT, borderValue=border_value)
        table = cv2.remap(src, table_x, table_y, interp, borderMode=cv2.BORDER_REPLICATE)
        dst = out
        if packed:
            dst, table = out.view(np.int32)[..., 0], table.view(np.int32)[..., 0]
        index = self.angles.index
        for y0, y1, x0, x1 in self.angles.fill_rects:
            cv2.remap(table, index[y0:y1, x0:x1], None, cv2.INTER_NEAREST, dst=dst[y0:y1, x0:x1],
                      borderMode=cv2.BORDER_TRANSPARENT)
        return cv2.cvtColor(out, cv2.COLOR_BGRA2BGR) if packed else out


def check_method(method: str) -> str:
    if method not in METHODS:
        raise InputError(f"unknown completion method '{method}'", None, f"use one of {', '.join(METHODS)}")
    return method


def border_ignore(label: np.ndarray | None) -> np.ndarray | None:
    """Boolean mask of the ignore pixels connected (8-neighbourhood) to the image border, or None
    when there are none. These cut the covered region; interior ignore holes do not."""
    if label is None:
        return None
    ign = (label == IGNORE).view(np.uint8)
    if not (ign[0].any() or ign[-1].any() or ign[:, 0].any() or ign[:, -1].any()):
        return None
    # a frame of ignore around the label joins every component that touches the border; one
    # 8-connected flood fill from the frame marks them all (value 2)
    framed = cv2.copyMakeBorder(ign, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=1)
    cv2.floodFill(framed, None, (0, 0), 2, flags=8)
    return framed[1:-1, 1:-1] == 2


def store_vp(H: np.ndarray, vp_src: tuple[float, float]) -> tuple[float, float]:
    """The VP ``vp_src`` (source pixels) in store coordinates: ``H @ vp``."""
    p = np.asarray(H, dtype=np.float64) @ np.array([vp_src[0], vp_src[1], 1.0])
    return float(p[0] / p[2]), float(p[1] / p[2])


# -- geometry ------------------------------------------------------------------------------------

def _src_H_dst(dst_H_src: np.ndarray) -> np.ndarray:
    return np.linalg.inv(np.asarray(dst_H_src, dtype=np.float64))


def _to_source(M: np.ndarray, c: tuple[float, float]) -> tuple[np.ndarray | None, np.ndarray]:
    """Source point of store point ``c`` (None if it lies beyond the source's horizon line, where
    the homogeneous scale changes sign relative to the source image) and the 2x2 matrix ``J``
    with source direction = ``J @ (p - c)`` for the ray from ``c`` toward ``p`` (independent of
    the overall sign of ``M``)."""
    V = M @ np.array([c[0], c[1], 1.0])
    J = np.array([[M[0, 0] * V[2] - V[0] * M[2, 0], M[0, 1] * V[2] - V[0] * M[2, 1]],
                  [M[1, 0] * V[2] - V[1] * M[2, 0], M[1, 1] * V[2] - V[1] * M[2, 1]]])
    if abs(V[2]) < 1e-12:
        return None, J
    return V[:2] / V[2], J


def exit_points_rectangle(c_src: np.ndarray, dx: np.ndarray, dy: np.ndarray, src_size: tuple[int, int]):
    """Where rays ``c_src + s (dx, dy)``, s > 0, leave the rectangle of pixel centres
    ``[0, w-1] x [0, h-1]`` (``c_src`` inside). Returns (x, y) arrays."""
    w, h = src_size
    cx, cy = float(c_src[0]), float(c_src[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        sx = np.where(dx > 0, (w - 1 - cx) / dx, np.where(dx < 0, -cx / dx, np.inf))
        sy = np.where(dy > 0, (h - 1 - cy) / dy, np.where(dy < 0, -cy / dy, np.inf))
    s = np.minimum(sx, sy)
    s = np.where(np.isfinite(s), s, 0.0)
    x = np.clip(cx + s * dx, 0, w - 1)
    y = np.clip(cy + s * dy, 0, h - 1)
    return x, y


def label_exit_points(c_src: np.ndarray, dx: np.ndarray, dy: np.ndarray, src_size: tuple[int, int],
                      rim: float = LABEL_RIM) -> tuple[np.ndarray, np.ndarray]:
    """The label pixel (rounded) of rays ``c_src + s (dx, dy)`` that leave through the image
    edge: where they leave the rectangle inset by ``rim`` px on every side (at most half the
    image), so that a thin band along the edge that disagrees with the rows inside it (an
    annotation rim) never fills the completion. ``c_src`` is first moved into that rectangle."""
    w, h = src_size
    rx, ry = min(float(rim), (w - 1) / 2), min(float(rim), (h - 1) / 2)
    c = np.clip(np.asarray(c_src, dtype=np.float64), [rx, ry], [w - 1 - rx, h - 1 - ry])
    # the inset rectangle [rx, w-1-rx] x [ry, h-1-ry] is the full one of an image 2rx, 2ry px smaller
    x, y = exit_points_rectangle(c - [rx, ry], dx, dy, (w - 2 * rx, h - 2 * ry))
    return np.rint(x + rx), np.rint(y + ry)


def _boundary_table(boundary: np.ndarray, c_src: np.ndarray, offset: tuple[int, int] = (0, 0)):
    """The first-exit boundary seen from ``c_src`` among the pixels of ``boundary`` (uint8 0/1).

    Each pixel covers the angular interval it subtends from ``c_src`` (half-width 0.71/r); in
    every angular bin the nearest covering pixel wins (a ray leaves the region there first; pixels
    hidden behind a nearer boundary, e.g. the side walls of a bonnet notch, never win). Returns
    the winners (theta, x, y) sorted by theta, and which bins any pixel covers (bool, ``nbins``).
    ``offset``: (x, y) of ``boundary``'s top-left pixel when it is a window of the image."""
    pts = cv2.findNonZero(boundary)  # row-major order, as np.nonzero
    if pts is None:
        return np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(1, dtype=bool)
    pts = pts.reshape(-1, 2)
    x = pts[:, 0].astype(np.float64) + offset[0]
    y = pts[:, 1].astype(np.float64) + offset[1]
    th = np.arctan2(y - c_src[1], x - c_src[0])
    r = np.hypot(x - c_src[0], y - c_src[1])
    nbins = int(np.clip(2 * math.pi * r.max(), 2048, 1 << 16))  # ~1 px at the farthest boundary
    bw = 2 * math.pi / nbins
    half = 0.71 / np.maximum(r, 0.5)
    lo = np.floor((th - half + math.pi) / bw).astype(np.int64)
    cnt = np.minimum(np.floor((th + half + math.pi) / bw).astype(np.int64) - lo + 1, nbins)
    by_r = np.argsort(r, kind="stable")  # nearest first; ties by pixel order
    rank = np.empty(len(r), dtype=np.int64)
    rank[by_r] = np.arange(len(r))
    owner = np.repeat(np.arange(len(x)), cnt)
    offs = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    b = (lo[owner] + offs) % nbins
    best = np.full(nbins, len(r), dtype=np.int64)
    np.minimum.at(best, b, rank[owner])  # per bin, the nearest covering pixel
    win = np.unique(by_r[best[best < len(r)]])
    win = win[np.argsort(th[win], kind="stable")]
    return th[win], x[win], y[win], best < len(r)


_CROSS = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))


@dataclass(frozen=True)
class _Rays:
    """The fill table's rays in the source, for one geometry (shared by every label): per table
    angle the angle ``th`` of the source direction from ``c_src``, the exact exit
    through the image rectangle (xr, yr), its distance ``rr``, the pixel it rounds to (lx, ly),
    and the flat source indices of that pixel (``lflat``) and of the exit's bilinear taps
    (``taps``, 4 x n)."""

    c_src: np.ndarray
    th: np.ndarray
    xr: np.ndarray
    yr: np.ndarray
    rr: np.ndarray
    lx: np.ndarray
    ly: np.ndarray
    lflat: np.ndarray
    taps: np.ndarray


def _bilinear_taps(x: np.ndarray, y: np.ndarray, src_size) -> np.ndarray:
    """Flat source indices (4 x n) of the pixels bilinear sampling at (x, y) reads."""
    w, h = src_size
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    return np.stack([y0 * w + x0, y0 * w + x1, y1 * w + x0, y1 * w + x1])


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


def _build_rays(n: int, J: np.ndarray, c_src: np.ndarray, src_size) -> _Rays:
    phi = np.arange(n) * (2 * math.pi / n)
    cx_, cy_ = np.cos(phi), np.sin(phi)
    dx = J[0, 0] * cx_ + J[0, 1] * cy_
    dy = J[1, 0] * cx_ + J[1, 1] * cy_
    xr, yr = exit_points_rectangle(c_src, dx, dy, src_size)
    lx, ly = label_exit_points(c_src, dx, dy, src_size)
    return _Rays(c_src, np.arctan2(dy, dx), xr, yr, np.hypot(xr - c_src[0], yr - c_src[1]), lx, ly,
                 ly.astype(np.int64) * src_size[0] + lx.astype(np.int64), _bilinear_taps(xr, yr, src_size))


def _exit_table(rays: _Rays, src_size, region_src):
    """Source points for the table angles of ``rays``: (image x, y, label x, y).

    Without a cut (``region_src`` None) the exit is the exact ray/rectangle intersection. With
    one, a ray leaves either through the rectangle (exact, as without) or, if nearer, through the
    cut: the region pixels 4-adjacent to it, found by :func:`_boundary_table`. There the image
    point is interpolated linearly in angle between neighbouring boundary pixels (the nearest
    one across an occlusion jump) and stepped ``INSET`` px inward; the label takes the boundary
    pixel nearest in angle. A point whose bilinear taps would touch the cut samples its label
    pixel instead, so no value ever comes from the cut. Only the angles a cut can change (those
    its boundary covers, or whose rectangle exit rounds into it) are computed per label."""
    w, h = src_size
    xr, yr, lx, ly = rays.xr, rays.yr, rays.lx, rays.ly
    if region_src is None:
        return xr, yr, lx, ly
    c_src = rays.c_src
    region = region_src.ravel()
    cut = 1 - region_src
    bx, by, bw, bh = cv2.boundingRect(cut)  # the cut's pixels and their 4-neighbours lie in this window
    x0, y0, x1, y1 = max(bx - 1, 0), max(by - 1, 0), min(bx + bw + 1, w), min(by + bh + 1, h)
    near_cut = cv2.dilate(cut[y0:y1, x0:x1], _CROSS, borderType=cv2.BORDER_CONSTANT, borderValue=0) \
        & region_src[y0:y1, x0:x1]
    th_k, x_k, y_k, covered = _boundary_table(near_cut, c_src, (x0, y0))
    tx, ty = xr, yr
    ok = region[rays.taps[0]] & region[rays.taps[1]] & region[rays.taps[2]] & region[rays.taps[3]]
    if len(th_k):
        nb = len(covered)
        cov = covered[np.floor((rays.th + math.pi) * (nb / (2 * math.pi))).astype(np.int64) % nb]
        rint_cut = region[rays.lflat] == 0
        s = np.flatnonzero(cov | rint_cut)  # the angles this cut can change
        th = rays.th[s]
        n = len(th_k)
        hi = np.searchsorted(th_k, th) % n
        lo = (hi - 1) % n
        span = np.mod(th_k[hi] - th_k[lo], 2 * math.pi)
        a = np.where(span > 0, np.mod(th - th_k[lo], 2 * math.pi) / np.where(span > 0, span, 1.0), 0.0)
        a = np.clip(a, 0.0, 1.0)
        near = np.where(a <= 0.5, lo, hi)
        jump = np.hypot(x_k[hi] - x_k[lo], y_k[hi] - y_k[lo]) > 1.5
        xc = np.where(jump, x_k[near], (1 - a) * x_k[lo] + a * x_k[hi])
        yc = np.where(jump, y_k[near], (1 - a) * y_k[lo] + a * y_k[hi])
        ox, oy = xc - c_src[0], yc - c_src[1]
        r = np.hypot(ox, oy)
        hit = cov[s] & (r < rays.rr[s])  # the cut comes before the rectangle edge
        f = np.where(r > INSET, (r - INSET) / np.maximum(r, 1e-9), 0.0)
        tx, ty, lx, ly = xr.copy(), yr.copy(), lx.copy(), ly.copy()
        tx[s] = np.where(hit, np.clip(c_src[0] + f * ox, 0, w - 1), xr[s])
        ty[s] = np.where(hit, np.clip(c_src[1] + f * oy, 0, h - 1), yr[s])
        # label: the nearest boundary pixel for cut exits and for rectangle exits that round into the cut
        into_cut = hit | rint_cut[s]
        lx[s] = np.where(into_cut, x_k[near], lx[s])
        ly[s] = np.where(into_cut, y_k[near], ly[s])
        t = _bilinear_taps(tx[s], ty[s], src_size)
        ok[s] = region[t[0]] & region[t[1]] & region[t[2]] & region[t[3]]
    ok = ok.astype(bool)
    return np.where(ok, tx, lx), np.where(ok, ty, ly), lx, ly


def _centre(vp: tuple[float, float], M: np.ndarray, src_size, dst_shape, region_src: np.ndarray | None,
            region_dst) -> tuple[tuple[float, float], bool]:
    """The ray centre in store coordinates and whether it is the VP itself (see module doc);
    ``region_dst()`` gives the covered store region (computed only when the VP is not in it)."""
    w, h = src_size
    c_src, _ = _to_source(M, vp)
    mid = M @ np.array([dst_shape[1] / 2, dst_shape[0] / 2, 1.0])
    front = c_src is not None and np.sign((M @ np.array([vp[0], vp[1], 1.0]))[2]) == np.sign(mid[2])
    if front and 0 <= c_src[0] <= w - 1 and 0 <= c_src[1] <= h - 1:
        if region_src is None or region_src[int(round(c_src[1])), int(round(c_src[0]))]:
            return (float(vp[0]), float(vp[1])), True
    region_dst = region_dst()
    ys, xs = np.nonzero(region_dst)
    if len(xs) == 0:
        raise GeometryError("no source pixel lands in the virtual image, nothing to complete from", None,
                            "check the camera, pose and scale")
    k = int(np.argmin((xs - vp[0]) ** 2 + (ys - vp[1]) ** 2))
    q = np.array([xs[k], ys[k]], dtype=np.float64)
    g = np.array([xs.mean(), ys.mean()])
    for cand in (q + FALLBACK_TOWARD * (g - q), g, q):
        u, v = int(round(cand[0])), int(round(cand[1]))
        if 0 <= v < region_dst.shape[0] and 0 <= u < region_dst.shape[1] and region_dst[v, u]:
            return (float(cand[0]), float(cand[1])), False
    return (float(q[0]), float(q[1])), False  # unreachable: q is a region pixel


# -- maps ------------------------------------------------------------------------------------------

def _finish(map_x, map_y, lab_x, lab_y, valid) -> RemapMaps:
    map_x = np.ascontiguousarray(map_x, dtype=np.float32)
    map_y = np.ascontiguousarray(map_y, dtype=np.float32)
    linear = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
    nearest = cv2.convertMaps(np.ascontiguousarray(lab_x, dtype=np.float32),
                              np.ascontiguousarray(lab_y, dtype=np.float32), cv2.CV_16SC2, nninterpolation=True)[0]
    return RemapMaps(map_x, map_y, linear, nearest, valid)


def _bands(valid: np.ndarray) -> tuple[tuple, tuple]:
    """Row bands covering every covered pixel (covered_rects) and every uncovered one (fill_rects).

    Per band of ``BAND_ROWS``-ish rows: the covered pixels lie in [first covered column, last + 1)
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
        covered.append((y0, y1, int(f.min()), int(l_.max()) + 1))
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


def complete_maps(base: RemapMaps, dst_H_src: np.ndarray, src_size: tuple[int, int], method: str,
                  vp: tuple[float, float] | None = None, src_ignore: np.ndarray | None = None) -> CompletionMaps:
    """Fill the uncovered pixels of the bare-warp maps ``base`` by ``method``.

    ``vp``: the ray centre in store coordinates (projective; default: the store centre).
    ``src_ignore``: boolean (h, w) source mask of border ignore pixels (see :func:`border_ignore`),
    excluded from the region that values are taken from.
    """
    check_method(method)
    valid = base.valid
    if method == "none":
        return CompletionMaps(base, method, IGNORE)
    if method == "zero":
        return CompletionMaps(base, method, 0)
    w, h = src_size
    unc = valid == 0
    if not unc.any():  # nothing to fill (also makes completion idempotent)
        return CompletionMaps(base, method, IGNORE, None if vp is None else tuple(map(float, vp)))
    region_src = None
    if src_ignore is not None and src_ignore.any():
        region_src = (~src_ignore).astype(np.uint8)
        if not region_src.any():
            raise InputError("the whole label is ignore at the border, nothing to complete from", None,
                             "check the label, or use --complete none")

    def region_dst() -> np.ndarray:
        r = valid.astype(bool)
        if region_src is not None:
            r &= cv2.remap(region_src, base.nearest, None, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                           borderValue=0) == 1
        if not r.any():
            raise GeometryError("no source pixel lands in the virtual image, nothing to complete from", None,
                                "check the camera, pose and scale")
        return r

    if method == "replicate":
        rdst = region_dst()
        map_x, map_y = base.map_x.copy(), base.map_y.copy()
        vs, us = np.nonzero(unc)
        # nearest region pixel of every store pixel (labels of the zero pixels of 1 - region)
        _, lab = cv2.distanceTransformWithLabels((~rdst).astype(np.uint8), cv2.DIST_L2, 5,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
        ry, rx = np.nonzero(rdst)
        lut = np.zeros(int(lab.max()) + 1, dtype=np.int64)
        lut[lab[ry, rx]] = np.arange(len(rx))
        k = lut[lab[vs, us]]
        map_x[vs, us] = base.map_x[ry[k], rx[k]]
        map_y[vs, us] = base.map_y[ry[k], rx[k]]
        # labels: the same points clamped into the rectangle LABEL_RIM px inside the edge (an
        # annotation rim is not replicated), unless that lands in the cut
        lab_x, lab_y = map_x.copy(), map_y.copy()
        rx_, ry_ = min(LABEL_RIM, (w - 1) / 2), min(LABEL_RIM, (h - 1) / 2)
        cx_ = np.clip(map_x[vs, us], rx_, w - 1 - rx_)
        cy_ = np.clip(map_y[vs, us], ry_, h - 1 - ry_)
        if region_src is not None:
            inside = region_src[np.rint(cy_).astype(np.int64), np.rint(cx_).astype(np.int64)] == 1
            cx_, cy_ = np.where(inside, cx_, map_x[vs, us]), np.where(inside, cy_, map_y[vs, us])
        lab_x[vs, us], lab_y[vs, us] = cx_, cy_
        return CompletionMaps(base, method, IGNORE, full=_finish(map_x, map_y, lab_x, lab_y, valid))

    # projective
    if vp is None:
        vp = ((valid.shape[1] - 1) / 2, (valid.shape[0] - 1) / 2)
    M = _src_H_dst(dst_H_src)
    centre, vp_inside = _centre(vp, M, src_size, valid.shape, region_src, region_dst)
    c_src, J = _to_source(M, centre)
    if c_src is None:  # cannot happen for a covered centre
        raise GeometryError("the completion centre has no source point", None, "check the VP")
    c_src = np.clip(c_src, [0, 0], [w - 1, h - 1])
    H = np.ascontiguousarray(dst_H_src, dtype=np.float64)
    angles = _angle_index(valid, centre, (H.tobytes(), tuple(src_size), base.size, centre))
    rays = _rays(angles.n, J, c_src, src_size, (H.tobytes(), tuple(src_size), base.size, centre))
    tx, ty, lx, ly = _exit_table(rays, src_size, region_src)
    fill = AngleFill(angles.table(tx), angles.table(ty), angles.table(lx), angles.table(ly))
    return CompletionMaps(base, method, IGNORE, centre, vp_inside, angles=angles, fill=fill)


_SCRATCH = threading.local()


def _scratch(shape: tuple[int, int, int]) -> np.ndarray:
    """A reused uint8 work buffer of ``shape`` for this thread (the packed BGRA image, which never
    leaves :meth:`CompletionMaps._fused`): a fresh one costs page faults, ~5 ms at 5500x2800."""
    buf = getattr(_SCRATCH, "buf", None)
    if buf is None or buf.shape != shape:
        buf = _SCRATCH.buf = np.empty(shape, dtype=np.uint8)
    return buf


_CACHE: "OrderedDict[tuple, CompletionMaps]" = OrderedDict()
_CACHE_MAX = 4


def completion_maps(dst_H_src: np.ndarray, src_size: tuple[int, int], dst_size: tuple[int, int], method: str,
                    vp: tuple[float, float] | None = None, src_ignore: np.ndarray | None = None) -> CompletionMaps:
    """Warp + completion maps for one (homography, sizes, method, VP, border-ignore mask), with a
    small LRU cache: in between-camera mode every image of a camera shares H and VP, so the maps
    are built once (per distinct ignore mask when labels cut the region)."""
    check_method(method)
    H = np.ascontiguousarray(dst_H_src, dtype=np.float64)
    if src_ignore is not None and src_ignore.shape != (src_size[1], src_size[0]):
        raise InputError(f"ignore mask is {src_ignore.shape[1]}x{src_ignore.shape[0]}, image is "
                         f"{src_size[0]}x{src_size[1]}", None, "labels must have the size of their images")
    if src_ignore is not None and not src_ignore.any():
        src_ignore = None
    mask_key = None if src_ignore is None else hashlib.sha1(np.packbits(src_ignore).tobytes()).hexdigest()
    vp_key = None if (vp is None or method != "projective") else (round(float(vp[0]), 9), round(float(vp[1]), 9))
    key = (H.tobytes(), tuple(src_size), tuple(dst_size), method, vp_key,
           mask_key if method in ("projective", "replicate") else None)
    return _lru(_CACHE, key, lambda: complete_maps(maps_for(H, src_size, dst_size), H, src_size, method, vp,
                                                   src_ignore if method in ("projective", "replicate") else None))


def clear_cache() -> None:
    """Forget the maps :func:`completion_maps` keeps, so the next call completes them afresh (a
    benchmark's cold start). The ray and angle tables they are built from stay cached, and so do the
    warp maps (:func:`vcprep.warp.clear_cache`)."""
    _CACHE.clear()
