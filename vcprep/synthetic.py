"""Synthetic road scenes with exactly known geometry: the oracle for tests and benchmarks.

A flat road plane (world Y = 0, X right, Z along the road) with an asphalt texture, lane markings
and kerbs, grass beside it and a sky above the horizon, ray-traced through any :class:`Camera`
at any pan/tilt. Because texture and masks are functions of the world point, two cameras that see
the same road point see the same colour: you know the road mask, the vanishing point
(:func:`vcprep.warp.homography.vp_from_pose`) and the exact ground homography.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera.pinhole import Camera
from .warp.homography import pose_axes

__all__ = ["RoadScene", "render_road", "road_fraction", "ground_points", "obstacle_hit"]


@dataclass(frozen=True)
class RoadScene:
    """Road layout in metres. The road runs along world Z, centred at X = ``offset``."""

    offset: float = 0.0          # lateral position of the road centre (m)
    width: float = 8.0           # road width kerb to kerb (m)
    lanes: int = 2               # lanes; markings between them are dashed
    marking_width: float = 0.15  # lane/edge marking width (m)
    dash_length: float = 3.0     # dashed marking: painted length, then the same gap (m)
    kerb_width: float = 0.3      # kerb strip outside the road edge (m)
    texture_seed: int = 0        # phase of the asphalt / grass texture
    sky_rgb: tuple[int, int, int] = (200, 170, 120)  # BGR-ish pale blue
    obstacle: tuple[float, float, float, float] | None = None  # a wall across the road: x0, x1, z, height (m)


def _rays(cam: Camera, pan: float | None, tilt: float | None, supersample: int,
          roll: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World directions (dx, dy, dz) of the rays through each pixel centre (or sub-sample), shapes
    (h*ss, w*ss); ``roll`` (degrees) turns the camera about its optical axis after pan and tilt
    (positive: the image turns clockwise, the horizon's right end drops)."""
    pan = cam.pan if pan is None else pan
    tilt = cam.tilt if tilt is None else tilt
    w, h = cam.size
    ss = int(supersample)
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    u = (np.arange(w)[:, None] + offs[None, :]).reshape(-1)
    v = (np.arange(h)[:, None] + offs[None, :]).reshape(-1)
    R1, R2, R3 = pose_axes(pan, tilt)
    c, s_ = np.cos(np.radians(roll)), np.sin(np.radians(roll))
    Rz = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
    R = Rz @ np.column_stack([R1, R2, R3])  # P_cam = R P_world + t
    Kinv = np.linalg.inv(cam.K)
    # ray in camera coordinates, then in world coordinates: d_w = R^T d_c
    dc_x = Kinv[0, 0] * u + Kinv[0, 2]
    dc_y = Kinv[1, 1] * v + Kinv[1, 2]
    Rt = R.T
    return tuple(Rt[i, 0] * dc_x[None, :] + Rt[i, 1] * dc_y[:, None] + Rt[i, 2] for i in range(3))


