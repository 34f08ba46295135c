"""Ground-plane homographies between a physical camera and the virtual camera (paper eqs. 2-8).

Every matrix is named ``dst_H_src``: it maps homogeneous pixel coordinates of ``src`` to those of
``dst`` (column vectors, (u, v, 1), pixel centres at integers). World frame: X right, Y down,
Z along the road, road plane Y = 0, camera at Y = -h (method.md).
"""
from __future__ import annotations

import math

import numpy as np

from ..camera.pinhole import Camera, scale_matrix
from ..errors import GeometryError

__all__ = [
    "pose_axes",
    "ground_to_image",
    "virt_H_src",
    "pose_from_vp",
    "vp_from_pose",
    "apply_homography",
    "check_not_folded",
    "virtual_at_scale",
    "road_magnification",
]

ROAD_FROM = 0.15  # road_magnification: the road region starts this share of the way from the VP row to the bottom


def pose_axes(pan_deg: float, tilt_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World axes in camera coordinates for a camera tilted by ``tilt`` (down > 0) then panned.

    Returns (R1, R2, R3): world X (right), Y (down) and Z (road direction) expressed in the
    camera frame, i.e. the columns of R in ``P_cam = R @ P_world + t``.
    """
    a, b = math.radians(pan_deg), math.radians(tilt_deg)
    R1 = np.array([math.cos(a), 0.0, -math.sin(a)])
    R3 = np.array([math.sin(a) * math.cos(b), -math.sin(b), math.cos(a) * math.cos(b)])
    R2 = np.cross(R3, R1)
    return R1, R2, R3


def ground_to_image(cam: Camera, pan: float | None = None, tilt: float | None = None) -> np.ndarray:
    """``G = K [R1 | R3 | t]`` (3x3): road-plane point (X, Z, 1) -> pixel (u, v, 1) of ``cam``.

    ``pan``/``tilt`` (degrees) override the camera's average pose (within-camera correction);
    ``t = h * R2`` puts the world origin on the road straight below the camera.
    """
    pan = cam.pan if pan is None else pan
    tilt = cam.tilt if tilt is None else tilt
    R1, R2, R3 = pose_axes(pan, tilt)
    t = cam.height * R2
    return cam.K @ np.column_stack([R1, R3, t])


def virt_H_src(src: Camera, virt: Camera, pan: float | None = None, tilt: float | None = None) -> np.ndarray:
    """``H = G_v @ inv(G_p)``: source pixels -> virtual pixels through the road plane.

    Normalised so that H[2, 2] > 0 where the source principal point maps with positive depth.
    """
    Gp = ground_to_image(src, pan, tilt)
    Gv = ground_to_image(virt)
    H = Gv @ np.linalg.inv(Gp)
    w = H[2] @ np.array([src.cx, src.cy, 1.0])
    if w < 0:
        H = -H
    return H / np.abs(H).max()


def virtual_at_scale(virt: Camera, scale: float) -> Camera:
    """The virtual camera at ``scale`` of its full resolution (square pixels kept; K follows the
    pixel-centre rule; the size is rounded to whole pixels, e.g. 5500x2800 at 1/8 -> 688x350)."""
    if not (0 < scale <= 4):
        raise GeometryError(f"scale {scale} is out of range", None, "use a scale in (0, 4], e.g. 0.125")
    size = (max(1, int(round(virt.size[0] * scale))), max(1, int(round(virt.size[1] * scale))))
    return virt.resized(scale, scale, size=size)


def pose_from_vp(cam: Camera, vp: tuple[float, float]) -> tuple[float, float]:
    """Pan and tilt (degrees) implied by the road vanishing point ``vp`` = (u, v) (eqs. 6-8)."""
    d = np.array([(vp[0] - cam.cx) / cam.fx, (vp[1] - cam.cy) / cam.fy, 1.0])
    R3 = d / np.linalg.norm(d)
    pan = math.degrees(math.atan2(d[0], 1.0))
    tilt = math.degrees(math.asin(-R3[1]))
    return pan, tilt


def vp_from_pose(cam: Camera, pan: float | None = None, tilt: float | None = None) -> tuple[float, float]:
    """The road vanishing point (u, v) of ``cam`` at the given pose: the image of R3."""
    pan = cam.pan if pan is None else pan
    tilt = cam.tilt if tilt is None else tilt
    R3 = pose_axes(pan, tilt)[2]
    p = cam.K @ R3
    return float(p[0] / p[2]), float(p[1] / p[2])


def apply_homography(H: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Map (N, 2) points through the 3x3 ``H``; returns (N, 2)."""
    pts = np.asarray(pts, dtype=float).reshape(-1, 2)
    p = np.column_stack([pts, np.ones(len(pts))]) @ np.asarray(H, dtype=float).T
    return p[:, :2] / p[:, 2:3]


def check_not_folded(H: np.ndarray, size: tuple[int, int], what: str | None = None) -> None:
    """Raise :class:`GeometryError` if the line that ``H`` sends to infinity crosses the image
    rectangle of ``size`` (w, h) (outer pixel edges): the warp would fold the image over."""
    w, h = size
    corners = np.array([[-0.5, -0.5, 1], [w - 0.5, -0.5, 1], [w - 0.5, h - 0.5, 1], [-0.5, h - 0.5, 1]])
    s = corners @ np.asarray(H, dtype=float)[2]
    if not (np.all(s > 0) or np.all(s < 0)):
        raise GeometryError(
            "the ground-plane homography sends a line crossing the image to infinity "
            "(the road plane is seen edge-on or from behind), so the warp would fold the image",
            what,
            "check the camera height, tilt and pan (tilt in degrees, positive = pitched down)",
        )


def scaled_homography(H: np.ndarray, src_scale: float = 1.0, dst_scale: float = 1.0) -> np.ndarray:
    """Re-express ``H`` for a source resized by ``src_scale`` and a destination by ``dst_scale``."""
    return scale_matrix(dst_scale) @ H @ np.linalg.inv(scale_matrix(src_scale))


def road_magnification(H: np.ndarray, size: tuple[int, int], vp_row: float, n: int = 24) -> float:
    """Destination pixels per source pixel on the road under ``H`` (linear: ``sqrt|det J|`` of the
    projective map, ``det J = det H / w^3``): the median over an ``n`` x ``n`` grid of the source frame
    of ``size`` (w, h) from :data:`ROAD_FROM` of the way below ``vp_row`` to the bottom row. Above 1 the
    warp enlarges the frame: the destination holds fewer real pixels than it has (a blurred image)."""
    H = np.asarray(H, dtype=np.float64).reshape(3, 3)
    w, h = int(size[0]), int(size[1])
    y0 = min(h - 1.0, max(0.0, vp_row + ROAD_FROM * (h - 1.0 - vp_row)))
    xs, ys = np.meshgrid(np.linspace(0.0, w - 1.0, n), np.linspace(y0, h - 1.0, n))
    depth = H[2, 0] * xs + H[2, 1] * ys + H[2, 2]
    return float(np.median(np.sqrt(np.abs(np.linalg.det(H) / depth ** 3))))
