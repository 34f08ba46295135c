"""Road vanishing points (VPs) and the reliability rule for within-camera correction (paper §4.2).

Three layers (style.md):

* :func:`detect_segments` / :func:`estimate_vp` — pure, in memory: one image -> :class:`VPResult`;
* :func:`apply_reliability`, :func:`smooth_sequences` — the dataset rules over many results;
* :func:`estimate_files`, :func:`read_vp_csv`, :func:`write_vp_csv` — file I/O wrappers.

Conventions: a VP is (u, v) in pixels of the image as stored on disk, origin at the CENTRE of
the top-left pixel (method.md). Pan/tilt in degrees from :func:`vcprep.homography.pose_from_vp`.

The detector (measured in ``benchmarks/vp.py``):

1. grey image, downscaled (INTER_AREA) to at most ``work_width`` px wide; OpenCV LSD segments
   (internal scale ``lsd_scale``, standard refinement), mapped back to source pixels with the
   pixel-centre rule (LSD's own subsampling offset of 0.5 / scale - 0.5 px is corrected);
2. keep segments longer than ``min_length`` (fraction of the width) whose angle to the horizontal
   lies in [``min_angle_deg``, ``max_angle_deg``] and whose supporting line crosses the *prior
   window* — the VPs the camera can have under its average pose ± ``pan_range`` / ``tilt_range``;
3. sub-pixel re-fit (``subpixel``, :func:`refine_segments`): each kept segment's line is re-fitted
   to the gradient peaks of the FULL-resolution grey image across it, which removes the
   blur/quantisation error of a coarse LSD scale (synthetic median error 0.23 -> 0.11 % width);
4. weight = length ** ``length_power``, x ``above_weight`` for a segment lying above the candidate
   VP (the road is below its VP): lane markings, kerbs and road edges dominate, facades and wires
   count less; the square root of the length lets many agreeing segments outvote one long line
   crossing one clutter line;
5. candidates = intersections of the strongest segments plus a regular grid over the prior
   window; each is scored by a robust (Tukey) vote of every segment on the angle between the
   segment and the ray from its midpoint to the candidate (coarse-to-fine: all candidates
   against the ``n_coarse`` strongest segments, the best ``n_finalists`` against all), times a
   two-sided factor (``one_sided``: a mode whose support below it comes from one side of its
   vertical only - a kerb, a row of parked cars - loses up to 20 %) and a wide pose prior
   (``pose_sigma``: Gaussian in pan / tilt around the camera's average pose, sigma 1.25 x the
   reliability window, so an edge-of-window mode loses a near-tie); both in angles or ratios,
   never pixels (:func:`_scores`); the best is refined by iteratively reweighted least squares
   on its supporting segments, weighted by length ** ``refine_power`` (the direction of a
   longer segment is more precise: its angular error falls faster than 1 / sqrt(length), so the
   refinement trusts long lines more than the vote that picks the mode does). No randomness:
   deterministic.

Per image the result says how much it trusts the VP (``confidence`` = share of the line weight
that supports it, ``n_support`` = number of supporting segments). :func:`apply_reliability` then
applies method.md's rule: implied pan more than 20° or tilt more than 15° from the camera's
average pose, or fewer than ``min_support`` (7) supporting segments -> rejected and replaced by the
mean of the accepted VPs of its sequence (:func:`sequence_key`: one drive, one mount; when the
sequence has at least 3), else of the dataset (status ``fallback``). Means are taken over
normalised rays ((u - cx)/fx, (v - cy)/fy), so images of different (uniformly rescaled) sizes
average correctly. When no VP of the dataset is accepted, the camera's average-pose VP is the
fallback.
"""
from __future__ import annotations

import csv
import functools
import io
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

import cv2
import numpy as np

from .camera import Camera
from .errors import InputError
from .homography import pose_from_vp, vp_from_pose
from .imageio import read_text

__all__ = [
    "VPConfig",
    "VPResult",
    "STATUSES",
    "to_gray",
    "detect_segments",
    "refine_segments",
    "prior_window",
    "estimate_vp",
    "score_vps",
    "is_reliable",
    "apply_reliability",
    "MIN_SEQUENCE_ACCEPTED",
    "sequence_key",
    "smooth_sequences",
    "estimate_files",
    "read_vp_csv",
    "format_vp_csv",
    "write_vp_csv",
    "given_results",
    "vps_for_items",
]

#: final statuses of a VP: detected and reliable, replaced by the dataset mean, read from a file.
#: (``rejected`` is the intermediate status of :func:`estimate_vp` before the dataset rule.)
STATUSES = ("accepted", "fallback", "given")


