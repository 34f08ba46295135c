"""Deployment: one ONNX graph with the camera inside (``vctrain export``), and running it.

The graph takes a camera's raw frame and returns road probability in that camera's pixels; it
holds everything ``vctrain predict`` does for that camera (:mod:`vctrain.predict`):

- ``virtual`` models: the warp into the checkpoint's virtual camera at its scale, the rectangle
  extended for this camera as ``predict`` does (:func:`vctrain.predict._canvas_for`), with the
  training store's completion; the resize to the working size; :func:`vctrain.data.to_input`
  (and the VP channel); the network; softmax; the resize back and the back-projection
  (:func:`vcprep.backproject.backproject_array` with ``kind="prob"``: bilinear, 0 outside).
  The camera's ``ego_rows`` are cut off before the warp and back-projected like any row.
- ``resize`` baseline models: resize in, network, softmax, resize back.

Fixed mount (default): the warp is a constant sampling grid -- the store maps of
:func:`vcprep.completion.completion_maps` for the camera's own pose, completion included -- and
the back-projection another. ``vp_input=True``: the graph takes the frame's road vanishing point
(u, v, source pixels) and builds ``virt_H_src`` (:func:`vcprep.homography.virt_H_src` via
:func:`~vcprep.homography.pose_from_vp`, in float64) and the projective completion in the graph:
every uncovered store pixel takes the source point where the ray from the VP, at the fill
table's quantised angle, leaves the source rectangle (:func:`vcprep.completion.exit_points_rectangle`
-- elementwise), and a VP outside the image starts the rays from the nearest covered pixel moved
10 % toward the centroid, as the library does. Its rectangle is fixed: the training's, extended
to hold the camera at every pose within ``pose_range`` (pan, tilt degrees) of its mount.

Sampling convention: every bilinear sample is the one OpenCV computes -- source coordinates
rounded to 1/32 px, weights from those fractions, 8-bit images rounded half up (``cv2.remap``
on uint8; the store holds exactly that), float maps with float weights (``cv2.warpPerspective``
for the back-projection). Layout for onnxruntime (whose gathers cost per index, not per byte):
the warp gathers 6-byte pixel pairs (:func:`_sample_u8`), the back-projection each pixel's four
taps at once (:func:`_sample_f`), the fixed mount's taps are constants (int32 index, int16
fractions to 1/65536: the fill table's float fractions lose < 2e-5 px) and its back-projection
covers only the box of frame pixels that see the store; P(road) of a two-class network is
``sigmoid(l1 - l0)`` (softmax's value; onnxruntime's channel softmax is slow). Graph I/O: ``frame`` uint8 (H, W, 3) BGR as ``cv2.imread`` gives it
at the camera's image size, ``vp`` float32 (2,) with ``vp_input``; output ``road_prob`` float32
(H, W). onnx / onnxruntime are optional (``pip install 'vcseg[deploy]'``) and imported here only.
"""
from __future__ import annotations

import io
import json
import math
import warnings
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from vcprep.camera import Camera, camera_from_dict, scale_matrix
from vcprep.errors import InputError

__all__ = ["OPSET", "RoadGraph", "export_onnx", "OnnxPredictor", "predict_images_onnx", "require"]

OPSET = 17
GRAPH_FORMAT = "vcseg-road-graph"
DEPLOY_FIX = "pip install 'vcseg[deploy]'"
TABLE_ARC, FALLBACK_TOWARD = 0.5, 0.1  # as vcprep.completion (checked below against its constants)


def require(module: str):
    """Import ``onnx`` or ``onnxruntime`` (the optional 'deploy' extra) or raise one clear error."""
    try:
        return __import__(module)
    except ImportError:
        raise InputError(f"{module} is not installed (needed to export or run ONNX graphs)", None, DEPLOY_FIX) from None


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


