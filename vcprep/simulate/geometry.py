"""The geometry of a simulated camera (:mod:`vcprep.simulate`): the rotation of a re-mounted,
rolled camera, its zoom and field of view, whether its view stays inside the source image
(:func:`covered`, :func:`widest_zoom`) and the per-image jitter draws. Pure numpy, no files.

Rotations (conventions of :mod:`vcprep.simulate`): ``Rw(pan, tilt) = column_stack(pose_axes(pan,
tilt))`` takes world directions to camera directions; a source of nominal pose (pan0, tilt0)
re-mounted at (pan1, tilt1) and rolled by ``roll`` has ``R = Rroll(roll) @ Rw(pan1, tilt1) @
Rw(pan0, tilt0).T``; positive roll turns the picture clockwise on screen.
"""
from __future__ import annotations

import hashlib
import math
from typing import Sequence

import numpy as np

from ..camera.pinhole import Camera
from ..warp.homography import pose_axes

__all__ = ["world_to_camera", "roll_matrix", "relative_rotation", "zoom_for_hfov", "hfov_for_zoom", "output_camera",
           "out_H_src_for", "covered", "widest_zoom", "draw_offsets"]

_ZOOM_LO, _ZOOM_HI = 1e-6, 1e6  # bracket for the widest-FOV search
_ZOOM_SAFETY = 1.0 + 1e-9  # the chosen zoom is this much inside the limit (margin ~1e-7 px)


def world_to_camera(pan_deg: float, tilt_deg: float) -> np.ndarray:
    """``Rw``: world directions -> camera directions for a camera at (pan, tilt) (roll 0)."""
    return np.column_stack(pose_axes(pan_deg, tilt_deg))


def roll_matrix(roll_deg: float) -> np.ndarray:
    """Rotation about the optical axis; positive = the picture turns clockwise on screen."""
    r = math.radians(roll_deg)
    c, s = math.cos(r), math.sin(r)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def relative_rotation(pan0: float, tilt0: float, pan1: float, tilt1: float, roll: float = 0.0) -> np.ndarray:
    """``R = Rroll(roll) @ Rw(pan1, tilt1) @ Rw(pan0, tilt0).T``: source camera frame (pose
    (pan0, tilt0)) -> frame of the same camera re-mounted at (pan1, tilt1) and rolled."""
    return roll_matrix(roll) @ world_to_camera(pan1, tilt1) @ world_to_camera(pan0, tilt0).T


def zoom_for_hfov(fx: float, width: int, hfov_deg: float) -> float:
    """Zoom giving an output of ``width`` px (central principal point) the horizontal FOV
    ``hfov_deg`` measured edge to edge (as :meth:`Camera.fov_deg`): ``W' = 2 z fx tan(hfov/2)``."""
    return width / (2.0 * fx * math.tan(math.radians(hfov_deg) / 2.0))


def hfov_for_zoom(fx: float, width: int, zoom: float) -> float:
    return math.degrees(2.0 * math.atan(width / (2.0 * zoom * fx)))


def output_camera(source: Camera, size: tuple[int, int], zoom: float, horizon_shift: float = 0.0,
                  name: str = "simulated") -> Camera:
    """The output camera at its nominal zero pose: focal lengths ``zoom*(fx, fy)``, principal
    point at the centre of the ``size`` (w, h) image, moved down by ``horizon_shift`` px."""
    W, H = int(size[0]), int(size[1])
    return Camera(name=name, size=(W, H), fx=zoom * source.fx, fy=zoom * source.fy, cx=(W - 1) / 2.0,
                  cy=(H - 1) / 2.0 + horizon_shift, height=source.height, tilt=0.0, pan=0.0)


