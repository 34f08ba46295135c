"""Simulating another camera, exactly: a new dataset as if shot by a re-mounted, re-zoomed,
re-cropped camera at the same place.

Rotating a pinhole camera about its optical centre changes the image by the homography
``out_H_src = K' R K^-1`` for ANY scene (no flat-road assumption), and zooming or cropping only
changes K. So a dataset can be re-rendered exactly for another pan, tilt, roll, focal length,
image size and principal point. A change of mounting HEIGHT moves the optical centre: it needs
the depth of every pixel and cannot be simulated exactly from one image, so it is not offered.

Conventions (``../shared/docs/method.md``): pixels (u, v) with the origin at the centre of the
top-left pixel; camera frame x right, y down, z forward; ``tilt`` > 0 = pitched down, ``pan``
about the vertical axis after the tilt. Rotations:

* ``Rw(pan, tilt) = column_stack(pose_axes(pan, tilt))`` takes world directions to camera
  directions (its columns are the world axes in camera coordinates);
* a source of nominal pose (pan0, tilt0) re-mounted at (pan0 + dpan, tilt0 + dtilt) and rolled by
  ``roll`` has the camera-frame rotation ``R = Rroll(roll) @ Rw(pan0 + dpan, tilt0 + dtilt) @
  Rw(pan0, tilt0).T``: a direction d in the source camera frame is ``R @ d`` in the new one;
* ``Rroll(r) = [[cos r, -sin r, 0], [sin r, cos r, 0], [0, 0, 1]]``: **positive roll turns the
  picture clockwise on screen** (a point right of the principal point moves down; the right end
  of the horizon drops), i.e. the camera itself rolls counter-clockwise as seen from behind it.

Output camera: ``fx' = zoom*fx``, ``fy' = zoom*fy`` (pixel aspect kept), principal point at the
output image centre ``((W'-1)/2, (H'-1)/2 + horizon_shift)``. With ``flip`` the output is
mirrored left-right (``u -> W'-1-u``); the camera stays a pinhole with ``cx' -> W'-1-cx'`` (the same
value, it is central) in a mirrored world: pan and roll change sign, tilt is kept.

Vanishing points: the output VP of an image is ``out_H_src`` applied to the SOURCE image's road VP
(from a CSV ``id,u,v`` or, without one, the source camera's nominal-pose VP). The per-image
change is exact; the absolute VP is as good as the source VP.

Three layers (style.md): pure geometry (:func:`relative_rotation`, :func:`output_camera`,
:func:`widest_zoom`, ...), :func:`plan_simulation` (every image's H, VP and pose, all inputs
checked, nothing written) and :func:`simulate_dataset` (reads, warps, writes atomically).
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import cv2
import numpy as np

from . import __version__
from .build import Job
from .camera import Camera, camera_from_dict, camera_to_yaml
from .errors import GeometryError, InputError
from .homography import pose_axes, pose_from_vp, vp_from_pose
from .imageio import image_size, read_image, write_bytes_atomic, write_png
from .labels import LabelFormat, decode_label

__all__ = [
    "SimulateParams",
    "SimItem",
    "SimPlan",
    "SimSummary",
    "world_to_camera",
    "roll_matrix",
    "relative_rotation",
    "zoom_for_hfov",
    "hfov_for_zoom",
    "output_camera",
    "out_H_src_for",
    "covered",
    "widest_zoom",
    "draw_offsets",
    "plan_simulation",
    "simulate_arrays",
    "simulate_dataset",
    "recorded_homographies",
]

SIM_ALGORITHM = "simulate-v1"  # bump when outputs of identical inputs would change
_ZOOM_LO, _ZOOM_HI = 1e-6, 1e6  # bracket for the widest-FOV search
_ZOOM_SAFETY = 1.0 + 1e-9  # the chosen zoom is this much inside the limit (margin ~1e-7 px)


@dataclass(frozen=True)
class SimulateParams:
    """What to simulate. Angles in degrees; ``pan``/``tilt`` are changes of the mounting relative
    to the source camera's nominal pose; jitters draw uniformly in [-j, +j] per image."""

    size: tuple[int, int] | None = None  # output (W', H'); None = the (first) source image size
    hfov: float | None = None            # output horizontal FOV (edge to edge); None with zoom None = widest covered
    zoom: float | None = None            # focal length factor fx' = zoom*fx (alternative to hfov)
    pan: float = 0.0                     # fixed pan change
    tilt: float = 0.0                    # fixed tilt change (positive = further down)
    roll: float = 0.0                    # fixed roll (positive = picture turns clockwise)
    pan_jitter: float = 0.0
    tilt_jitter: float = 0.0
    roll_jitter: float = 0.0
    seed: int = 0                        # per-image draws depend only on (seed, image id)
    horizon_shift: float = 0.0           # output px; positive moves the principal point (and horizon) down
    greyscale: bool = False              # write 3-channel grey images
    flip: bool = False                   # mirror left-right (images, labels, camera)
    name: str | None = None              # name of the output camera (default: the output folder's name)