def _taps(x: torch.Tensor, y: torch.Tensor, w: int, h: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Bilinear taps of source coordinates ``x``/``y`` (float32 px, pixel centres at integers, shape
    (S,)) in a ``w`` x ``h`` image padded by :func:`_padded`: the flat index (int32) of each
    top-left tap in the padded image and the fractions ``ax``, ``ay`` (float32) toward the right and
    lower taps. A tap outside the image reads the zero border (BORDER_CONSTANT); a coordinate more
    than one pixel outside reads the corner's zeros (index 0, fractions 0).

    This is OpenCV's arithmetic: with coordinates already rounded to 1/32 px (what ``cv2.remap``
    does with fixed-point maps, :func:`_fixed_point`) every fraction is a multiple of 1/32 and each
    step of :func:`_sample_u8` is exact in float32 and equals OpenCV's integer result; with plain
    float32 coordinates it is OpenCV 5's float-map path (float weights), which the completion's
    fill table and ``warpPerspective`` use."""
    x0, y0 = torch.floor(x), torch.floor(y)
    ok = (x0 >= -1) & (x0 <= w - 1) & (y0 >= -1) & (y0 <= h - 1)
    zero = torch.zeros_like(x)
    idx = (y0.clamp(-1, h - 1) + 1) * _padded_width(w) + (x0.clamp(-1, w - 1) + 1)
    return (torch.where(ok, idx, zero).to(torch.int32), torch.where(ok, x - x0, zero),
            torch.where(ok, y - y0, zero))


def _sample_u8(src: torch.Tensor, w: int, idx: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """Bilinear samples (float32 (3, S), rounded half up: what ``cv2.remap`` writes to uint8) of
    the padded uint8 image ``src`` (P, 3) (:func:`_padded` of a ``w``-wide image) at the taps of
    :func:`_taps`. One gather of 6-byte pixel pairs (the padded image read as pairs starting at
    even pixels, then at odd ones): the upper pair and the lower pair of every sample; then two
    linear interpolations along x and one along y (channels first: what the network takes)."""
    n = src.shape[0]  # even (padded width even)
    pairs = torch.cat([src.reshape(n // 2, 6), src[1:n - 1].reshape(n // 2 - 1, 6)], 0)
    idx = idx.to(torch.int32)
    W2 = _padded_width(w)
    rows = torch.stack([idx, idx + W2])  # (2, S): the upper and lower pair's first pixel
    rows = torch.where(rows % 2 == 0, rows // 2, rows // 2 + n // 2)
    v = torch.index_select(pairs, 0, rows.reshape(-1)).reshape(2, -1, 2, 3).permute(0, 2, 3, 1).to(torch.float32)
    left, right = v[:, 0], v[:, 1]  # (2, 3, S): upper and lower row
    row = left + ax * (right - left)
    return torch.floor(row[0] + ay * (row[1] - row[0]) + 0.5)


def _sample_f(src: torch.Tensor, w: int, idx: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """Bilinear samples (float32 (S,)) of the padded float map ``src`` (P,) (:func:`_padded` of a
    ``w``-wide map) at the taps of :func:`_taps`: one gather of each sample's four taps (a (P, 4)
    table of every pixel with its right, lower and lower-right neighbours), weighted and summed."""
    W2 = _padded_width(w)
    n = src.shape[0] - W2 - 1
    quads = torch.stack([src[0:n], src[1:n + 1], src[W2:W2 + n], src[W2 + 1:W2 + 1 + n]], -1)
    wts = torch.stack([(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay], -1)
    return (torch.index_select(quads, 0, idx.to(torch.int32)) * wts).sum(-1)


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


def _resize_u8(x: torch.Tensor, src: tuple[int, int], dst: tuple[int, int]) -> torch.Tensor:
    """``cv2.resize(img, dst, INTER_LINEAR)`` of a uint8 image held as float (N, C, h, w): the
    same integer arithmetic (11-bit weights; the vertical pass as OpenCV's SIMD code rounds it,
    checked bit-exact against cv2 for down- and upscaling). Returns float (N, C, dst_h, dst_w)."""
    xi0, xi1, a0, a1 = _resize_taps(src[0], dst[0])
    yi0, yi1, b0, b1 = _resize_taps(src[1], dst[1])
    v = x.to(torch.int64)
    hor = v.index_select(3, xi0) * a0 + v.index_select(3, xi1) * a1
    s0 = torch.div(hor.index_select(2, yi0), 16, rounding_mode="floor") * b0[:, None]
    s1 = torch.div(hor.index_select(2, yi1), 16, rounding_mode="floor") * b1[:, None]
    out = torch.div(torch.div(s0, 65536, rounding_mode="floor") + torch.div(s1, 65536, rounding_mode="floor") + 2, 4,
                    rounding_mode="floor")
    return out.clamp(0, 255).to(x.dtype)


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
    """``vcprep.homography.virt_H_src(cam, virt, *pose_from_vp(cam, vp))`` (pose_axes written
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
    """Source point of store point ``c`` and the 2x2 ray Jacobian (vcprep.completion._to_source)."""
    V = [M[i, 0] * c[0] + M[i, 1] * c[1] + M[i, 2] for i in range(3)]
    J = [[M[0, 0] * V[2] - V[0] * M[2, 0], M[0, 1] * V[2] - V[0] * M[2, 1]],
         [M[1, 0] * V[2] - V[1] * M[2, 0], M[1, 1] * V[2] - V[1] * M[2, 1]]]
    return (V[0] / V[2], V[1] / V[2]), J, V[2]


def _store_maps_from_vp(vp: torch.Tensor, cam: Camera, Gv: torch.Tensor, store_size: tuple[int, int],
                        vis: tuple[int, int], completion: str):
    """(H, fixed-point qx, qy of every store pixel): vcprep.warp.build_maps plus the completion
    (vcprep.completion.complete_maps) for a VP given at run time. See the module docstring."""
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
        uu, vv = u.expand(Hs, Ws), v.expand(Hs, Ws)
        d2 = torch.where(valid, (uu - cu) ** 2 + (vv - cv) ** 2, torch.full_like(uu, float("inf")))
        k = torch.argmin(d2.reshape(-1))
        kf = k.to(torch.float64)
        qv = torch.floor(kf / Ws)
        qu = kf - qv * Ws
        n_valid = vf.sum().clamp_min(1)
        gu, gv = (uu * vf).sum() / n_valid, (vv * vf).sum() / n_valid
        fu, fv = qu + FALLBACK_TOWARD * (gu - qu), qv + FALLBACK_TOWARD * (gv - qv)
        ok = lambda a, b: valid.reshape(-1)[(torch.round(b).clamp(0, Hs - 1) * Ws  # noqa: E731
                                             + torch.round(a).clamp(0, Ws - 1)).to(torch.int64)]
        fb_u = torch.where(ok(fu, fv), fu, torch.where(ok(gu, gv), gu, qu))
        fb_v = torch.where(ok(fu, fv), fv, torch.where(ok(gu, gv), gv, qv))
        cu, cv = torch.where(inside, cu, fb_u), torch.where(inside, cv, fb_v)
        (sx, sy), J, _ = _jacobian(Minv, (cu, cv))
        sx, sy = sx.clamp(0, w - 1), sy.clamp(0, h - 1)
        # the fill table's angle of every pixel (float32, as vcprep.completion._build_angle_index)
        far = torch.stack([torch.sqrt((a - cu) ** 2 + (b - cv) ** 2) for a in (0, Ws - 1) for b in (0, Hs - 1)]).max()
        n = torch.ceil(2 * math.pi * far / TABLE_ARC).clamp_min(1024)
        du = torch.arange(Ws, dtype=torch.float32)[None, :] - cu.float()
        dv = torch.arange(Hs, dtype=torch.float32)[:, None] - cv.float()
        kk = torch.round(torch.atan2(dv, du) * (n / (2 * math.pi)).float())
        n32 = n.float()
        kk = (kk - n32 * torch.floor(kk / n32)).double()
        phi = kk * (2 * math.pi / n)
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
        ex, ey = (sx + t * dx).clamp(0, w - 1), (sy + t * dy).clamp(0, h - 1)
        # covered pixels: fixed-point maps (cv2.convertMaps); the fill table: float maps
        return H, torch.where(valid, _fixed_point(mx), ex.float()), torch.where(valid, _fixed_point(my), ey.float())
    return H, _fixed_point(mx), _fixed_point(my)


# -- the graph -----------------------------------------------------------------------------------------

class RoadGraph(nn.Module):
    """Frame (H, W, 3) uint8 BGR [, VP (2,) float32] -> P(road) (H, W) float32; see the module doc.

    ``geom``: what :func:`_geometry` computed (sizes, maps, VP map, camera); ``model``: the
    network in eval mode."""

    def __init__(self, model: nn.Module, geom: dict[str, Any]):
        super().__init__()
        self.model, self.g = model, geom
        if geom.get("vp_map") is not None:
            self.register_buffer("vp_map", torch.from_numpy(np.ascontiguousarray(geom["vp_map"])), persistent=False)
        if geom.get("warp_qx") is None:
            return
        # fixed mount: every tap index and weight is a constant (computed once, here)
        wv, hv = geom["visible"]
        Ws, Hs = geom["store_size"]
        w, h = geom["size"]
        x, y = (torch.from_numpy(np.ascontiguousarray(geom[k])).reshape(-1) for k in ("warp_qx", "warp_qy"))
        self._constants("warp", *_taps(x, y, wv, hv))
        # the back-projection only where a frame pixel reads the store: its bounding box (0 around it)
        idx, ax, ay = _taps(torch.from_numpy(geom["back_qx"]).reshape(-1), torch.from_numpy(geom["back_qy"]).reshape(-1),
                            Ws, Hs)
        rows, cols = np.nonzero(((idx > 0) | (ax > 0) | (ay > 0)).reshape(h, w).numpy())
        r0, r1 = (int(rows.min()), int(rows.max()) + 1) if rows.size else (0, 1)
        c0, c1 = (int(cols.min()), int(cols.max()) + 1) if cols.size else (0, 1)
        self.back_box = (r0, r1, c0, c1)
        self._constants("back", *(t.reshape(h, w)[r0:r1, c0:c1].reshape(-1) for t in (idx, ax, ay)))

    def _constants(self, name: str, idx: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> None:
        """Fixed-mount taps as buffers: int32 indices, fractions as int16 (the file stays small;
        onnxruntime converts them once when it loads the graph)."""
        self.register_buffer(f"{name}_idx", idx.contiguous())
        self.register_buffer(f"{name}_ax", _store_fraction(ax))
        self.register_buffer(f"{name}_ay", _store_fraction(ay))

    def _taps_of(self, name: str) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        return (getattr(self, f"{name}_idx"), _load_fraction(getattr(self, f"{name}_ax")),
                _load_fraction(getattr(self, f"{name}_ay")))

    def _net(self, x: torch.Tensor, vp_map: torch.Tensor | None, ws: int, hs: int) -> torch.Tensor:
        """(3, hs, ws) float 0-255 BGR image -> P(road) (hs, ws) at that size (working size inside)."""
        g = self.g
        x = x[None]
        if tuple(g["work"]) != (ws, hs):  # resize_pair: cv2.resize bilinear on the uint8 image
            x = _resize_u8(x, (ws, hs), tuple(g["work"]))
        x = x * (2 / 255) - 1 if not g["greyscale"] else x
        if g["greyscale"]:  # to_input: cvtColor BGR2GRAY on [0, 1] floats, replicated
            grey = (x[:, 0:1] * 0.114 + x[:, 1:2] * 0.587 + x[:, 2:3] * 0.299) / 255
            x = (grey * 2 - 1).expand(-1, 3, -1, -1)
        if vp_map is not None:
            x = torch.cat([x, vp_map[None, None]], 1)
        logits = self.model(x).float()
        if logits.shape[1] == 2:  # softmax's P(road) of two classes, without onnxruntime's slow channel softmax
            prob = torch.sigmoid(logits[:, 1:2] - logits[:, 0:1])
        else:
            prob = torch.softmax(logits, dim=1)[:, 1:2]
        if tuple(g["work"]) != (ws, hs):
            prob = F.interpolate(prob, size=(hs, ws), mode="bilinear", align_corners=False)
        return prob[0, 0]

    def forward(self, frame: torch.Tensor, vp: torch.Tensor | None = None) -> torch.Tensor:
        g = self.g
        w, h = g["size"]
        if g["mode"] == "resize":
            vp_map = None
            if g["vp_channel"]:
                vp_map = self.vp_map if vp is None else _vp_map(vp.double(), g["work"], (w, h)).float()
            return self._net(frame.to(torch.float32).permute(2, 0, 1), vp_map, w, h).clamp(0, 1)
        wv, hv = g["visible"]
        src = _padded(frame[:hv])  # (P, 3) uint8; the own vehicle's rows are never warped
        Ws, Hs = g["store_size"]
        vp_map = getattr(self, "vp_map", None)
        if vp is None:
            taps = self._taps_of("warp")
        else:
            H, qx, qy = _store_maps_from_vp(vp.double(), g["camera"], torch.tensor(g["Gv"], dtype=torch.float64),
                                            (Ws, Hs), (wv, hv), g["completion"])
            taps = _taps(qx.reshape(-1), qy.reshape(-1), wv, hv)
        store = _sample_u8(src, wv, *taps)  # (3, Hs*Ws) 0-255, exactly the store image
        prob = self._net(store.reshape(3, Hs, Ws), vp_map, Ws, Hs)
        if vp is None:
            r0, r1, c0, c1 = self.back_box
            out = _sample_f(_padded(prob), Ws, *self._taps_of("back")).reshape(r1 - r0, c1 - c0)
            out = F.pad(out, (c0, w - c1, r0, h - r1))
        else:
            bx, by = _backproject_coords(H, w, h)
            out = _sample_f(_padded(prob), Ws, *_taps(bx.reshape(-1), by.reshape(-1), Ws, Hs)).reshape(h, w)
        return out.clamp(0, 1)


def _vp_map(vp_src: torch.Tensor, work: tuple[int, int], src: tuple[int, int]) -> torch.Tensor:
    """vctrain.data.vp_proximity at the working size for a source-pixel VP (float64)."""
    ww, wh = work
    vx, vy = vp_src[0] * (ww / src[0]), vp_src[1] * (wh / src[1])
    x = (torch.arange(ww, dtype=torch.float64)[None, :] - vx).abs() / ww
    y = (torch.arange(wh, dtype=torch.float64)[:, None] - vy).abs() / wh
    return 1 - torch.maximum(x, y)


def _geometry(predictor, camera: Camera, vp_input: bool, pose_range: tuple[float, float]) -> dict[str, Any]:
    """Everything the graph holds for ``camera`` (at its own image size)."""
    from vcprep import completion as C
    from vcprep.build import item_geometry, item_maps, store_params
    from vcprep.homography import apply_homography, vp_from_pose
    from vcprep.virtual_camera import extend_canvas

    from .data import vp_proximity

    assert (C.TABLE_ARC, C.FALLBACK_TOWARD) == (TABLE_ARC, FALLBACK_TOWARD)  # the in-graph completion's constants
    data = predictor.data
    cam = camera.for_image_size(camera.size)
    w, h = cam.size
    g: dict[str, Any] = {"mode": predictor.mode, "size": [w, h], "greyscale": predictor.greyscale,
                         "vp_channel": predictor.vp_channel, "vp_input": vp_input}
    vp_src = vp_from_pose(cam)
    if predictor.mode == "resize":
        g["work"] = list(predictor.size)
        if predictor.vp_channel:
            S = scale_matrix(g["work"][0] / w, g["work"][1] / h)
            p = S @ np.array([vp_src[0], vp_src[1], 1.0])
            g["vp_map"] = vp_proximity(tuple(g["work"]), (p[0], p[1])).astype(np.float32)
        return g
    sp = data.get("store_params")
    if not sp:
        raise InputError("model was not trained in a virtual camera and is no resize baseline", predictor.path,
                         "use a model written by 'vctrain fit'")
    completion = data.get("completion", "none")
    if vp_input and completion == "replicate":
        raise InputError("'replicate' completion (a distance transform) cannot follow a VP given at run time",
                         predictor.path, "export without --vp-input (the camera's mount pose)")
    virtual = camera_from_dict(sp["virtual"], predictor.path)
    views = [(cam, cam.pan, cam.tilt)]
    if vp_input:  # one fixed rectangle for every pose in the range (vctrain predict extends per frame set)
        views += [(cam, cam.pan + a * pose_range[0], cam.tilt + b * pose_range[1])
                  for a in (-1, 0, 1) for b in (-1, 0, 1)]
    canvas = extend_canvas(virtual, views)
    params = store_params(canvas, float(sp["scale"]))
    vs = camera_from_dict(params["virtual_scaled"])
    store_size = tuple(params["store_size"])
    _, H = item_geometry(cam, (w, h), vs, None, cam.pan, cam.tilt)
    vis = cam.visible_size
    vp_store = tuple(apply_homography(H, [vp_src])[0])
    work = predictor.working_size(store_size)
    g.update(work=list(work), store_size=list(store_size), visible=list(vis), completion=completion,
             virtual=canvas.to_dict(), scale=float(sp["scale"]), ego_rows=int(cam.ego_rows))
    if predictor.vp_channel:
        S = scale_matrix(work[0] / store_size[0], work[1] / store_size[1])
        p = S @ np.array([vp_store[0], vp_store[1], 1.0])
        g["vp_map"] = vp_proximity(work, (p[0], p[1])).astype(np.float32)
    if vp_input:
        from vcprep.homography import ground_to_image

        g["camera"] = cam
        g["Gv"] = ground_to_image(vs)
        return g
    maps = item_maps(H, vis, store_size, completion, vp_store)
    covered = torch.from_numpy(maps.valid.astype(bool))
    mx, my = torch.from_numpy(maps.exact_maps.map_x), torch.from_numpy(maps.exact_maps.map_y)
    # covered pixels are remapped with fixed-point maps, the completion's fill table with float ones
    g["warp_qx"] = torch.where(covered, _fixed_point(mx), mx).numpy()
    g["warp_qy"] = torch.where(covered, _fixed_point(my), my).numpy()
    bx, by = _backproject_coords(torch.tensor(np.asarray(H, dtype=np.float64)), w, h)
    g["back_qx"], g["back_qy"] = bx.numpy(), by.numpy()
    return g


def export_onnx(checkpoint: str | Path, camera: Camera, out: str | Path, vp_input: bool = False,
                pose_range: tuple[float, float] = (5.0, 5.0), check: bool = True) -> dict[str, Any]:
    """Write the ONNX graph of ``checkpoint`` for ``camera`` to ``out`` (module docstring); with
    ``check`` runs it once in onnxruntime against the torch module. Returns its description (also
    stored in the graph's metadata ``vcseg``): inputs, output, sizes, opset, max_abs_diff."""
    onnx = require("onnx")
    from .predict import Predictor

    if not isinstance(camera, Camera):
        raise InputError("export needs one camera (the graph holds one mount)", None,
                         "give a preset or one calibration file, not a folder")
    predictor = Predictor(checkpoint, "cpu")
    geom = _geometry(predictor, camera, vp_input, pose_range)
    graph = RoadGraph(predictor.model.eval(), geom).eval()
    w, h = geom["size"]
    frame = torch.zeros(h, w, 3, dtype=torch.uint8)
    vp = torch.tensor(vp_from_cam(camera), dtype=torch.float32)
    args = (frame, vp) if vp_input else (frame,)
    names = ["frame", "vp"] if vp_input else ["frame"]
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation and tracer notes
        torch.onnx.export(graph, args, buf, dynamo=False, opset_version=OPSET, input_names=names,
                          output_names=["road_prob"],
                          do_constant_folding=vp_input)  # fixed mount: int16 taps stay small in the file
    model = onnx.load_from_string(buf.getvalue())
    info = {"format": GRAPH_FORMAT, "checkpoint": str(checkpoint), "mode": geom["mode"],
            "camera": camera.to_dict(), "camera_name": camera.name, "opset": OPSET,
            "inputs": {"frame": ["uint8", [h, w, 3], "BGR"], **({"vp": ["float32", [2], "u, v source px"]}
                                                                 if vp_input else {})},
            "output": {"road_prob": ["float32", [h, w]]},
            **{k: geom[k] for k in ("work", "store_size", "completion", "ego_rows", "vp_input") if k in geom}}
    if vp_input and geom["mode"] == "virtual":
        info["pose_range"] = list(pose_range)
    if check:
        ort = require("onnxruntime")
        rng = np.random.default_rng(0)
        test = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        feeds = {"frame": test, **({"vp": vp.numpy()} if vp_input else {})}
        got = _session(ort, buf.getvalue()).run(None, feeds)[0]
        with torch.no_grad():
            ref = graph(torch.from_numpy(test), *((vp,) if vp_input else ())).numpy()
        info["max_abs_diff_vs_torch"] = float(np.abs(got - ref).max())
    entry = model.metadata_props.add()
    entry.key, entry.value = "vcseg", json.dumps(info)
    out = Path(out)
    try:
        onnx.save(model, str(out))
    except OSError as e:
        raise InputError(f"cannot write: {e.strerror or e}", out, "check the folder exists and is writable") from None
    return info


def vp_from_cam(camera: Camera) -> tuple[float, float]:
    from vcprep.homography import vp_from_pose

    return vp_from_pose(camera.for_image_size(camera.size))


def _session(ort, model, threads: int = 0):
    so = ort.SessionOptions()
    if threads:
        so.intra_op_num_threads = threads
    so.log_severity_level = 3
    return ort.InferenceSession(model, so, providers=["CPUExecutionProvider"])


class OnnxPredictor:
    """An exported graph (``vctrain export``) run in onnxruntime: frame (+ VP) -> P(road)."""

    def __init__(self, path: str | Path, threads: int = 0):
        ort = require("onnxruntime")
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError("ONNX graph not found", self.path, "give the .onnx file written by 'vctrain export'")
        try:
            self.session = _session(ort, str(self.path), threads)
        except Exception as e:  # onnxruntime raises its own types for foreign/corrupt files
            raise InputError(f"cannot load ONNX graph ({str(e).splitlines()[0][:120]})", self.path,
                             "give the .onnx file written by 'vctrain export'") from None
        meta = self.session.get_modelmeta().custom_metadata_map.get("vcseg")
        info = json.loads(meta) if meta else {}
        if info.get("format") != GRAPH_FORMAT:
            raise InputError("not a graph written by 'vctrain export' (no vcseg metadata)", self.path,
                             "export the model with 'vctrain export'")
        self.info = info
        self.size = tuple(info["inputs"]["frame"][1][1::-1])  # (w, h)
        self.vp_input = "vp" in info["inputs"]
        self.camera = camera_from_dict(info["camera"], self.path)
        self.mode = info["mode"]

    def road_probability(self, frame: np.ndarray, vp: tuple[float, float] | None = None,
                         name: str | Path | None = None) -> np.ndarray:
        """P(road) float32 (h, w) of one BGR uint8 frame of the graph's camera size."""
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            raise InputError(f"frame is {frame.dtype} with shape {frame.shape}, the graph takes uint8 BGR (h, w, 3)",
                             name, "give 8-bit colour frames")
        if (frame.shape[1], frame.shape[0]) != self.size:
            raise InputError(f"frame is {frame.shape[1]}x{frame.shape[0]} but the graph's camera is "
                             f"{self.size[0]}x{self.size[1]}", name, "export the model for this camera's image size")
        feeds = {"frame": np.ascontiguousarray(frame)}
        if self.vp_input:
            feeds["vp"] = np.asarray(vp if vp is not None else vp_from_cam(self.camera), dtype=np.float32)
        return self.session.run(None, feeds)[0]


def predict_images_onnx(predictor: OnnxPredictor, images: Iterable[str | Path], out: str | Path,
                        camera: Camera | None = None, progress: bool = True, overlay: bool = False,
                        within: str = "auto") -> list[Path]:
    """:func:`vctrain.predict.predict_images` for an exported graph: writes ``<stem>_prob.png`` and
    ``<stem>_mask.png``. A ``--vp-input`` graph gets each frame's VP: ``within`` 'auto'/'estimate'
    estimates it (with ``camera``, default the graph's), a CSV ``id,u,v`` gives it, 'none' takes
    the camera's mount pose; a fixed graph takes only 'auto' or 'none'."""
    from tqdm import tqdm

    from vcprep.imageio import read_image

    from .predict import _out_dir, collect_images, write_prediction

    jobs = collect_images(images)
    out = _out_dir(out)
    vps: dict[str, tuple[float, float]] = {}
    if not predictor.vp_input:
        if within not in ("auto", "none"):
            raise InputError("this graph has the camera's mount pose built in (exported without --vp-input)",
                             predictor.path, "drop --within, or export with --vp-input")
    elif within != "none":
        from vcprep.vanishing_point import vps_for_items

        cam = camera or predictor.camera
        res = vps_for_items([j.image for j in jobs], [j.id for j in jobs], cam,
                            "estimate" if within == "auto" else within)
        vps = {j.id: (float(r.vp[0]), float(r.vp[1])) for j, r in zip(jobs, res)}
    written = []
    for job in tqdm(jobs, desc="predict", unit="img", disable=None if progress else True, leave=False):
        img = read_image(job.image).array
        prob = predictor.road_probability(img, vps.get(job.id), job.image)
        written.append(write_prediction(out, job.id, prob, job.image if overlay else None)[0])
    return written