def _flip_matrix(width: int) -> np.ndarray:
    return np.array([[-1.0, 0.0, width - 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def out_H_src_for(src: Camera, out: Camera, R: np.ndarray, flip: bool = False) -> np.ndarray:
    """``out_H_src = [F] K' R K^-1`` (source pixel -> output pixel, pixel centres at integers,
    F = the mirror ``u -> W'-1-u`` with ``flip``). Not normalised: its third row applied to a
    source pixel is the depth of that ray in the new camera (> 0 in front)."""
    H = out.K @ R @ np.linalg.inv(src.K)
    return _flip_matrix(out.size[0]) @ H if flip else H


def _boundary(size: tuple[int, int], n: int = 8) -> np.ndarray:
    """(3, M) homogeneous pixel centres on the border of a ``size`` image: corners + n per edge."""
    W, H = size
    t = np.linspace(0.0, 1.0, n + 2)
    us, vs = t * (W - 1), t * (H - 1)
    pts = np.concatenate([np.column_stack([us, np.zeros_like(us)]), np.column_stack([us, np.full_like(us, H - 1.0)]),
                          np.column_stack([np.zeros_like(vs), vs]), np.column_stack([np.full_like(vs, W - 1.0), vs])])
    return np.vstack([pts.T, np.ones(len(pts))])


def _covered_many(A: np.ndarray, sizes: np.ndarray, norm_pts: np.ndarray) -> np.ndarray:
    """For each i: do the rays ``norm_pts`` (3, M) (output camera coordinates) all land in front
    of source i and inside its pixel-centre rectangle? ``A`` (N, 3, 3) = K_i R_i^T."""
    q = A @ norm_pts  # (N, 3, M)
    z = q[:, 2]
    front = np.all(z > 1e-12, axis=1)
    zz = np.where(z > 1e-12, z, 1.0)
    x, y = q[:, 0] / zz, q[:, 1] / zz
    w = sizes[:, 0:1] - 1.0
    h = sizes[:, 1:2] - 1.0
    return front & np.all((x >= 0) & (x <= w) & (y >= 0) & (y <= h), axis=1)


def _norm_boundary(out0: Camera, zoom: float, pts: np.ndarray) -> np.ndarray:
    """Output boundary pixels as rays of the output camera with focal lengths zoom*(fx0, fy0)."""
    return np.vstack([(pts[0] - out0.cx) / (zoom * out0.fx), (pts[1] - out0.cy) / (zoom * out0.fy),
                      np.ones(pts.shape[1])])


def covered(src_H_out: np.ndarray, src_size: tuple[int, int], out_size: tuple[int, int]) -> bool:
    """Does every output pixel centre map (through ``src_H_out``, the inverse of out_H_src) in
    front of the source and to a point whose bilinear neighbourhood is inside the source
    (u in [0, w-1], v in [0, h-1])? The map must not fold the output rectangle (the homogeneous
    scale keeps one sign on it); then its image is a convex quadrilateral and the border decides."""
    M = np.asarray(src_H_out, dtype=float)
    pts = _boundary(out_size)
    sizes = np.array([src_size], dtype=float)
    return bool(_covered_many(M[None], sizes, pts)[0])


def _sources_A(items_R: Sequence[np.ndarray], cams: Sequence[Camera]) -> tuple[np.ndarray, np.ndarray]:
    A = np.stack([c.K @ R.T for R, c in zip(items_R, cams)])
    sizes = np.array([c.size for c in cams], dtype=float)
    return A, sizes


def widest_zoom(rotations: Sequence[np.ndarray], cams: Sequence[Camera], out0: Camera) -> tuple[float, np.ndarray]:
    """Smallest zoom (widest FOV) at which every output pixel of every image is covered by its
    source. ``out0`` is the output camera at zoom 1. Coverage only grows with zoom (the output
    rectangle contains its principal point, so the rays shrink towards the optical axis).

    Returns (zoom, bad) with ``bad`` a boolean per image that is True where NO zoom works (the
    simulated optical axis leaves the source image); the zoom then covers the others."""
    A, sizes = _sources_A(rotations, cams)
    # identical (K R^T, size) pairs (no jitter) are one problem
    key = np.concatenate([A.reshape(len(A), -1), sizes], axis=1)
    uniq, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = np.asarray(inverse).reshape(-1)
    A_u, sizes_u = uniq[:, :9].reshape(-1, 3, 3), uniq[:, 9:]
    pts = _boundary(out0.size)
    ok_hi = _covered_many(A_u, sizes_u, _norm_boundary(out0, _ZOOM_HI, pts))
    bad = ~ok_hi[inverse]
    A_u, sizes_u = A_u[ok_hi], sizes_u[ok_hi]
    if len(A_u) == 0:
        return _ZOOM_HI, bad
    if np.all(_covered_many(A_u, sizes_u, _norm_boundary(out0, _ZOOM_LO, pts))):
        return _ZOOM_LO, bad
    lo, hi = math.log(_ZOOM_LO), math.log(_ZOOM_HI)
    while hi - lo > 1e-13:
        mid = 0.5 * (lo + hi)
        if np.all(_covered_many(A_u, sizes_u, _norm_boundary(out0, math.exp(mid), pts))):
            hi = mid
        else:
            lo = mid
    return math.exp(hi) * _ZOOM_SAFETY, bad


def draw_offsets(seed: int, item_id: str, pan_jitter: float = 0.0, tilt_jitter: float = 0.0,
                 roll_jitter: float = 0.0) -> tuple[float, float, float]:
    """Per-image (dpan, dtilt, droll), uniform in [-j, +j]. Depends only on (seed, item_id):
    adding or removing other images changes nothing, and the three variates are drawn even for a
    zero jitter, so changing one jitter does not change the others' draws."""
    digest = hashlib.sha256(f"vcprep-simulate\0{int(seed)}\0{item_id}".encode()).digest()
    a = np.random.default_rng(int.from_bytes(digest[:16], "little")).uniform(-1.0, 1.0, size=3)
    return float(pan_jitter * a[0]), float(tilt_jitter * a[1]), float(roll_jitter * a[2])
