"""Line segments for the road VP detector (:mod:`vcprep.vp`, steps 1-3): grey
conversion, OpenCV LSD segments in source pixels (:func:`detect_segments`), the prior window of
the VPs a camera can have (:func:`prior_window`) and the sub-pixel re-fit of a segment to the
full-resolution gradient (:func:`refine_segments`). Pure, in memory."""
from __future__ import annotations

import functools

import cv2
import numpy as np

from ..camera.pinhole import Camera
from ..warp.homography import vp_from_pose

__all__ = ["to_gray", "detect_segments", "prior_window", "refine_segments"]



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
