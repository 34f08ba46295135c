"""The road VP of one image (:mod:`vcprep.vp`, steps 4-5 of the detector): the
detector's parameters (:class:`VPConfig`) and result (:class:`VPResult`), the robust vote of the
segments for candidate VPs, :func:`estimate_vp`, :func:`score_vps` and the per-image reliability
rule :func:`is_reliable`. Pure, in memory: one image -> :class:`VPResult`."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..camera.pinhole import Camera
from ..errors import InputError
from ..warp.homography import pose_from_vp, vp_from_pose
from .segments import _line_crosses_box, detect_segments, prior_window, refine_segments, to_gray

__all__ = ["VPConfig", "VPResult", "STATUSES", "estimate_vp", "score_vps", "is_reliable"]

#: final statuses of a VP: detected and reliable, replaced by the dataset mean, read from a file.
#: (``rejected`` is the intermediate status of :func:`estimate_vp` before the dataset rule.)
STATUSES = ("accepted", "fallback", "given")


@dataclass(frozen=True)
class VPConfig:
    """Detector parameters (defaults measured on synthetic and CamVid frames, benchmarks/camera_from_frames/vp.py)."""

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
