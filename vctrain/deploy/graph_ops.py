"""The road graph's tensor operations (:mod:`vctrain.deploy.export`): OpenCV's bilinear sampling and
resize written as ONNX-exportable torch ops, and the homography and projective completion of a
VP given at run time, in float64 (:func:`_store_maps_from_vp`; traced with float64 scalars,
:func:`vctrain.deploy.engine.trace_onnx`).

Sampling convention: every bilinear sample is the one OpenCV computes -- source coordinates
rounded to 1/32 px, weights from those fractions, 8-bit images rounded half up (``cv2.remap``
on uint8; the store holds exactly that), float maps with float weights (``cv2.warpPerspective``
for the back-projection). Layout for onnxruntime (whose gathers cost per index, not per byte):
the warp gathers 6-byte pixel pairs (:func:`_sample_u8`, addressed by :func:`_pair_rows`), the
fixed mount's back-projection each pixel's four taps at once (:func:`_sample_f`), only in the
box of frame pixels that see the store; the fixed mount's taps are constants (int32 pair rows
and indices, int16 fractions to 1/65536: the fill table's float fractions lose < 2e-5 px).
With a VP at run time the completion's exit points are a 1-D table over the fill table's angles
(every pixel reads its angle's entry), the angle index is a constant while the ray centre is the
mount pose's (every VP in the image), and the back-projection is GridSample in bands of rows
(:func:`_backproject_grid`) over the box of pixels that see the store at some pose in the range.
"""
from __future__ import annotations

import math

import numpy as np
import torch
from torch.nn import functional as F

from vcprep.camera import Camera

TABLE_ARC, FALLBACK_TOWARD = 0.5, 0.1  # as vcprep.warp.completion (checked by vctrain.deploy.export against its constants)



# -- OpenCV's bilinear sampling as tensor ops ---------------------------------------------------------

def _padded_width(w: int) -> int:
    """Width of an image of width ``w`` padded by :func:`_padded`: one zero column left, one or
    two right (an even width, so that the padded image splits into pixel pairs)."""
    return w + 2 + w % 2


def _padded(img: torch.Tensor) -> torch.Tensor:
    """``img`` (h, w[, C]) with zeros around it (one row above and below, :func:`_padded_width`),
    flattened to ((h+2) * padded width[, C])."""
    right = 1 + img.shape[1] % 2
    p = F.pad(img, (1, right, 1, 1) if img.dim() == 2 else (0, 0, 1, right, 1, 1))
    return p.reshape((p.shape[0] * p.shape[1],) + tuple(p.shape[2:]))