@dataclass(frozen=True)
class VPConfig:
    """Detector parameters (defaults measured on synthetic and CamVid frames, benchmarks/vp.py)."""

    work_width: int = 480          # images wider than this are downscaled before line detection (px)
    lsd_scale: float = 0.5         # LSD's own internal scale (OpenCV default 0.8; 0.5 is ~2.5x faster;
                                   # the sub-pixel re-fit below restores the precision lost)
    lsd_refine: int = 1            # cv2.LSD_REFINE_STD (1: splits bent segments) or _NONE (0)
    min_length: float = 0.025      # shortest segment kept, as a fraction of the working width
    min_angle_deg: float = 8.0     # reject segments closer than this to horizontal
    max_angle_deg: float = 86.0    # reject segments steeper than this (poles, building edges)
    length_power: float = 0.5      # vote weight = length ** length_power (0.5: many agreeing segments
                                   # beat one long line + one clutter line; measured on synthetic + train)
    refine_power: float = 1.5      # weight = length ** refine_power in the final least-squares refinement
                                   # (a long segment's direction is more precise; synthetic median
                                   # 0.15 -> 0.11 % width, measured)
    above_weight: float = 0.3      # weight factor for segments lying above the candidate VP (not road)
    one_sided: float = 0.8         # score factor of a candidate supported from one side of the road only:
                                   # x (one_sided + (1 - one_sided) * 2 * min(L, R) / (L + R)), L / R = the
                                   # support below the candidate left / right of its vertical (1: off)
    pose_sigma: float = 1.25       # pose prior: score x exp(-(d_pan / (pose_sigma * pan_range))^2 / 2
                                   # - (d_tilt / (pose_sigma * tilt_range))^2 / 2) around the camera's
                                   # average pose (0: off); a wide, weak prior that breaks near-ties
                                   # against edge-of-window modes
    inlier_deg: float = 2.0        # a segment supports a VP if its angular residual is below this
    n_strong: int = 30             # strongest segments whose pairwise intersections are candidates
    max_segments: int = 150        # at most this many (strongest) segments vote
    grid_deg: float = 2.0          # step of the candidate grid over the prior window (degrees)
    n_coarse: int = 40             # candidates are first scored against this many strongest segments
    n_finalists: int = 24          # ... and the best this many against all segments
    pan_range: float = 20.0        # reliability rule: |pan - camera pan| <= pan_range (degrees)
    tilt_range: float = 15.0       # reliability rule: |tilt - camera tilt| <= tilt_range (degrees)
    min_support: int = 7           # fewer supporting segments -> rejected (dev: below 7, half the
                                   # detections were more than 10 % of the width off)
    subpixel: bool = True          # re-fit kept segments to the full-resolution gradient (refine_segments)


@dataclass(frozen=True)
class VPResult:
    """The road VP of one image.

    ``vp`` (u, v) source pixels; ``status`` one of :data:`STATUSES` (or ``rejected`` before
    :func:`apply_reliability`); ``reason`` says why a VP was rejected ('' otherwise);
    ``detected`` is the detector's own VP (None when it found none), kept when ``vp`` is replaced.
    ``segments`` (N, 4) x1, y1, x2, y2 in source pixels and ``support`` (N,) bool are for figures.
    """

    vp: tuple[float, float]
    confidence: float
    n_support: int
    pan_deg: float
    tilt_deg: float
    status: str
    reason: str = ""
    detected: tuple[float, float] | None = None
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)), repr=False, compare=False)
    support: np.ndarray = field(default_factory=lambda: np.zeros(0, bool), repr=False, compare=False)

    def to_dict(self) -> dict:
        """JSON-ready summary (no segment arrays)."""
        return {"vp": [round(float(self.vp[0]), 3), round(float(self.vp[1]), 3)],
                "confidence": round(float(self.confidence), 4), "n_support": int(self.n_support),
                "pan_deg": round(float(self.pan_deg), 4), "tilt_deg": round(float(self.tilt_deg), 4),
                "status": self.status, "reason": self.reason}


# --------------------------------------------------------------------------------------------
# segments


def to_gray(image: np.ndarray) -> np.ndarray:
    """Any decoded image (grey/BGR, 8/16-bit) -> uint8 grey."""
    img = image
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    elif img.dtype != np.uint8:
        img = np.clip(img, 0, 255).astype(np.uint8)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    return np.ascontiguousarray(img)


_LSD: dict[tuple[float, int], object] = {}


def _lsd(scale: float, refine: int = 0):
    key = (float(scale), int(refine))
    if key not in _LSD:  # stateless detector: one per setting and process
        _LSD[key] = cv2.createLineSegmentDetector(int(refine), float(scale))
    return _LSD[key]


def detect_segments(gray: np.ndarray, work_width: int = 480, lsd_scale: float = 0.5, lsd_refine: int = 1) -> np.ndarray:
    """LSD line segments of a grey image: (N, 4) float ``x1, y1, x2, y2`` in SOURCE pixels.

    An image wider than ``work_width`` is first resized by s = work_width / w (INTER_AREA);
    working pixel centres map back by ``u = (u' + 0.5) / s - 0.5``. LSD's own subsampling
    offset (``lsd_scale`` != 1) is corrected first, so a straight edge is reported where it is.
    """
    h, w = gray.shape[:2]
    if min(h, w) < 8:
        return np.zeros((0, 4))
    s = 1.0
    if w > work_width:
        s = work_width / w
        gray = cv2.resize(gray, (work_width, max(8, int(round(h * s)))), interpolation=cv2.INTER_AREA)
    sx, sy = gray.shape[1] / w, gray.shape[0] / h
    lines = _lsd(lsd_scale, lsd_refine).detect(gray)[0]
    if lines is None or len(lines) == 0:
        return np.zeros((0, 4))
    seg = lines.reshape(-1, 4).astype(np.float64)
    # OpenCV's LSD maps its internally subsampled coordinates back by x / scale, which puts
    # pixel centres (0.5 / scale - 0.5) px too far up-left (measured: -0.333 px at scale 0.6);
    # undo that so the working-image coordinates follow the pixel-centre rule
    seg += 0.5 / lsd_scale - 0.5
    seg[:, [0, 2]] = (seg[:, [0, 2]] + 0.5) / sx - 0.5
    seg[:, [1, 3]] = (seg[:, [1, 3]] + 0.5) / sy - 0.5
    return seg