@dataclass(frozen=True)
class SimItem:
    """One image's simulated geometry. ``draw`` is the per-image jitter (dpan, dtilt, droll);
    ``out_H_src`` maps source pixels to output pixels (flip included); ``pose`` is the output
    image's (pan, tilt) from its VP and its roll (mirrored with flip)."""

    job: Job
    size: tuple[int, int]
    camera: Camera                       # the source camera at this image's size
    draw: tuple[float, float, float]
    rotation: np.ndarray                 # R (camera frame, before the flip)
    out_H_src: np.ndarray
    vp_source: tuple[float, float]
    vp_status: str                       # 'given' (VP file) or 'camera' (nominal pose)
    vp: tuple[float, float]              # output pixels
    pose: tuple[float, float, float]     # pan_deg, tilt_deg, roll_deg of the output image


@dataclass(frozen=True)
class SimPlan:
    params: SimulateParams
    source: Camera                       # the source camera at the first image's size (zoom refers to it)
    camera: Camera                       # the output camera (nominal pose)
    zoom: float
    fov_auto: bool
    items: list[SimItem]
    notes: list[str] = field(default_factory=list)

    @property
    def fov_deg(self) -> tuple[float, float]:
        return self.camera.fov_deg()


@dataclass
class SimSummary:
    out: Path
    total: int = 0
    written: int = 0
    up_to_date: int = 0
    removed: int = 0
    zoom: float = 1.0
    fov_deg: tuple[float, float] = (0.0, 0.0)
    fov_auto: bool = False
    size: tuple[int, int] = (0, 0)
    notes: list[str] = field(default_factory=list)

    def line(self) -> str:
        how = "widest covered" if self.fov_auto else "given"
        return (f"{self.total} images: {self.written} written, {self.up_to_date} up to date; "
                f"{self.size[0]}x{self.size[1]}, hfov {self.fov_deg[0]:.2f} deg ({how}), "
                f"vfov {self.fov_deg[1]:.2f} deg, zoom {self.zoom:.4f}"
                + (f"; {self.removed} outputs of images no longer given removed" if self.removed else ""))


# --- pure geometry ----------------------------------------------------------------------------

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


# --- planning: every image's geometry, all inputs checked, nothing written ----------------------

def _check_params(p: SimulateParams) -> None:
    def finite(name: str, v: float) -> None:
        if not math.isfinite(v):
            raise InputError(f"{name} is {v}", name, "give a finite number")

    for name in ("pan", "tilt", "roll", "pan_jitter", "tilt_jitter", "roll_jitter", "horizon_shift"):
        finite("--" + name.replace("_", "-"), getattr(p, name))
    for name in ("pan_jitter", "tilt_jitter", "roll_jitter"):
        if getattr(p, name) < 0:
            raise InputError(f"{getattr(p, name):g} is negative", "--" + name.replace("_", "-"),
                             "a jitter is a half-range in degrees, >= 0")
    if abs(p.pan) + p.pan_jitter >= 80 or abs(p.tilt) + p.tilt_jitter >= 80:
        raise InputError("pan/tilt change of 80 degrees or more", "--pan/--tilt", "use degrees, well below 80")
    if p.hfov is not None and p.zoom is not None:
        raise InputError("both --hfov and --zoom given", "--hfov/--zoom", "give one of them, or neither for the widest covered view")
    if p.hfov is not None and not (0 < p.hfov < 180):
        raise InputError(f"hfov {p.hfov:g} is out of range", "--hfov", "give degrees in (0, 180)")
    if p.zoom is not None and not (math.isfinite(p.zoom) and p.zoom > 0):
        raise InputError(f"zoom {p.zoom:g} is out of range", "--zoom", "give a positive factor, e.g. 1.5")


