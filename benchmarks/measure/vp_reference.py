"""Road vanishing points without our detector: the plain LSD + RANSAC baseline
(:func:`baseline_vp`) and the reference VP from a road label (:func:`reference_vp`,
:func:`kitti_reference_vp`; the rule is in benchmarks/camera_from_frames/vp.py's docstring).
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from vcprep.vp import prior_window, to_gray

STATIC = np.array([0, 1, 4, 5, 7])  # CamVid classes whose border with road is a real road edge (reference VP)


def baseline_vp(image: np.ndarray, iters: int = 500, min_len_px: float = 15.0, lower: float = 0.6,
                min_deg: float = 15.0, max_deg: float = 75.0, band_px: float = 3.0,
                seed: int = 0) -> tuple[float, float]:
    """The plain baseline of issue 17: OpenCV's LSD (default settings) on the grey image; segments
    kept if 15-75 deg from horizontal, longer than 15 px and with their midpoint in the lower 60 %
    of the image; ``iters`` RANSAC pairs (seeded), each pair's intersection scored by the summed
    length of the kept segments whose line passes within ``band_px`` px of it; the best
    intersection, unrefined. No prior, no camera. (Image centre if fewer than 2 segments.)"""
    h, w = image.shape[:2]
    lines = cv2.createLineSegmentDetector().detect(to_gray(image))[0]
    seg = np.zeros((0, 4)) if lines is None else lines.reshape(-1, 4).astype(np.float64)
    d = seg[:, 2:4] - seg[:, 0:2]
    L = np.hypot(d[:, 0], d[:, 1])
    ang = np.degrees(np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0])))
    mid_y = 0.5 * (seg[:, 1] + seg[:, 3])
    keep = (L > min_len_px) & (ang >= min_deg) & (ang <= max_deg) & (mid_y >= (1 - lower) * h)
    seg, L = seg[keep], L[keep]
    if len(seg) < 2:
        return (w / 2 - 0.5, h / 2 - 0.5)
    hom = np.cross(np.c_[seg[:, :2], np.ones(len(seg))], np.c_[seg[:, 2:], np.ones(len(seg))])
    hom /= np.linalg.norm(hom[:, :2], axis=1, keepdims=True)          # a u + b v + c = 0, (a, b) unit
    rng = np.random.default_rng(seed)
    i = rng.integers(0, len(seg), iters)
    j = rng.integers(0, len(seg), iters)
    X = np.cross(hom[i], hom[j])
    ok = (i != j) & (np.abs(X[:, 2]) > 1e-12)
    if not ok.any():
        return (w / 2 - 0.5, h / 2 - 0.5)
    X = X[ok, :2] / X[ok, 2:3]
    dist = np.abs(X @ hom[:, :2].T + hom[None, :, 2])                  # (candidates, segments) px
    score = (dist < band_px).astype(np.float64) @ L
    best = X[int(np.argmax(score))]
    return float(best[0]), float(best[1])


def _fit_side(ys: np.ndarray, xs: np.ndarray, band: float = 2.0, gate: bool = True):
    """RANSAC + LSQ line x = a*y + b; returns (a, b) or None if the fit is not good (rule 3).
    ``band``: RANSAC inlier band in px (the rule uses 2); ``gate=False`` skips the goodness
    tests. Both only serve to measure the reference's own sensitivity (camvid_vp_set)."""
    n = len(ys)
    if n < 25:
        return None
    i, j = np.triu_indices(n, 1)
    if len(i) > 4000:
        sel = np.linspace(0, len(i) - 1, 4000).astype(int)
        i, j = i[sel], j[sel]
    dy = ys[j] - ys[i]
    ok = np.abs(dy) >= 10
    i, j, dy = i[ok], j[ok], dy[ok]
    if len(i) == 0:
        return None
    a = (xs[j] - xs[i]) / dy
    b = xs[i] - a * ys[i]
    res = np.abs(xs[None, :] - (a[:, None] * ys[None, :] + b[:, None]))
    cnt = (res < band).sum(1)
    k = int(np.argmax(cnt))
    inl = res[k] < band
    A = np.c_[ys[inl], np.ones(inl.sum())]
    a, b = np.linalg.lstsq(A, xs[inl], rcond=None)[0]
    r = xs[inl] - (a * ys[inl] + b)
    span = ys[inl].max() - ys[inl].min()
    if gate and (inl.sum() < 25 or inl.mean() < 0.6 or span < 40 or math.sqrt(np.mean(r ** 2)) > 1.2):
        return None
    return float(a), float(b), float(ys[inl].min())


def reference_vp(label: np.ndarray, cam, band: float = 2.0, gate: bool = True) -> tuple[float, float] | None:
    """Reference road VP of a CamVid label image (the rule in benchmarks/camera_from_frames/vp.py's docstring), or None.
    ``band`` (rule 3's inlier band, 2 px) and ``gate`` (rule 3's goodness tests) are changed
    only to measure the reference's spread on frames the rule accepted."""
    return reference_from_masks(label == 3, np.isin(label, STATIC), cam, band, gate)


def kitti_reference_vp(gt: np.ndarray, cam) -> tuple[float, float] | None:
    """The same rule on a KITTI road ground truth (BGR colours): road = magenta; a road edge
    counts where the pixel outside is red (evaluated not-road), never black (outside the
    evaluated area)."""
    b, g, r = (gt[..., k].astype(int) for k in range(3))
    road = (r > 127) & (b > 127) & (g < 128)
    not_road = (r > 127) & (b < 128) & (g < 128)
    return reference_from_masks(road, not_road, cam)


def reference_from_masks(road: np.ndarray, edge_ok: np.ndarray, cam, band: float = 2.0,
                         gate: bool = True) -> tuple[float, float] | None:
    """Rule steps 1-4 on a road mask; ``edge_ok`` marks the pixels whose border with the road is
    a real road edge (static classes), so occluders never give boundary points."""
    road = road.astype(np.uint8)
    n, comp, stats, _ = cv2.connectedComponentsWithStats(road, connectivity=8)
    if n < 2:
        return None
    big = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    road = comp == big
    h, w = road.shape
    rows = np.flatnonzero(road.any(1))
    top = rows.min() + 0.15 * (rows.max() - rows.min())
    pts = {"l": ([], []), "r": ([], [])}
    for y in rows:
        if y < top:
            continue
        xs = np.flatnonzero(road[y])
        xl, xr = xs[0], xs[-1]
        if xr - xl < 12:
            continue
        if xl >= 3 and edge_ok[y, xl - 1]:
            pts["l"][0].append(y), pts["l"][1].append(xl - 0.5)
        if xr <= w - 4 and edge_ok[y, xr + 1]:
            pts["r"][0].append(y), pts["r"][1].append(xr + 0.5)
    fits = [_fit_side(np.array(pts[s][0], float), np.array(pts[s][1], float), band, gate) for s in ("l", "r")]
    if fits[0] is None or fits[1] is None:
        return None
    (al, bl, yl), (ar, br, yr) = fits
    ang = abs(math.degrees(math.atan(al) - math.atan(ar)))
    if ang < 8 or abs(al - ar) < 1e-9:
        return None
    y = (br - bl) / (al - ar)
    x = al * y + bl
    u0, v0, u1, v1 = prior_window(cam)
    if y >= min(yl, yr) or not (u0 <= x <= u1 and v0 <= y <= v1):
        return None
    return float(x), float(y)