@functools.lru_cache(maxsize=64)
def prior_window(cam: Camera, pan_range: float = 20.0, tilt_range: float = 15.0) -> tuple[float, float, float, float]:
    """Bounding box (u0, v0, u1, v1) in pixels of the VPs the camera can have with pan within
    ``pan_range`` and tilt within ``tilt_range`` degrees of its average pose (cached per camera)."""
    pts = [vp_from_pose(cam, cam.pan + a, cam.tilt + b)
           for a in np.linspace(-pan_range, pan_range, 5) for b in np.linspace(-tilt_range, tilt_range, 5)]
    p = np.array(pts)
    return float(p[:, 0].min()), float(p[:, 1].min()), float(p[:, 0].max()), float(p[:, 1].max())


def _line_crosses_box(seg: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
    """(N,) bool: the infinite line through each segment crosses the box (corners on both sides)."""
    u0, v0, u1, v1 = box
    corners = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
    d = seg[:, 2:4] - seg[:, 0:2]
    rel = corners[None, :, :] - seg[:, None, 0:2]                     # (N, 4, 2)
    side = d[:, None, 0] * rel[:, :, 1] - d[:, None, 1] * rel[:, :, 0]  # cross product sign
    return (side.min(axis=1) <= 0) & (side.max(axis=1) >= 0)


def _gradient_window(gray: np.ndarray, mx: np.ndarray, my: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The 3x3 Sobel gradient (x, y; float32, cv2.spatialGradient's values) of ``gray`` over the
    window that bilinear sampling at the points (mx, my) reads, and the window's top-left (x0, y0).

    The same numbers as the gradient of the whole image, sampled at (mx - x0, my - y0) with
    BORDER_REPLICATE: the window holds every pixel a sample reads (2 px to spare) and reaches the
    image edge wherever a sample is clamped to it; the Sobel is computed with a 1 px margin of
    real pixels (dropped after) except at the image edge, where both reflect alike."""
    h, w = gray.shape[:2]
    x0 = int(np.clip(np.floor(mx.min()) - 2, 0, w - 1))
    x1 = int(np.clip(np.floor(mx.max()) + 3, x0 + 1, w))
    y0 = int(np.clip(np.floor(my.min()) - 2, 0, h - 1))
    y1 = int(np.clip(np.floor(my.max()) + 3, y0 + 1, h))
    mx0, my0 = max(x0 - 1, 0), max(y0 - 1, 0)
    sub = gray[my0:min(y1 + 1, h), mx0:min(x1 + 1, w)]
    win = (slice(y0 - my0, y1 - my0), slice(x0 - mx0, x1 - mx0))
    gx = cv2.Sobel(sub, cv2.CV_32F, 1, 0, ksize=3)[win]
    gy = cv2.Sobel(sub, cv2.CV_32F, 0, 1, ksize=3)[win]
    return gx, gy, x0, y0


def refine_segments(gray: np.ndarray, seg: np.ndarray, samples: int = 16, half_width: float = 2.5,
                    step: float = 0.5) -> np.ndarray:
    """Sub-pixel re-fit of each segment's line to the gradient of ``gray`` (source pixels).

    ``samples`` points along each segment (5 %..95 % of its length) look for the peak of the
    gradient component along the segment's normal within +/- ``half_width`` px (bilinear
    samples every ``step`` px, parabolic peak interpolation, polarity of the segment's own
    edge); a line offset ``p + q * s`` (s in [0, 1] along the segment) is fitted to the peaks by
    weighted least squares (weight = gradient at the peak) and the endpoints are moved along the
    normal. A segment with fewer than half of its samples peaking inside the window is kept as
    is. Shapes: ``seg`` (N, 4) ``x1, y1, x2, y2`` -> (N, 4). Pixel-centre coordinates.
    """
    seg = np.asarray(seg, dtype=np.float64)
    if len(seg) == 0:
        return seg.copy()
    d = seg[:, 2:4] - seg[:, 0:2]
    t = d / (np.hypot(d[:, 0], d[:, 1])[:, None] + 1e-12)
    nrm = np.column_stack([-t[:, 1], t[:, 0]])
    s = np.linspace(0.05, 0.95, samples)
    o = np.arange(-half_width, half_width + 1e-9, step)
    n_seg, n_off = len(seg), len(o)
    pts = (seg[:, None, None, 0:2] + s[None, :, None, None] * d[:, None, None, :]
           + o[None, None, :, None] * nrm[:, None, None, :])                       # (N, K, O, 2)
    mx = pts[..., 0].reshape(n_seg * samples, n_off).astype(np.float32)
    my = pts[..., 1].reshape(n_seg * samples, n_off).astype(np.float32)
    gx, gy, x0, y0 = _gradient_window(gray, mx, my)
    mx -= np.float32(x0)  # exact: an integer shift of float32 values below 2**24
    my -= np.float32(y0)
    sx = cv2.remap(gx, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(n_seg, samples, n_off)
    sy = cv2.remap(gy, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(n_seg, samples, n_off)
    gp = sx * nrm[:, None, None, 0].astype(np.float32) + sy * nrm[:, None, None, 1].astype(np.float32)
    gp *= np.sign(gp.sum(axis=(1, 2)))[:, None, None]          # the segment's own edge polarity
    j = np.clip(np.argmax(gp, axis=2), 1, n_off - 2)
    a = np.take_along_axis(gp, (j - 1)[..., None], 2)[..., 0].astype(np.float64)
    b = np.take_along_axis(gp, j[..., None], 2)[..., 0].astype(np.float64)
    c = np.take_along_axis(gp, (j + 1)[..., None], 2)[..., 0].astype(np.float64)
    den = a - 2 * b + c
    sub = np.where(den < 0, 0.5 * (a - c) / np.where(den < 0, den, -1.0), 0.0)
    pos = o[j] + np.clip(sub, -0.5, 0.5) * step
    wt = np.clip(b, 0, None) * ((j > 1) & (j < n_off - 2))      # a peak at the window border is no peak
    A0, A1, A2 = wt.sum(1) + 1e-12, (wt * s).sum(1), (wt * s * s).sum(1)
    B0, B1 = (wt * pos).sum(1), (wt * pos * s).sum(1)
    det = A0 * A2 - A1 * A1
    ok = (det > 1e-9 * A0 * A0) & ((wt > 0).sum(1) >= samples // 2)
    safe = np.where(ok, det, 1.0)
    p0 = np.where(ok, (A2 * B0 - A1 * B1) / safe, 0.0)
    q = np.where(ok, (A0 * B1 - A1 * B0) / safe, 0.0)
    out = seg.copy()
    out[:, 0:2] += p0[:, None] * nrm
    out[:, 2:4] += (p0 + q)[:, None] * nrm
    return out


# --------------------------------------------------------------------------------------------
# voting


def _residual_sin(cands: np.ndarray, mid: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """|sin| of the angle between each segment direction and the ray midpoint -> candidate: (M, N)."""
    rx = cands[:, None, 0] - mid[None, :, 0]
    ry = cands[:, None, 1] - mid[None, :, 1]
    norm = np.sqrt(rx * rx + ry * ry) + 1e-9
    return np.abs(rx * dirs[None, :, 1] - ry * dirs[None, :, 0]) / norm


def _votes(cands: np.ndarray, mid: np.ndarray, dirs: np.ndarray, length: np.ndarray, tau: float,
           above_weight: float) -> np.ndarray:
    """(M, N) vote of each segment for each candidate VP (before the length weight).

    Tukey kernel (1 - (r/tau)^2)^2 on the angular residual r; x ``above_weight`` when the
    segment lies above the candidate (the road is below its VP); 0 when the candidate lies on
    the segment itself (its extent along the segment direction).
    """
    rx = cands[:, None, 0] - mid[None, :, 0]
    ry = cands[:, None, 1] - mid[None, :, 1]
    norm = np.sqrt(rx * rx + ry * ry) + 1e-9
    r = np.abs(rx * dirs[None, :, 1] - ry * dirs[None, :, 0]) / norm / tau
    v = np.clip(1.0 - r * r, 0.0, None)
    v *= v
    along = np.abs(rx * dirs[None, :, 0] + ry * dirs[None, :, 1])
    v *= along > 0.5 * length[None, :]
    return v * np.where(ry < 0, 1.0, above_weight)


def _scores(cands: np.ndarray, mid: np.ndarray, dirs: np.ndarray, length: np.ndarray, wts: np.ndarray,
            tau: float, cam: Camera, cfg: VPConfig) -> np.ndarray:
    """(M,) score of each candidate VP: the weighted vote (:func:`_votes` @ ``wts``), times

    * the two-sided factor ``one_sided + (1 - one_sided) * 2 * min(L, R) / (L + R)``, where L and R
      are the votes of the segments lying below the candidate, left and right of its vertical
      (a road's VP is approached from both of its edges; a kerb, a row of parked cars or a
      facade alone gives a one-sided mode);
    * the pose prior ``exp(-(d_pan / s_pan)^2 / 2 - (d_tilt / s_tilt)^2 / 2)``, d = the candidate's
      implied pose minus the camera's average pose, s = ``pose_sigma`` x the reliability window
      (``pan_range``, ``tilt_range``): angles, so the same for every camera and image size.
    """
    v = _votes(cands, mid, dirs, length, tau, cfg.above_weight) * wts[None, :]
    sc = v.sum(axis=1)
    if cfg.one_sided < 1.0:
        below = mid[None, :, 1] > cands[:, None, 1]
        left = mid[None, :, 0] < cands[:, None, 0]
        L = (v * (below & left)).sum(axis=1)
        R = (v * (below & ~left)).sum(axis=1)
        sc = sc * (cfg.one_sided + (1.0 - cfg.one_sided) * 2.0 * np.minimum(L, R) / (L + R + 1e-12))
    if cfg.pose_sigma > 0:
        x = (cands[:, 0] - cam.cx) / cam.fx
        y = (cands[:, 1] - cam.cy) / cam.fy
        d_pan = np.degrees(np.arctan(x)) - cam.pan              # pose_from_vp, vectorised
        d_tilt = np.degrees(np.arcsin(np.clip(-y / np.sqrt(x * x + y * y + 1.0), -1.0, 1.0))) - cam.tilt
        sc = sc * np.exp(-0.5 * (d_pan / (cfg.pose_sigma * cfg.pan_range)) ** 2
                         - 0.5 * (d_tilt / (cfg.pose_sigma * cfg.tilt_range)) ** 2)
    return sc


def _intersections(seg: np.ndarray) -> np.ndarray:
    """Pairwise intersections of the lines through ``seg`` (finite ones only): (M, 2)."""
    p1 = np.column_stack([seg[:, 0:2], np.ones(len(seg))])
    p2 = np.column_stack([seg[:, 2:4], np.ones(len(seg))])
    L = np.cross(p1, p2)
    i, j = np.triu_indices(len(seg), 1)
    X = np.cross(L[i], L[j])
    ok = np.abs(X[:, 2]) > 1e-9
    return X[ok, :2] / X[ok, 2:3]


def _refine(c: np.ndarray, seg: np.ndarray, mid: np.ndarray, dirs: np.ndarray, length: np.ndarray,
            wts: np.ndarray, tau: float, above_weight: float, iters: int = 5) -> np.ndarray:
    """IRLS: minimise sum_i w_i * (angular residual_i)^2 with the votes at the current VP as weights.

    The angular residual of line l_i (unit normal) at c is ``(l_i . c) / |c - m_i|``: a weighted
    linear least-squares problem in c for fixed distances |c - m_i|.
    """
    p1 = np.column_stack([seg[:, 0:2], np.ones(len(seg))])
    p2 = np.column_stack([seg[:, 2:4], np.ones(len(seg))])
    L = np.cross(p1, p2)
    L /= np.linalg.norm(L[:, :2], axis=1, keepdims=True) + 1e-12
    for _ in range(iters):
        tw = _votes(c[None], mid, dirs, length, tau, above_weight)[0]
        dist = np.linalg.norm(c[None] - mid, axis=1) + 1e-9
        w = wts * tw / dist ** 2
        if np.count_nonzero(w) < 2:
            break
        A = L[:, :2] * np.sqrt(w)[:, None]
        b = -L[:, 2] * np.sqrt(w)
        M = A.T @ A
        if np.linalg.cond(M) > 1e10:
            break
        c_new = np.linalg.solve(M, A.T @ b)
        done = np.linalg.norm(c_new - c) < 1e-3
        c = c_new
        if done:
            break
    return c


def _result(cam: Camera, vp, confidence: float, n_support: int, status: str, reason: str = "",
            detected=None, segments=None, support=None) -> VPResult:
    pan, tilt = pose_from_vp(cam, vp)
    return VPResult(vp=(float(vp[0]), float(vp[1])), confidence=float(confidence), n_support=int(n_support),
                    pan_deg=float(pan), tilt_deg=float(tilt), status=status, reason=reason,
                    detected=None if detected is None else (float(detected[0]), float(detected[1])),
                    segments=np.zeros((0, 4)) if segments is None else segments,
                    support=np.zeros(0, bool) if support is None else support)


def is_reliable(cam: Camera, pan: float, tilt: float, n_support: int, cfg: VPConfig = VPConfig()) -> str:
    """'' if a VP passes the reliability rule (method.md), else the reason it is rejected."""
    if n_support < cfg.min_support:
        return f"too little support ({n_support} segments < {cfg.min_support})"
    if abs(pan - cam.pan) > cfg.pan_range:
        return f"pan {pan:.1f} deg is more than {cfg.pan_range:g} deg from the camera's {cam.pan:g}"
    if abs(tilt - cam.tilt) > cfg.tilt_range:
        return f"tilt {tilt:.1f} deg is more than {cfg.tilt_range:g} deg from the camera's {cam.tilt:g}"
    return ""


def _own_crop(image: np.ndarray, cam: Camera) -> tuple[np.ndarray, Camera]:
    """Check the image size against ``cam``; a camera with ``ego_rows`` -> the exact bottom crop
    without them and its camera (VP coordinates stay those of the whole frame)."""
    h, w = image.shape[:2]
    if (w, h) != tuple(cam.size):
        raise InputError(f"image is {w}x{h} but the camera is for {cam.size[0]}x{cam.size[1]}", None,
                         "use camera.for_image_size(...) first")
    if cam.ego_rows:
        return image[: h - cam.ego_rows], cam.without_ego()
    return image, cam


@dataclass(frozen=True)
class _Voters:
    """The segments that vote, strongest first: ``seg`` (K, 4) (sub-pixel re-fitted), their vote
    weights ``wts``, lengths ``seg_len``, midpoints ``mid`` and unit directions ``dirs``; ``idx``
    their rows in ``all_seg`` (every detected segment); ``box`` the prior window."""

    all_seg: np.ndarray
    idx: np.ndarray
    seg: np.ndarray
    wts: np.ndarray
    seg_len: np.ndarray
    mid: np.ndarray
    dirs: np.ndarray
    box: tuple[float, float, float, float]


def _voters(image: np.ndarray, cam: Camera, cfg: VPConfig, segments: np.ndarray | None = None) -> _Voters:
    """Steps 1-3 of the detector (module docstring): detect, filter, rank and re-fit segments."""
    w = image.shape[1]
    gray = to_gray(image)
    seg = detect_segments(gray, cfg.work_width, cfg.lsd_scale, cfg.lsd_refine) if segments is None else np.asarray(segments, float).reshape(-1, 4)
    all_seg = seg
    d = seg[:, 2:4] - seg[:, 0:2]
    length = np.hypot(d[:, 0], d[:, 1])
    ang = np.degrees(np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0]) + 1e-12))
    box = prior_window(cam, cfg.pan_range, cfg.tilt_range)
    scale = min(1.0, cfg.work_width / w)  # lengths are judged at the working resolution
    keep = ((length * scale >= cfg.min_length * min(w, cfg.work_width)) & (ang >= cfg.min_angle_deg)
            & (ang <= cfg.max_angle_deg))
    if len(seg):
        keep &= _line_crosses_box(seg, box)
    idx = np.flatnonzero(keep)
    # vote weight = length (the road-below-VP factor is applied per candidate in _votes)
    wts_all = length ** cfg.length_power
    idx = idx[np.argsort(-wts_all[idx], kind="stable")][: cfg.max_segments]
    seg, wts, seg_len = seg[idx], wts_all[idx], length[idx]
    if cfg.subpixel and len(seg) >= 2:
        seg = refine_segments(gray, seg)
    mid = 0.5 * (seg[:, 0:2] + seg[:, 2:4])
    dirs = (seg[:, 2:4] - seg[:, 0:2]) / (np.hypot(*(seg[:, 2:4] - seg[:, 0:2]).T)[:, None] + 1e-12)
    return _Voters(all_seg, idx, seg, wts, seg_len, mid, dirs, box)


def score_vps(image: np.ndarray, cam: Camera, points, cfg: VPConfig = VPConfig()) -> np.ndarray:
    """The detector's own score (the vote, two-sided factor and pose prior of step 5) at each of
    ``points`` (M, 2) source pixels, from the same segments :func:`estimate_vp` votes with: (M,).

    What it is for: telling a search miss from a disagreement of definitions. If a reference VP
    scores higher than the detection, the search missed a better mode; if it scores lower, the
    image's lines (as the detector weighs them) converge elsewhere than the reference says.
    Zeros when fewer than 2 segments vote.
    """
    image, cam = _own_crop(image, cam)
    pts = np.asarray(points, float).reshape(-1, 2)
    v = _voters(image, cam, cfg)
    if len(v.idx) < 2:
        return np.zeros(len(pts))
    return _scores(pts, v.mid, v.dirs, v.seg_len, v.wts, math.sin(math.radians(cfg.inlier_deg)), cam, cfg)


def estimate_vp(image: np.ndarray, cam: Camera, cfg: VPConfig = VPConfig(),
                segments: np.ndarray | None = None) -> VPResult:
    """The road VP of one image; ``cam`` must be calibrated for this image's size.

    Returns status 'accepted', or 'rejected' with a ``reason`` and ``vp`` = the camera's
    average-pose VP (the dataset rule :func:`apply_reliability` replaces it). ``segments``
    (N, 4) may be given to skip line detection. Never raises on image content. A camera with
    ``ego_rows`` (its own vehicle at the bottom) is read as the exact bottom crop without them:
    no line of the rig votes, and the VP's coordinates are those of the whole frame.
    """
    image, cam = _own_crop(image, cam)
    prior = vp_from_pose(cam)
    v = _voters(image, cam, cfg, segments)
    all_seg, idx = v.all_seg, v.idx
    support_all = np.zeros(len(all_seg), bool)

    def rejected(reason, n=0, conf=0.0, detected=None):
        return _result(cam, prior, conf, n, "rejected", reason, detected, all_seg, support_all)

    if len(idx) < 2:
        return rejected(f"too little support ({len(idx)} usable line segments)")
    seg, wts, seg_len, mid, dirs, box = v.seg, v.wts, v.seg_len, v.mid, v.dirs, v.box
    tau = math.sin(math.radians(cfg.inlier_deg))
    # candidates: intersections of the strongest segments inside the (slightly enlarged) window
    u0, v0, u1, v1 = box
    mu, mv = 0.1 * (u1 - u0), 0.1 * (v1 - v0)
    X = _intersections(seg[: cfg.n_strong])
    X = X[(X[:, 0] >= u0 - mu) & (X[:, 0] <= u1 + mu) & (X[:, 1] >= v0 - mv) & (X[:, 1] <= v1 + mv)]
    pans = np.arange(-cfg.pan_range, cfg.pan_range + 1e-9, cfg.grid_deg) + cam.pan
    tilts = np.arange(-cfg.tilt_range, cfg.tilt_range + 1e-9, cfg.grid_deg) + cam.tilt
    ta = np.tan(np.radians(pans))
    # VP of (pan a, tilt b): u = cx + fx tan a, v = cy - fy tan b / cos a
    G = np.stack([np.broadcast_to(cam.cx + cam.fx * ta[:, None], (len(pans), len(tilts))),
                  cam.cy - cam.fy * np.tan(np.radians(tilts))[None, :] / np.cos(np.radians(pans))[:, None]],
                 axis=-1).reshape(-1, 2)
    cands = np.vstack([X, G]) if len(X) else G
    # coarse-to-fine scoring: every candidate against the strongest segments, then the best
    # few against all of them (the ranking rarely changes, the cost drops ~4x)
    if len(cands) > cfg.n_finalists and len(seg) > cfg.n_coarse:
        n = cfg.n_coarse
        sc0 = _scores(cands, mid[:n], dirs[:n], seg_len[:n], wts[:n], tau, cam, cfg)
        cands = cands[np.argsort(-sc0, kind="stable")[: cfg.n_finalists]]
    sc = _scores(cands, mid, dirs, seg_len, wts, tau, cam, cfg)
    best = cands[int(np.argmax(sc))]
    c = _refine(best.astype(float), seg, mid, dirs, seg_len, seg_len ** cfg.refine_power, tau, cfg.above_weight)
    # keep the refinement only if it stays finite, near the window and at least as well supported
    if (not np.all(np.isfinite(c)) or not (u0 - mu <= c[0] <= u1 + mu and v0 - mv <= c[1] <= v1 + mv)
            or _scores(c[None], mid, dirs, seg_len, wts, tau, cam, cfg)[0] < 0.95 * sc.max()):
        c = best.astype(float)
    votes = _votes(c[None], mid, dirs, seg_len, tau, cfg.above_weight)[0]
    sup = votes > 0
    n_sup = int(sup.sum())
    conf = float(votes @ wts / (wts.sum() + 1e-12))
    support_all[idx[sup]] = True
    pan, tilt = pose_from_vp(cam, c)
    reason = is_reliable(cam, pan, tilt, n_sup, cfg)
    if reason:
        return rejected(reason, n_sup, conf, c)
    return _result(cam, c, conf, n_sup, "accepted", "", c, all_seg, support_all)


# --------------------------------------------------------------------------------------------
# dataset rules


def _ray(cam: Camera, vp) -> np.ndarray:
    return np.array([(vp[0] - cam.cx) / cam.fx, (vp[1] - cam.cy) / cam.fy])


def _from_ray(cam: Camera, r) -> tuple[float, float]:
    return float(cam.cx + cam.fx * r[0]), float(cam.cy + cam.fy * r[1])


#: a rejected VP falls back to its sequence's mean when the sequence has at least this many accepted VPs
MIN_SEQUENCE_ACCEPTED = 3


def apply_reliability(results: Sequence[VPResult], cams: Sequence[Camera],
                      ids: Sequence[str] | None = None) -> list[VPResult]:
    """Replace every non-accepted result by a mean of accepted VPs (status 'fallback').

    ``cams[i]`` is the camera of image i at its own size. Means are over normalised rays, so
    they are the same direction for every image size. With ``ids``, the images are grouped into
    sequences (:func:`sequence_key`: one drive, one mount) and a rejected VP takes the mean of
    its own sequence's accepted VPs when there are at least :data:`MIN_SEQUENCE_ACCEPTED`
    (CamVid's 0001TP rig looks 4.3 deg further down than the other two: the dataset mean would
    tilt its rejected frames by that much); otherwise, and without ``ids``, the mean of all
    accepted VPs. With no accepted VP at all, each image falls back to its camera's
    average-pose VP. The reason says which. 'given' results pass through and count as accepted.
    """
    ok = [r.status in ("accepted", "given") for r in results]
    rays = [_ray(c, r.vp) if k else None for r, c, k in zip(results, cams, ok)]
    acc = [x for x in rays if x is not None]
    mean = np.mean(acc, axis=0) if acc else None
    seq_mean: dict[str, tuple[np.ndarray, int]] = {}
    if ids is not None:
        if len(ids) != len(results):
            raise ValueError(f"{len(ids)} ids for {len(results)} results")
        groups: dict[str, list[np.ndarray]] = {}
        for iid, x in zip(ids, rays):
            if x is not None:
                groups.setdefault(sequence_key(iid), []).append(x)
        seq_mean = {k: (np.mean(v, axis=0), len(v)) for k, v in groups.items() if len(v) >= MIN_SEQUENCE_ACCEPTED}
    out = []
    for i, (r, c) in enumerate(zip(results, cams)):
        if ok[i]:
            out.append(r)
            continue
        key = sequence_key(ids[i]) if ids is not None else None
        if key in seq_mean:
            m, n = seq_mean[key]
            vp, why = _from_ray(c, m), f"mean of the {n} accepted VPs of sequence {key}"
        elif mean is not None:
            vp, why = _from_ray(c, mean), f"mean of {len(acc)} accepted VPs"
        else:
            vp, why = vp_from_pose(c), "camera average pose (no accepted VP in the dataset)"
        reason = f"{r.reason or 'rejected'}; replaced by the {why}"
        pan, tilt = pose_from_vp(c, vp)
        out.append(replace(r, vp=(float(vp[0]), float(vp[1])), pan_deg=float(pan), tilt_deg=float(tilt),
                           status="fallback", reason=reason))
    return out


_SEQ_RE = re.compile(r"^(.+?)_")


def sequence_key(image_id: str) -> str:
    """The sequence an image belongs to: its id up to the first '_' (CamVid ``0016E5_07959`` ->
    ``0016E5``); an id without '_' is a sequence of its own."""
    m = _SEQ_RE.match(image_id)
    return m.group(1) if m else image_id


def smooth_sequences(ids: Sequence[str], results: Sequence[VPResult], cams: Sequence[Camera],
                     window: int = 2) -> list[VPResult]:
    """Temporal smoothing of VPs over consecutive frames (VPSeg: VPs of a video are coherent).

    Frames are grouped by :func:`sequence_key` and ordered by id (zero-padded frame numbers sort
    in time order). Each accepted or fallback VP becomes the median (per normalised-ray
    coordinate) of the accepted VPs among the ``window`` frames either side and itself; a frame
    with no accepted neighbour keeps its VP. 'given' VPs are never changed. Apply after
    :func:`apply_reliability`.
    """
    if window <= 0:
        return list(results)
    groups: dict[str, list[int]] = {}
    for i, iid in enumerate(ids):
        groups.setdefault(sequence_key(iid), []).append(i)
    out = list(results)
    for members in groups.values():
        members.sort(key=lambda i: ids[i])
        for k, i in enumerate(members):
            r = results[i]
            if r.status == "given":
                continue
            near = [members[j] for j in range(max(0, k - window), min(len(members), k + window + 1))]
            rays = [_ray(cams[j], results[j].vp) for j in near if results[j].status == "accepted"]
            if not rays:
                continue
            vp = _from_ray(cams[i], np.median(np.array(rays), axis=0))
            pan, tilt = pose_from_vp(cams[i], vp)
            out[i] = replace(r, vp=vp, pan_deg=float(pan), tilt_deg=float(tilt),
                             status="accepted" if r.status == "accepted" else "fallback",
                             reason=(r.reason + "; " if r.reason else "") + f"smoothed over {len(rays)} frames")
    return out


# --------------------------------------------------------------------------------------------
# files


def estimate_files(images: Sequence[str | Path], camera: Camera, cfg: VPConfig = VPConfig(), smooth: int = 0,
                   ids: Sequence[str] | None = None,
                   on_image: Callable[[int], None] | None = None) -> list[VPResult]:
    """Detect the VP of every image file, then apply the reliability rule (and ``smooth``).

    ``camera`` is rescaled to each image's size (uniform rescales only, else InputError).
    ``ids`` (default: file stems) define sequences for smoothing. ``on_image(i)`` is called after
    each image (progress).
    """
    from .imageio import read_image

    results, cams = [], []
    for i, p in enumerate(images):
        img = read_image(p).array
        cam = camera.for_image_size((img.shape[1], img.shape[0]), p)
        results.append(estimate_vp(img, cam, cfg))
        cams.append(cam)
        if on_image is not None:
            on_image(i)
    ids = list(ids) if ids is not None else [Path(p).stem for p in images]
    results = apply_reliability(results, cams, ids)
    if smooth > 0:
        results = smooth_sequences(ids, results, cams, smooth)
    return results


def read_vp_csv(path: str | Path) -> dict[str, tuple[float, float]]:
    """Read known VPs from a CSV ``id,u,v`` (u, v in source pixels of the image as stored).

    A first row ``id,u,v`` is a header; further columns are ignored; blank lines and lines
    starting with '#' are skipped. A row with a missing field, a number that does not parse or
    is not finite, or an id seen before raises :class:`InputError` naming the line.
    """
    path = Path(path)
    text = read_text(path, "VP file", "give a CSV with columns id,u,v")
    vps: dict[str, tuple[float, float]] = {}
    lines: dict[str, int] = {}
    first = True
    for n, row in enumerate(csv.reader(io.StringIO(text)), 1):
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in row]
        if first and [c.lower() for c in cells[:3]] == ["id", "u", "v"]:
            first = False
            continue
        first = False
        if len(cells) < 3 or not cells[0] or not cells[1] or not cells[2]:
            raise InputError(f"line {n}: expected 'id,u,v', got {','.join(row)!r}", path,
                             "give every row an image id and the VP's u and v in pixels")
        iid = cells[0]
        try:
            u, v = float(cells[1]), float(cells[2])
        except ValueError:
            raise InputError(f"line {n} ('{iid}'): u, v must be numbers, got {cells[1]!r}, {cells[2]!r}", path,
                             "write the VP as pixel coordinates, e.g. 241.5,180.0") from None
        if not (math.isfinite(u) and math.isfinite(v)):
            raise InputError(f"line {n} ('{iid}'): u, v must be finite, got {cells[1]}, {cells[2]}", path,
                             "write the VP as finite pixel coordinates")
        if iid in vps:
            raise InputError(f"line {n}: duplicate id '{iid}' (first on line {lines[iid]})", path,
                             "keep one VP per image id")
        vps[iid] = (u, v)
        lines[iid] = n
    if not vps:
        raise InputError("VP file has no rows", path, "write one 'id,u,v' row per image")
    return vps


def format_vp_csv(ids: Iterable[str], results: Iterable[VPResult]) -> str:
    """CSV text ``id,u,v,status,confidence,n_support,pan_deg,tilt_deg`` with a header row
    (readable by :func:`read_vp_csv`, which uses the first three columns)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["id", "u", "v", "status", "confidence", "n_support", "pan_deg", "tilt_deg"])
    for iid, r in zip(ids, results):
        w.writerow([iid, f"{r.vp[0]:.3f}", f"{r.vp[1]:.3f}", r.status, f"{r.confidence:.4f}", r.n_support,
                    f"{r.pan_deg:.4f}", f"{r.tilt_deg:.4f}"])
    return buf.getvalue()


def write_vp_csv(path: str | Path, ids: Iterable[str], results: Iterable[VPResult]) -> None:
    """Write :func:`format_vp_csv` to ``path`` atomically."""
    from .imageio import write_bytes_atomic

    try:
        write_bytes_atomic(path, format_vp_csv(ids, results).encode())
    except (FileNotFoundError, NotADirectoryError):
        raise InputError("cannot write here (parent folder missing)", path, "create the folder first") from None


def given_results(vps: Mapping[str, tuple[float, float]], ids: Sequence[str], cams: Sequence[Camera],
                  file: str | Path | None = None) -> list[VPResult]:
    """Results with status 'given' for ``ids`` from a VP table; a missing id raises InputError."""
    missing = [i for i in ids if i not in vps]
    if missing:
        more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
        raise InputError(f"no VP row for image id '{missing[0]}'{more}", file,
                         "add an 'id,u,v' row for every image (ids are file stems)")
    return [_result(c, vps[i], 1.0, 0, "given", detected=vps[i]) for i, c in zip(ids, cams)]


def vps_for_items(images: Sequence[str | Path], ids: Sequence[str], camera: Camera, within: str,
                  smooth: int = 0, cfg: VPConfig = VPConfig(), id_prefix: str = "",
                  on_image: Callable[[int], None] | None = None) -> list[VPResult]:
    """Per-image VPs for within-camera correction: ``within`` is 'estimate' (detector + reliability
    rule + optional smoothing) or the path of a CSV ``id,u,v`` (status 'given'; every id must
    have a row; an id is looked up as given, then without ``id_prefix``)."""
    from .camera import camera_of_image

    if within == "estimate":
        if not isinstance(camera, Camera):
            raise InputError("VP estimation needs one camera; a per-frame calibration folder already gives every "
                             "frame its exact pose", camera.folder, "use the calibrated poses (no --within)")
        return estimate_files(images, camera, cfg, smooth, ids, on_image)
    path = Path(within)
    table = read_vp_csv(path)
    keys = [i if i in table or not (id_prefix and i.startswith(id_prefix)) else i[len(id_prefix):] for i in ids]
    from .imageio import image_size

    cams = [camera_of_image(camera, p, image_size(p)) for p in images]  # (per-frame calibration: each its own)
    res = given_results(table, keys, cams, path)
    for (u, v), c, k in zip((r.vp for r in res), cams, keys):
        w, h = c.size
        if not (-10 * w <= u <= 11 * w and -10 * h <= v <= 11 * h):
            raise InputError(f"VP of '{k}' ({u:g}, {v:g}) is far outside its {w}x{h} image", path,
                             "give u, v in pixels of the image as stored on disk")
    return res