def plan_simulation(jobs: Sequence[Job], camera: Camera, params: SimulateParams,
                    vps: Mapping[str, tuple[float, float]] | None = None, vps_file: str | Path | None = None,
                    out_name: str = "simulated") -> SimPlan:
    """The geometry of a simulation: output camera, zoom (given, from hfov, or the widest that
    covers every image) and each image's draw, ``out_H_src``, VP and pose. Reads only file
    headers; every problem raises :class:`InputError` / :class:`GeometryError`."""
    _check_params(params)
    if not jobs:
        raise InputError("no images to simulate", None, "check --images")
    sizes = [image_size(j.image, "image") for j in jobs]
    for j, s in zip(jobs, sizes):
        if j.label is not None:
            ls = image_size(j.label, "label")
            if ls != s:
                raise InputError(f"label is {ls[0]}x{ls[1]} but its image is {s[0]}x{s[1]}", j.label,
                                 "give the label that belongs to this image")
    cams = [camera.for_image_size(s, j.image) for j, s in zip(jobs, sizes)]
    ref = cams[0]
    out_size = tuple(params.size) if params.size is not None else ref.size
    if abs(params.horizon_shift) > (out_size[1] - 1) / 2.0:
        raise InputError(f"horizon shift {params.horizon_shift:g} px moves the principal point out of the "
                         f"{out_size[0]}x{out_size[1]} output", "--horizon-shift",
                         f"use at most +/-{(out_size[1] - 1) / 2.0:g} px")
    out0 = output_camera(ref, out_size, 1.0, params.horizon_shift, params.name or out_name)

    pan0, tilt0 = camera.pan, camera.tilt
    draws = [draw_offsets(params.seed, j.id, params.pan_jitter, params.tilt_jitter, params.roll_jitter) for j in jobs]
    rots = [relative_rotation(pan0, tilt0, pan0 + params.pan + d[0], tilt0 + params.tilt + d[1], params.roll + d[2])
            for d in draws]

    # the zoom: given, from hfov, or the widest covering every image
    fixed = params.zoom if params.zoom is not None else (
        zoom_for_hfov(ref.fx, out_size[0], params.hfov) if params.hfov is not None else None)
    best, bad = widest_zoom(rots, cams, out0)  # also needed to tell the user what a given hfov should be
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        d = draws[i]
        raise InputError(
            f"the simulated optical axis (pan {params.pan + d[0]:+.2f}, tilt {params.tilt + d[1]:+.2f} deg from "
            f"the source pose) points outside this {sizes[i][0]}x{sizes[i][1]} source image, so no field of view "
            "fits inside it", jobs[i].image, "reduce --pan/--tilt or their jitter")
    if fixed is None:
        zoom = best
    else:
        zoom = float(fixed)
        A, sz = _sources_A(rots, cams)
        ok = _covered_many(A, sz, _norm_boundary(out0, zoom, _boundary(out_size)))
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            max_hfov = math.floor(hfov_for_zoom(ref.fx, out_size[0], best) * 100) / 100
            given = f"--hfov {params.hfov:g}" if params.hfov is not None else f"--zoom {params.zoom:g}"
            raise InputError(
                f"with {given} ({out_size[0]}x{out_size[1]}) the simulated view of this image reaches outside the source "
                f"image ({sum(~ok)} of {len(ok)} images)", jobs[i].image,
                f"use --hfov {max_hfov:.2f} or less, the widest that covers every image, i.e. --zoom {best:.4f} or "
                "more; or leave out --hfov/--zoom to choose it automatically")
    out_cam = replace(out0, fx=zoom * ref.fx, fy=zoom * ref.fy)

    # nominal pose of the output camera: the VP of the mean draw from the nominal source VP
    R_mean = relative_rotation(pan0, tilt0, pan0 + params.pan, tilt0 + params.tilt, params.roll)
    H_mean = out_H_src_for(ref, out_cam, R_mean, params.flip)
    vp_mean = _map_vp(H_mean, vp_from_pose(ref), "the camera's nominal vanishing point", None)
    pan_n, tilt_n = pose_from_vp(out_cam, vp_mean)
    out_cam = replace(out_cam, pan=pan_n, tilt=tilt_n)
    try:
        camera_from_dict(out_cam.to_dict(), "camera.yaml")
    except InputError as e:
        raise InputError(f"the simulated camera is not valid: {e.problem}", "--pan/--tilt/--size",
                         "choose a smaller pose change or another size") from None

    items = []
    for j, s, cam, d, R in zip(jobs, sizes, cams, draws, rots):
        H = out_H_src_for(cam, out_cam, R, params.flip)
        if vps is not None:
            vp_src = vps.get(j.id, vps.get(j.image.stem))
            if vp_src is None:
                raise InputError(f"no row for image '{j.id}'", vps_file, f"add a row '{j.id},u,v' (source pixels) or drop --vps")
            status = "given"
        else:
            vp_src, status = vp_from_pose(cam), "camera"
        vp = _map_vp(H, vp_src, f"the vanishing point of '{j.id}'", vps_file)
        pan_i, tilt_i = pose_from_vp(out_cam, vp)
        roll_i = params.roll + d[2]
        items.append(SimItem(j, s, cam, d, R, H, (float(vp_src[0]), float(vp_src[1])), status, vp,
                             (pan_i, tilt_i, (-roll_i if params.flip else roll_i) + 0.0)))
    notes = []
    if params.roll != 0 or params.roll_jitter != 0:
        notes.append("the camera model has no roll: camera.yaml holds the pose of the road VP without the roll; "
                     "per-image rolls are in poses.csv")
    return SimPlan(params, ref, out_cam, zoom, fixed is None, items, notes)