def ground_points(cam: Camera, pan: float | None = None, tilt: float | None = None,
                  supersample: int = 1, roll: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World road-plane coordinates (X, Z) seen by each pixel centre (or sub-sample), and a
    boolean ``hit`` that is False where the ray points at or above the horizon.

    Shapes (h*ss, w*ss). Sub-samples sit on a regular grid inside each pixel.
    """
    dwx, dwy, dwz = _rays(cam, pan, tilt, supersample, roll)
    hit = dwy > 1e-9
    s = np.where(hit, cam.height / np.where(hit, dwy, 1.0), 0.0)  # camera centre is at Y = -h
    return s * dwx, s * dwz, hit


def obstacle_hit(cam: Camera, scene: "RoadScene", X: np.ndarray, Z: np.ndarray, hit: np.ndarray,
                 pan: float | None = None, tilt: float | None = None, supersample: int = 1,
                 roll: float = 0.0) -> np.ndarray:
    """Where the rays meet ``scene.obstacle`` (a wall across the road, (x0, x1, z, height) metres)
    before the road: False everywhere without one."""
    if scene.obstacle is None:
        return np.zeros(X.shape, dtype=bool)
    x0, x1, zo, top = scene.obstacle
    dwx, dwy, dwz = _rays(cam, pan, tilt, supersample, roll)
    s = np.where(dwz > 1e-9, zo / np.where(dwz > 1e-9, dwz, 1.0), -1.0)
    xw, yw = s * dwx, -cam.height + s * dwy
    return (s > 0) & (xw >= x0) & (xw <= x1) & (yw >= -top) & (yw <= 0) & (~hit | (Z >= zo))


def _smooth_noise(X: np.ndarray, Z: np.ndarray, seed: int, scale: float) -> np.ndarray:
    """Band-limited texture in [-1, 1]: a few sinusoids of world position (no aliasing hash)."""
    rng = np.random.default_rng(seed)
    out = np.zeros_like(X)
    for _ in range(6):
        kx, kz = rng.normal(size=2) * scale
        ph = rng.uniform(0, 2 * np.pi)
        out += np.sin(kx * X + kz * Z + ph)
    return out / 6.0


def _road_layers(X: np.ndarray, Z: np.ndarray, scene: RoadScene):
    x = X - scene.offset
    half = scene.width / 2
    ax = np.abs(x)
    road = ax < half
    kerb = (ax >= half) & (ax < half + scene.kerb_width)
    mw = scene.marking_width
    # solid edge lines just inside the kerbs
    marks = road & (ax > half - 0.2 - mw) & (ax < half - 0.2)
    # dashed lane separators
    lane_w = scene.width / scene.lanes
    for i in range(1, scene.lanes):
        xc = -half + i * lane_w
        dashed = np.mod(Z, 2 * scene.dash_length) < scene.dash_length
        marks |= road & (np.abs(x - xc) < mw / 2) & dashed
    return road, kerb, marks


def render_road(cam: Camera, scene: RoadScene = RoadScene(), pan: float | None = None,
                tilt: float | None = None, supersample: int = 3,
                max_distance: float = 400.0, roll: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Render ``scene`` through ``cam`` (pose overridden by ``pan``/``tilt`` in degrees, turned by
    ``roll`` degrees about the optical axis; an ``obstacle`` wall is not road and hides what is behind).

    Returns ``(image, label)``: a (h, w, 3) uint8 BGR image and a (h, w) uint8 label with
    1 = road, 0 = not road (the label is the road membership at the pixel centre). Ground points
    farther than ``max_distance`` fade into a haze colour so that the horizon stays smooth.
    """
    ss = max(1, int(supersample))
    X, Z, hit = ground_points(cam, pan, tilt, ss, roll)
    wall = obstacle_hit(cam, scene, X, Z, hit, pan, tilt, ss, roll)
    road, kerb, marks = _road_layers(X, Z, scene)
    road &= ~wall
    n1 = _smooth_noise(X, Z, scene.texture_seed, 1.3)
    n2 = _smooth_noise(X, Z, scene.texture_seed + 1, 0.4)
    asphalt = 95 + 25 * n1 + 12 * n2
    grass_g = 120 + 30 * n1 + 20 * n2
    img = np.empty(X.shape + (3,), dtype=np.float64)
    img[..., 0] = 40 + 10 * n2
    img[..., 1] = grass_g
    img[..., 2] = 60 + 10 * n1
    for c in range(3):
        img[..., c] = np.where(road, asphalt, img[..., c])
    kerb_col = np.where(np.mod(Z, 2.0) < 1.0, 1.0, 0.0)  # red/white kerb blocks
    img[..., 0] = np.where(kerb, 60 + 180 * kerb_col, img[..., 0])
    img[..., 1] = np.where(kerb, 60 + 180 * kerb_col, img[..., 1])
    img[..., 2] = np.where(kerb, 220, img[..., 2])
    for c in range(3):
        img[..., c] = np.where(marks, 235, img[..., c])
    dist = np.hypot(X, Z)
    haze = np.clip(dist / max_distance, 0, 1)[..., None]
    sky = np.array(scene.sky_rgb, dtype=np.float64)
    img = img * (1 - haze) + sky * haze
    img[~hit] = sky
    img[wall] = (70, 70, 90)
    h, w = cam.size[1], cam.size[0]
    img = img.reshape(h, ss, w, ss, 3).mean(axis=(1, 3))
    image = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    # label at the pixel centre (the middle sub-sample for odd ss)
    if ss % 2 == 1:
        mid = ss // 2
        label = (road & hit).reshape(h, ss, w, ss)[:, mid, :, mid]
    else:
        Xc, Zc, hc = ground_points(cam, pan, tilt, 1, roll)
        label = _road_layers(Xc, Zc, scene)[0] & hc & ~obstacle_hit(cam, scene, Xc, Zc, hc, pan, tilt, 1, roll)
    return image, label.astype(np.uint8)


def road_fraction(cam: Camera, scene: RoadScene = RoadScene(), pan: float | None = None, tilt: float | None = None,
                  supersample: int = 4, roll: float = 0.0) -> np.ndarray:
    """(h, w) float: the share of each pixel's ``supersample``^2 sub-samples that see road (an
    obstacle hides it): an ideal road probability map, exact to a fraction of a pixel at the road's
    edges where a label at the pixel centre is exact to half a pixel."""
    ss = max(1, int(supersample))
    X, Z, hit = ground_points(cam, pan, tilt, ss, roll)
    road = _road_layers(X, Z, scene)[0] & hit & ~obstacle_hit(cam, scene, X, Z, hit, pan, tilt, ss, roll)
    h, w = cam.size[1], cam.size[0]
    return road.reshape(h, ss, w, ss).mean(axis=(1, 3))