def _taps(x: torch.Tensor, y: torch.Tensor, w: int, h: int,
          inside: bool = False) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Bilinear taps of source coordinates ``x``/``y`` (float32 px, pixel centres at integers, shape
    (S,)) in a ``w`` x ``h`` image padded by :func:`_padded`: the flat index (int32) of each
    top-left tap in the padded image and the fractions ``ax``, ``ay`` (float32) toward the right and
    lower taps. A tap outside the image reads the zero border (BORDER_CONSTANT); a coordinate more
    than one pixel outside reads the corner's zeros (index 0, fractions 0).

    This is OpenCV's arithmetic: with coordinates already rounded to 1/32 px (what ``cv2.remap``
    does with fixed-point maps, :func:`_fixed_point`) every fraction is a multiple of 1/32 and each
    step of :func:`_sample_u8` is exact in float32 and equals OpenCV's integer result; with plain
    float32 coordinates it is OpenCV 5's float-map path (float weights), which the completion's
    fill table and ``warpPerspective`` use. ``inside``: every coordinate is known to lie in
    [0, w-1] x [0, h-1] (maps with projective completion), so no test is needed."""
    x0, y0 = torch.floor(x), torch.floor(y)
    if inside:
        return ((y0 + 1) * _padded_width(w) + (x0 + 1)).to(torch.int32), x - x0, y - y0
    ok = (x0 >= -1) & (x0 <= w - 1) & (y0 >= -1) & (y0 <= h - 1)
    zero = torch.zeros_like(x)
    idx = (y0.clamp(-1, h - 1) + 1) * _padded_width(w) + (x0.clamp(-1, w - 1) + 1)
    return (torch.where(ok, idx, zero).to(torch.int32), torch.where(ok, x - x0, zero),
            torch.where(ok, y - y0, zero))


def _quads(src: torch.Tensor, w: int) -> torch.Tensor:
    """Every pixel of the padded map ``src`` (P,) (:func:`_padded` of a ``w``-wide map) with its
    right, lower and lower-right neighbours: (P - W2 - 1, 4), W2 the padded width. A sample's four
    taps are one row of it: one gather per sample (onnxruntime's gathers cost per index)."""
    W2 = _padded_width(w)
    n = src.shape[0] - W2 - 1
    return torch.stack([src[0:n], src[1:n + 1], src[W2:W2 + n], src[W2 + 1:W2 + 1 + n]], -1)


def _pair_rows(idx: torch.Tensor, w: int, h: int) -> torch.Tensor:
    """The row (int32) of :func:`_sample_u8`'s pair table holding the pixel pair that starts at
    each tap index ``idx`` of :func:`_taps` in the padded ``w`` x ``h`` image: the pairs that
    start at even pixels come first, then those at odd ones."""
    idx = idx.to(torch.int32)
    odd = idx % 2
    return torch.div(idx - odd, 2, rounding_mode="trunc") + odd * ((h + 2) * _padded_width(w) // 2)


def _sample_u8(src: torch.Tensor, w: int, rows: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """Bilinear samples (float32 (3, S), rounded half up: what ``cv2.remap`` writes to uint8) of
    the padded uint8 image ``src`` (P, 3) (:func:`_padded` of a ``w``-wide image) at the taps of
    :func:`_taps`, their index given as :func:`_pair_rows`. One gather of 6-byte pixel pairs (the
    padded image read as pairs starting at even pixels, then at odd ones): the upper pair and the
    lower pair (the padded width is even: the same parity, half a padded row further) of every
    sample; then two linear interpolations along x and one along y (channels first: what the
    network takes)."""
    n = src.shape[0]  # even (padded width even)
    pairs = torch.cat([src.reshape(n // 2, 6), src[1:n - 1].reshape(n // 2 - 1, 6)], 0)
    rows = torch.cat([rows, rows + _padded_width(w) // 2])  # (2S): the upper and lower pairs
    v = torch.index_select(pairs, 0, rows).reshape(2, -1, 2, 3).permute(0, 2, 3, 1).to(torch.float32)
    left, right = v[:, 0], v[:, 1]  # (2, 3, S): upper and lower row
    row = left + ax * (right - left)
    return torch.floor(row[0] + ay * (row[1] - row[0]) + 0.5)


def _sample_f(src: torch.Tensor, w: int, idx: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """Bilinear samples (float32 (S,)) of the padded float map ``src`` (P,) (:func:`_padded` of a
    ``w``-wide map) at the taps of :func:`_taps`: one gather of each sample's four taps (a (P, 4)
    table of every pixel with its right, lower and lower-right neighbours), weighted and summed."""
    quads = _quads(src, w)
    wts = torch.stack([(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay], -1)
    return (torch.index_select(quads, 0, idx.to(torch.int32)) * wts).sum(-1)


GRID_BAND = 128  # rows per GridSample of the back-projection (benchmarks/speed/deploy.py)
FRACTION = 65536  # fixed-mount fractions are stored as int16: round(a * FRACTION) - 32768


def _store_fraction(a: torch.Tensor) -> torch.Tensor:
    """int16 of a fraction in [0, 1] (1.0 occurs: ``x - floor(x)`` of a tiny negative float32)."""
    return (torch.round(a.double() * FRACTION) - 32768).clamp(-32768, 32767).to(torch.int16)


def _load_fraction(q: torch.Tensor) -> torch.Tensor:
    return (q.to(torch.float32) + 32768) * (1 / FRACTION)


def _resize_taps(n_in: int, n_out: int):
    """``cv2.resize`` INTER_LINEAR's taps and 11-bit weights along one axis (uint8 images)."""
    f = ((np.arange(n_out) + 0.5) * (1.0 / (n_out / n_in)) - 0.5).astype(np.float32)
    i0 = np.floor(f).astype(np.int64)
    a = (f - i0.astype(np.float32)).astype(np.float32)
    a = np.where((i0 < 0) | (i0 >= n_in - 1), np.float32(0), a)
    i0 = np.clip(i0, 0, n_in - 1)
    i1 = np.minimum(i0 + 1, n_in - 1)
    w0 = np.rint((np.float32(1) - a) * np.float32(2048)).astype(np.int64)
    w1 = np.rint(a * np.float32(2048)).astype(np.int64)
    return torch.from_numpy(i0), torch.from_numpy(i1), torch.from_numpy(w0), torch.from_numpy(w1)


def _resize_u8(x: torch.Tensor, src: tuple[int, int], dst: tuple[int, int], hwc: bool = False) -> torch.Tensor:
    """``cv2.resize(img, dst, INTER_LINEAR)`` of a uint8 image: float (N, C, h, w) holding 0-255, or
    with ``hwc`` the frame itself (h, w, C), any dtype (gathered before the cast, so only the kept
    columns are converted). OpenCV's integer arithmetic (11-bit weights; the vertical pass as its SIMD
    code rounds it: bit-exact against cv2 when shrinking; enlarging, a grey level off here and there),
    in floats that hold every step exactly: the horizontal pass in float32 (at most 255 * 2048), the
    vertical products in float64 (up to 2^26). Every value is >= 0, so OpenCV's shifts are floors.
    The horizontal weights have the full trailing shape: onnxruntime multiplies by a tensor broadcast
    along a middle axis ~10x slower (a 1280x720 frame: 23 ms before, 14 ms now). Returns float32
    (N, C, dst_h, dst_w)."""
    xi0, xi1, a0, a1 = _resize_taps(src[0], dst[0])
    yi0, yi1, b0, b1 = _resize_taps(src[1], dst[1])
    cols, rows = (1, 0) if hwc else (3, 2)
    a0, a1 = (a.to(torch.float32)[:, None].expand(-1, x.shape[2]).contiguous() if hwc else a.to(torch.float32)
              for a in (a0, a1))
    b0, b1 = ((b.to(torch.float64) * (1 / 65536)).reshape((-1, 1, 1) if hwc else (-1, 1))  # (exact: powers of two)
              for b in (b0, b1))
    hor = x.index_select(cols, xi0).float() * a0 + x.index_select(cols, xi1).float() * a1
    h16 = torch.floor(hor * (1 / 16)).double()
    s = torch.floor(h16.index_select(rows, yi0) * b0) + torch.floor(h16.index_select(rows, yi1) * b1)
    out = torch.floor((s + 2) * 0.25).float()
    return (out.permute(2, 0, 1)[None] if hwc else out).clamp(0, 255)


def _fixed_point(c: torch.Tensor) -> torch.Tensor:
    """Float coordinates rounded to OpenCV's fixed point (1/32 px, half to even), float32."""
    return torch.round(c.float() * 32) * (1 / 32)


def _backproject_coords(H: torch.Tensor, w: int, h: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Store coordinates (float32) of every source pixel centre, ``H @ (u, v, 1)`` with H =
    virt_H_src, as ``cv2.warpPerspective(..., WARP_INVERSE_MAP)`` samples them ((h, w) each)."""
    u = torch.arange(w, dtype=torch.float64)[None, :]
    v = torch.arange(h, dtype=torch.float64)[:, None]
    W = H[2, 0] * u + H[2, 1] * v + H[2, 2]
    ok = W != 0
    W = torch.where(ok, W, torch.ones_like(W))
    lim = 1e6  # far outside any store: 0 (and no inf/nan where the road plane's horizon maps)
    far = torch.full_like(W, -64.0)
    X = torch.where(ok, ((H[0, 0] * u + H[0, 1] * v + H[0, 2]) / W).clamp(-lim, lim), far)
    Y = torch.where(ok, ((H[1, 0] * u + H[1, 1] * v + H[1, 2]) / W).clamp(-lim, lim), far)
    return X.float(), Y.float()


def _ray_clamped(X: torch.Tensor, Y: torch.Tensor, centre: tuple[float, float],
                 rect: tuple[float, float, float, float]) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`vcprep.warp.backproject.ray_clamped` as tensor ops: store coordinates outside ``rect``
    (x0, y0, x1, y1) moved along the ray from ``centre`` to where it leaves the rectangle."""
    cx, cy = float(centre[0]), float(centre[1])
    dx, dy = X - cx, Y - cy
    s = torch.ones_like(dx)
    big = torch.full_like(dx, 2.0)
    for d, lo, hi, c in ((dx, rect[0], rect[2], cx), (dy, rect[1], rect[3], cy)):
        pos, neg = d > 0, d < 0
        s = torch.minimum(s, torch.where(pos, (hi - c) / torch.where(pos, d, torch.ones_like(d)), big))
        s = torch.minimum(s, torch.where(neg, (lo - c) / torch.where(neg, d, torch.ones_like(d)), big))
    s = s.clamp(0, 1)
    return cx + s * dx, cy + s * dy


def _backproject_grid(prob: torch.Tensor, H: torch.Tensor, box: tuple[int, int, int, int], centre: tuple[float, float],
                      rect: tuple[float, float, float, float]) -> torch.Tensor:
    """P(road) (float32, rows r0:r1, cols c0:c1 of the frame; ``box`` = (r0, r1, c0, c1)) of the
    store map ``prob`` (Hs, Ws) back-projected through ``H`` = virt_H_src: every frame pixel centre
    sampled bilinearly at ``H @ (u, v, 1)``, a position outside ``rect`` (the training rectangle in
    store pixel centres) moved along the ray from ``centre`` (the road VP in store pixels) to its
    edge (:func:`_ray_clamped`: ``vctrain predict --beyond hybrid``), by GridSample (float32
    coordinates: ~1e-4 px from float64's, far below the 1e-3 agreement on smooth P maps). A pixel on
    the line that maps to infinity (W = 0 exactly) divides by 1 instead. Built and sampled in bands
    of :data:`GRID_BAND` rows: onnxruntime's GridSample takes ~3x longer per pixel on a 1280x712
    grid than on bands, and a band's grid needs no copy into a large one."""
    r0, r1, c0, c1 = box
    Hs, Ws = prob.shape
    G = H.float()
    u = torch.arange(c0, c1, dtype=torch.float32)[None, :]
    bands = []
    for i in range(r0, r1, GRID_BAND):
        v = torch.arange(i, min(i + GRID_BAND, r1), dtype=torch.float32)[:, None]
        W = G[2, 0] * u + (G[2, 1] * v + G[2, 2])
        inv = 1 / (W + (W == 0).to(torch.float32))
        X = ((G[0, 0] * u + (G[0, 1] * v + G[0, 2])) * inv).clamp(-1e6, 1e6)
        Y = ((G[1, 0] * u + (G[1, 1] * v + G[1, 2])) * inv).clamp(-1e6, 1e6)
        X, Y = _ray_clamped(X, Y, centre, rect)
        gx, gy = (2 * X + 1) / Ws - 1, (2 * Y + 1) / Hs - 1  # GridSample's coordinates (align_corners=False)
        bands.append(F.grid_sample(prob[None, None], torch.stack([gx, gy], -1)[None], mode="bilinear",
                                   padding_mode="zeros", align_corners=False)[0, 0])
    return torch.cat(bands, 0)


def _seen_box(seen: np.ndarray, margin: int = 0) -> tuple[int, int, int, int]:
    """(r0, r1, c0, c1): the bounding box of the True pixels of ``seen`` (h, w), grown by
    ``margin`` and clipped to the frame; one pixel when none is."""
    rows, cols = np.nonzero(seen)
    if not rows.size:
        return 0, 1, 0, 1
    h, w = seen.shape
    return (max(0, int(rows.min()) - margin), min(h, int(rows.max()) + 1 + margin),
            max(0, int(cols.min()) - margin), min(w, int(cols.max()) + 1 + margin))


# -- the homography and completion from a VP, in the graph (float64) ---------------------------------

def _mat(rows) -> torch.Tensor:
    return torch.stack([torch.stack(list(r)) for r in rows])


def _adjugate(A: torch.Tensor) -> torch.Tensor:
    """det(A) * inv(A) of a 3x3 (elementwise; the scale of a homography does not matter)."""
    c = lambda i, j, k, l: A[i, j] * A[k, l] - A[i, l] * A[k, j]  # noqa: E731
    return _mat([[c(1, 1, 2, 2), -c(0, 1, 2, 2), c(0, 1, 1, 2)],
                 [-c(1, 0, 2, 2), c(0, 0, 2, 2), -c(0, 0, 1, 2)],
                 [c(1, 0, 2, 1), -c(0, 0, 2, 1), c(0, 0, 1, 1)]])


def _virt_H_src(vp: torch.Tensor, cam: Camera, Gv: torch.Tensor) -> torch.Tensor:
    """``vcprep.warp.homography.virt_H_src(cam, virt, *pose_from_vp(cam, vp))`` (pose_axes written
    with square roots instead of the angles: cos/sin of pan and tilt follow from the VP ray)."""
    d0, d1 = (vp[0] - cam.cx) / cam.fx, (vp[1] - cam.cy) / cam.fy
    r = torch.sqrt(d0 * d0 + d1 * d1 + 1)
    ca = 1 / torch.sqrt(1 + d0 * d0)  # cos(pan), sin(pan) = d0 * ca
    R1 = [ca, torch.zeros_like(ca), -d0 * ca]
    R3 = [d0 / r, d1 / r, 1 / r]
    R2 = [R3[1] * R1[2] - R3[2] * R1[1], R3[2] * R1[0] - R3[0] * R1[2], R3[0] * R1[1] - R3[1] * R1[0]]
    K = torch.tensor(cam.K, dtype=torch.float64)
    Gp = K @ _mat([[R1[i], R3[i], cam.height * R2[i]] for i in range(3)])
    H = Gv @ _adjugate(Gp)
    s = H[2, 0] * cam.cx + H[2, 1] * cam.cy + H[2, 2]
    H = torch.where(s < 0, -H, H)
    return H / H.abs().max()


def _jacobian(M: torch.Tensor, c: tuple[torch.Tensor, torch.Tensor]):
    """Source point of store point ``c`` and the 2x2 ray Jacobian (vcprep.warp.completion._to_source)."""
    V = [M[i, 0] * c[0] + M[i, 1] * c[1] + M[i, 2] for i in range(3)]
    J = [[M[0, 0] * V[2] - V[0] * M[2, 0], M[0, 1] * V[2] - V[0] * M[2, 1]],
         [M[1, 0] * V[2] - V[1] * M[2, 0], M[1, 1] * V[2] - V[1] * M[2, 1]]]
    return (V[0] / V[2], V[1] / V[2]), J, V[2]


def _angle_index(cu: torch.Tensor, cv: torch.Tensor, n: torch.Tensor, store_size: tuple[int, int],
                 known: tuple | None) -> torch.Tensor:
    """The fill table's angle index (int32 (Hs, Ws)) of every store pixel seen from (cu, cv)
    (float32) with ``n`` angles: vcprep.warp.completion_tables._all_angles (atan2 to float64 precision,
    rounded to float32: onnxruntime's float32 Atan is too coarse to round to the same entry). ``known``
    (see :func:`_store_maps_from_vp`): when the centre and n are its, its index, and the rows
    computed here are none (an empty range: a branch without control flow)."""
    Ws, Hs = store_size
    rows = torch.tensor(Hs)
    if known is not None:
        kcu, kcv, kn, index = known
        same = (cu == kcu) & (cv == kcv) & (n == kn)
        rows = torch.where(same, torch.zeros_like(rows), rows)
    du = (torch.arange(Ws, dtype=torch.float32)[None, :] - cu).double()  # float32 differences, as the library's
    dv = (torch.arange(rows.to(torch.int64), dtype=torch.float32)[:, None] - cv).double()
    # onnxruntime has Atan in float32 only (and too coarse): one Newton step of x sin t = y cos t in float64
    t = torch.atan2(dv.float(), du.float()).double()
    c, s = torch.cos(t), torch.sin(t)
    slope = du * c + dv * s
    t = t - (du * s - dv * c) / torch.where(slope == 0, torch.ones_like(slope), slope)
    kk = torch.round(t.float() * (n / (2 * math.pi)).float())
    n32 = n.float()
    kk = (kk - n32 * torch.floor(kk / n32)).to(torch.int32)
    if known is None:
        return kk
    return torch.cat([kk, index.to(torch.int32)], 0)[:Hs]


def _store_maps_from_vp(vp: torch.Tensor, cam: Camera, Gv: torch.Tensor, store_size: tuple[int, int],
                        vis: tuple[int, int], completion: str, angles: tuple | None = None):
    """(H, fixed-point qx, qy of every store pixel): vcprep.warp.build_maps plus the completion
    (vcprep.warp.completion.complete_maps) for a VP given at run time. See the module docstring.

    ``angles``: (cu, cv, n, index): the fill table's angle index of every store pixel (int16
    (Hs, Ws)) seen from the ray centre (cu, cv) (float32) with n angles, as the library computes
    it (:func:`vcprep.warp.completion_tables._all_angles`): the graph uses it whenever the frame's
    centre is that one (every VP in the image: the centre is the virtual camera's VP) and computes
    the index only otherwise (:func:`_angle_index`)."""
    Ws, Hs = store_size
    w, h = vis
    H = _virt_H_src(vp, cam, Gv)
    Minv = _adjugate(H)  # src_H_virt up to scale (complete_maps' M; sign-free where used)
    mid = Minv[2, 0] * (Ws / 2) + Minv[2, 1] * (Hs / 2) + Minv[2, 2]
    M = torch.where(mid < 0, -Minv, Minv)  # build_maps: the store's middle in front
    u = torch.arange(Ws, dtype=torch.float64)[None, :]
    v = torch.arange(Hs, dtype=torch.float64)[:, None]
    den = M[2, 0] * u + (M[2, 1] * v + M[2, 2])
    front = den > 0
    inv = 1 / torch.where(front, den, torch.ones_like(den))
    x = (M[0, 0] * u + (M[0, 1] * v + M[0, 2])) * inv
    y = (M[1, 0] * u + (M[1, 1] * v + M[1, 2])) * inv
    valid = front & (x >= -0.5) & (x < w - 0.5) & (y >= -0.5) & (y < h - 0.5)
    mx = torch.where(valid, x.clamp(0, w - 1), torch.full_like(x, -64.0))
    my = torch.where(valid, y.clamp(0, h - 1), torch.full_like(y, -64.0))
    if completion == "projective":
        # the ray centre: the VP in the store (= the virtual principal point), or the fallback
        pv = [H[i, 0] * vp[0] + H[i, 1] * vp[1] + H[i, 2] for i in range(3)]
        cu, cv = pv[0] / pv[2], pv[1] / pv[2]
        (sx, sy), _, sw = _jacobian(Minv, (cu, cv))
        inside = ((torch.sign(sw) == torch.sign(mid)) & (sx >= 0) & (sx <= w - 1) & (sy >= 0) & (sy <= h - 1))
        vf = valid.to(torch.float64)
        d2 = (u - cu) ** 2 + (v - cv) ** 2  # (1, Ws) + (Hs, 1): the one full-size op is this sum
        k = torch.argmin(torch.where(valid, d2, torch.full_like(d2, float("inf"))).reshape(-1))
        kf = k.to(torch.float64)
        qv = torch.floor(kf / Ws)
        qu = kf - qv * Ws
        n_valid = vf.sum().clamp_min(1)  # the centroid from row and column counts (exact integer sums)
        gu, gv = (vf.sum(0) * u[0]).sum() / n_valid, (vf.sum(1) * v[:, 0]).sum() / n_valid
        fu, fv = qu + FALLBACK_TOWARD * (gu - qu), qv + FALLBACK_TOWARD * (gv - qv)
        ok = lambda a, b: valid.reshape(-1)[(torch.round(b).clamp(0, Hs - 1) * Ws  # noqa: E731
                                             + torch.round(a).clamp(0, Ws - 1)).to(torch.int64)]
        fb_u = torch.where(ok(fu, fv), fu, torch.where(ok(gu, gv), gu, qu))
        fb_v = torch.where(ok(fu, fv), fv, torch.where(ok(gu, gv), gv, qv))
        cu, cv = torch.where(inside, cu, fb_u), torch.where(inside, cv, fb_v)
        (sx, sy), J, _ = _jacobian(Minv, (cu, cv))
        sx, sy = sx.clamp(0, w - 1), sy.clamp(0, h - 1)
        # the fill table: the exit point of each of its n angles (a 1-D table, float64 as the
        # library computes it), looked up by every pixel's angle index (float32, as
        # vcprep.warp.completion._build_angle_index); n varies with the centre: a Range in the graph
        far = torch.stack([torch.sqrt((a - cu) ** 2 + (b - cv) ** 2) for a in (0, Ws - 1) for b in (0, Hs - 1)]).max()
        n = torch.ceil(2 * math.pi * far / TABLE_ARC).clamp_min(1024)
        phi = torch.arange(n.to(torch.int64), dtype=torch.float64) * (2 * math.pi / n)
        c, s = torch.cos(phi), torch.sin(phi)
        dx, dy = J[0][0] * c + J[0][1] * s, J[1][0] * c + J[1][1] * s
        big = torch.full_like(dx, float("inf"))
        one = torch.ones_like(dx)
        tx = torch.where(dx > 0, (w - 1 - sx) / torch.where(dx > 0, dx, one),
                         torch.where(dx < 0, -sx / torch.where(dx < 0, dx, one), big))
        ty = torch.where(dy > 0, (h - 1 - sy) / torch.where(dy > 0, dy, one),
                         torch.where(dy < 0, -sy / torch.where(dy < 0, dy, one), big))
        t = torch.minimum(tx, ty)
        t = torch.where(torch.isinf(t), torch.zeros_like(t), t)
        exits = torch.stack([(sx + t * dx).clamp(0, w - 1), (sy + t * dy).clamp(0, h - 1)], -1).float()
        kk = _angle_index(cu.float(), cv.float(), n, (Ws, Hs), angles)
        e = torch.index_select(exits, 0, kk.reshape(-1)).reshape(Hs, Ws, 2)
        ex, ey = e[..., 0], e[..., 1]
        # covered pixels: fixed-point maps (cv2.convertMaps); the fill table: float maps
        return H, torch.where(valid, _fixed_point(mx), ex), torch.where(valid, _fixed_point(my), ey)
    return H, _fixed_point(mx), _fixed_point(my)


# -- the graph -----------------------------------------------------------------------------------------


def _vp_map(vp_src: torch.Tensor, work: tuple[int, int], src: tuple[int, int]) -> torch.Tensor:
    """vctrain.training.data.vp_proximity at the working size for a source-pixel VP (float64)."""
    ww, wh = work
    vx, vy = vp_src[0] * (ww / src[0]), vp_src[1] * (wh / src[1])
    x = (torch.arange(ww, dtype=torch.float64)[None, :] - vx).abs() / ww
    y = (torch.arange(wh, dtype=torch.float64)[:, None] - vy).abs() / wh
    return 1 - torch.maximum(x, y)