def _map_vp(H: np.ndarray, vp: tuple[float, float], what: str, file) -> tuple[float, float]:
    p = H @ np.array([vp[0], vp[1], 1.0])
    if not p[2] > 1e-12:
        raise GeometryError(f"{what} ({vp[0]:g}, {vp[1]:g}) lies behind the simulated camera", file,
                            "check the VP (source pixels) and reduce --pan/--tilt")
    return float(p[0] / p[2]), float(p[1] / p[2])


# --- one image in memory ----------------------------------------------------------------------

def simulate_arrays(image: np.ndarray, label: np.ndarray | None, out_H_src: np.ndarray, out_size: tuple[int, int],
                    greyscale: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """Warp one image (bilinear, any depth/channels) and its raw label (nearest: ids or colours
    kept) through ``out_H_src`` to ``out_size``. Every output pixel must be covered (see
    :func:`covered`); ``greyscale`` gives a 3-channel grey image."""
    from .warp import maps_for, warp_image, warp_label

    h, w = image.shape[:2]
    maps = maps_for(out_H_src, (w, h), tuple(out_size))
    if not maps.valid.all():
        raise GeometryError("the simulated view reaches outside the source image", None,
                            "plan the simulation with plan_simulation, which checks coverage")
    img = warp_image(image, maps)
    if greyscale:
        g = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
        img = cv2.merge([g, g, g])
    lab = warp_label(label, maps) if label is not None else None
    return img, lab


# --- the dataset driver -----------------------------------------------------------------------

def _sha(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _csv(header: list[str], rows: list[list[Any]]) -> bytes:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue().encode()


def _params_dict(plan: SimPlan, fmt: LabelFormat | None, vps_file) -> dict[str, Any]:
    p = asdict(plan.params)
    p["size"] = list(plan.camera.size)
    return {**p, "label_format": fmt.name if fmt else None, "vps": str(vps_file) if vps_file else None}


def _item_key(plan: SimPlan, item: SimItem, img_sha: str, lab_sha: str | None, fmt: LabelFormat | None) -> str:
    parts = {"algorithm": SIM_ALGORITHM, "camera": plan.camera.to_dict(), "greyscale": plan.params.greyscale,
             "H": [float(x) for x in item.out_H_src.ravel()], "image": img_sha, "label": lab_sha,
             "label_format": fmt.name if fmt else None}
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def recorded_homographies(out: str | Path) -> dict[str, np.ndarray]:
    """{item id: out_H_src (3, 3)} of a finished ``vcprep simulate`` output folder, read from its
    ``simulate.json``: the exact map from each source frame's pixels to its simulated frame's
    (pixel centres, origin at the top-left pixel's centre), e.g. to carry anything computed on a
    source frame (a prediction, a detected VP) into the simulated camera. A missing, unfinished or
    unreadable record raises :class:`InputError`."""
    meta = Path(out) / "simulate.json"
    try:
        doc = json.loads(meta.read_text())
        if not doc.get("complete"):
            raise InputError("the simulation is unfinished", meta, "run the same 'vcprep simulate' again")
        return {str(r["id"]): np.asarray(r["out_H_src"], dtype=np.float64).reshape(3, 3) for r in doc["items"]}
    except FileNotFoundError:
        raise InputError("no simulate.json", meta, "give the folder of a 'vcprep simulate' output") from None
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
        raise InputError(f"unreadable simulation record ({e.__class__.__name__}: {e})", meta,
                         "run the same 'vcprep simulate' again") from None


def _prepare_out(out: Path) -> dict[str, dict]:
    """Check OUT is new, empty or an earlier simulate output; return its earlier item records."""
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a folder", out, "give a new folder for --out")
    meta = out / "simulate.json"
    if out.is_dir() and any(out.iterdir()) and not meta.is_file():
        raise InputError("folder is not empty and holds no simulate.json", out,
                         "give a new or empty folder, or the folder of an earlier 'vcprep simulate'")
    if not meta.is_file():
        return {}
    try:
        old = json.loads(meta.read_text())
        return {r["id"]: r for r in old.get("items", []) if isinstance(r, dict) and "id" in r}
    except (OSError, ValueError, AttributeError, TypeError):
        return {}


def simulate_dataset(jobs: Sequence[Job], camera: Camera, out: str | Path, params: SimulateParams,
                     fmt: LabelFormat | None = None, vps_file: str | Path | None = None,
                     progress: bool = True) -> tuple[SimPlan, SimSummary]:
    """Write the simulated dataset to ``out``: ``images/<stem>.png``, ``labels/<label name>.png``
    (raw values), ``camera.yaml``, ``vps.csv`` (id,u,v output pixels), ``poses.csv``
    (id,pan_deg,tilt_deg,roll_deg: pan/tilt of the output image's road VP through the output
    camera, plus its roll) and ``simulate.json`` (parameters, cameras, zoom, per-image H, hashes).

    Everything is checked before anything is written; files are written atomically. Re-running
    with the same inputs skips the images whose recorded outputs are unchanged; outputs of images
    no longer in the input are removed (OUT holds exactly one simulated dataset)."""
    from tqdm import tqdm

    from .vanishing_point import read_vp_csv

    out = Path(out)
    for j in jobs:
        for src, sub in ((j.image, "images"), (j.label, "labels")):
            if src is not None and src.parent.resolve() == (out / sub).resolve():
                raise InputError("--out would overwrite the source files", out, "give another folder for --out")
    vps = read_vp_csv(vps_file) if vps_file is not None else None
    labelled = [j.label for j in jobs if j.label is not None]
    if labelled and fmt is None:
        raise InputError("labels given without a label format", labelled[0], "add --label-format (e.g. camvid)")
    plan = plan_simulation(jobs, camera, params, vps, vps_file, out_name=out.name or "simulated")
    old = _prepare_out(out)
    cam = plan.camera
    img_dir, lab_dir = out / "images", out / "labels"
    has_labels = any(it.job.label is not None for it in plan.items)
    out.mkdir(parents=True, exist_ok=True)
    img_dir.mkdir(exist_ok=True)
    if has_labels:
        lab_dir.mkdir(exist_ok=True)

    summary = SimSummary(out, total=len(plan.items), zoom=plan.zoom, fov_deg=plan.fov_deg, fov_auto=plan.fov_auto,
                         size=cam.size, notes=list(plan.notes))
    records: dict[str, dict] = {}

    def meta(complete: bool) -> None:
        recs = [records.get(it.job.id) or old.get(it.job.id) for it in plan.items]
        hf, vf = plan.fov_deg
        doc = {"format": "vcprep-simulate", "version": 1, "tool_version": __version__, "algorithm": SIM_ALGORITHM,
               "complete": complete, "parameters": _params_dict(plan, fmt, vps_file),
               "source_camera": plan.source.to_dict(), "camera": cam.to_dict(), "zoom": plan.zoom,
               "fov_deg": [hf, vf], "fov_auto": plan.fov_auto,
               "counts": {"images": len(plan.items), "labels": sum(it.job.label is not None for it in plan.items),
                          "written": summary.written, "up_to_date": summary.up_to_date},
               "items": [r for r in recs if r is not None]}
        write_bytes_atomic(out / "simulate.json", (json.dumps(doc, indent=1) + "\n").encode())

    # the marker first (OUT is ours from now on), then the files that need only the geometry
    meta(False)
    write_bytes_atomic(out / "camera.yaml", camera_to_yaml(cam).encode())
    write_bytes_atomic(out / "vps.csv", _csv(["id", "u", "v"], [[it.job.id, f"{it.vp[0]:.9f}", f"{it.vp[1]:.9f}"]
                                                                for it in plan.items]))
    write_bytes_atomic(out / "poses.csv", _csv(["id", "pan_deg", "tilt_deg", "roll_deg"],
                                               [[it.job.id] + [f"{x:.9f}" for x in it.pose] for it in plan.items]))
    # OUT holds exactly this dataset: drop outputs of images no longer given and stray temp files
    keep = {img_dir / f"{it.job.image.stem}.png" for it in plan.items}
    keep |= {lab_dir / f"{it.job.label.stem}.png" for it in plan.items if it.job.label is not None}
    for d in (img_dir, lab_dir):
        if d.is_dir():
            for f in d.iterdir():
                if f.is_file() and f not in keep and (f.suffix == ".png" or f.name.endswith(".tmp")):
                    f.unlink()
                    summary.removed += 1

    bar = tqdm(total=len(plan.items), desc="simulate", unit="img", disable=None if progress else True, leave=False)
    try:
        for it in plan.items:
            records[it.job.id] = _simulate_item(it, plan, fmt, img_dir, lab_dir, old.get(it.job.id), summary)
            bar.update()
    except BaseException:
        meta(False)  # keep what is finished, so that re-running skips it
        raise
    finally:
        bar.close()
    meta(True)
    return plan, summary


def _simulate_item(it: SimItem, plan: SimPlan, fmt: LabelFormat | None, img_dir: Path, lab_dir: Path,
                   old: dict | None, summary: SimSummary) -> dict:
    job = it.job
    try:
        img_bytes = job.image.read_bytes()
        lab_bytes = job.label.read_bytes() if job.label is not None else None
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", e.filename, "check the file") from None
    img_sha = hashlib.sha256(img_bytes).hexdigest()
    lab_sha = hashlib.sha256(lab_bytes).hexdigest() if lab_bytes is not None else None
    key = _item_key(plan, it, img_sha, lab_sha, fmt)
    out_img = img_dir / f"{job.image.stem}.png"
    out_lab = lab_dir / f"{job.label.stem}.png" if job.label is not None else None
    if (old is not None and old.get("key") == key and _sha(out_img) == old.get("out_image_sha256")
            and (out_lab is None or _sha(out_lab) == old.get("out_label_sha256"))):
        summary.up_to_date += 1
        return old
    img = read_image(job.image).array
    if img.shape[1::-1] != it.size:
        raise InputError(f"image is {img.shape[1]}x{img.shape[0]}, its header said {it.size[0]}x{it.size[1]}",
                         job.image, "re-copy or re-export the file")
    lab = None
    if job.label is not None:
        lab = read_image(job.label, label=True).array
        if lab.shape[:2] != img.shape[:2]:
            raise InputError(f"label is {lab.shape[1]}x{lab.shape[0]} but its image is {img.shape[1]}x{img.shape[0]}",
                             job.label, "give the label that belongs to this image")
        decode_label(lab, fmt, job.label)  # refuse labels the format cannot read (the output keeps raw values)
    wimg, wlab = simulate_arrays(img, lab, it.out_H_src, plan.camera.size, plan.params.greyscale)
    img_out_sha = write_png(out_img, wimg)
    lab_out_sha = write_png(out_lab, wlab, kind="mask") if wlab is not None else None
    summary.written += 1
    return {"id": job.id, "image": str(job.image), "image_sha256": img_sha,
            "label": str(job.label) if job.label is not None else None, "label_sha256": lab_sha,
            "draw_deg": list(it.draw), "out_H_src": [float(x) for x in it.out_H_src.ravel()],
            "vp_source": list(it.vp_source), "vp_status": it.vp_status, "vp": list(it.vp),
            "pose_deg": list(it.pose), "out_image": f"images/{out_img.name}", "out_image_sha256": img_out_sha,
            "out_label": f"labels/{out_lab.name}" if out_lab is not None else None, "out_label_sha256": lab_out_sha,
            "key": key}
