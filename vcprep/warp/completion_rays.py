"""Ray geometry of the projective completion (:mod:`vcprep.warp.completion`), in the SOURCE image:
where a ray from the completion centre leaves the source rectangle (:func:`exit_points_rectangle`,
:func:`label_exit_points`) or a border-ignore cut (:func:`_exit_table`), and where the rays start
(:func:`_centre`: the VP, or the fallback when it lies outside the covered region)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import GeometryError

__all__ = ["exit_points_rectangle", "label_exit_points"]

INSET = 1.0            # px the image map steps inward from a cut (ignore) boundary
LABEL_RIM = 8          # source px: completed labels never take their value from this band along the image edge
FALLBACK_TOWARD = 0.1  # VP outside: move the nearest covered pixel this far toward the centroid


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
