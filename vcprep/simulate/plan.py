"""Planning a simulation (:mod:`vcprep.simulate`): what to simulate (:class:`SimulateParams`),
every image's geometry (:class:`SimItem`) and the whole plan (:func:`plan_simulation`), all inputs
checked, nothing written. Reads only image headers."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..dataset import Job
from ..camera.pinhole import Camera
from ..camera.files import camera_from_dict
from ..errors import GeometryError, InputError
from ..warp.homography import pose_from_vp, vp_from_pose
from ..io.images import image_size
from .geometry import (_boundary, _covered_many, _norm_boundary, _sources_A, draw_offsets, hfov_for_zoom,
                                out_H_src_for, output_camera, relative_rotation, widest_zoom, zoom_for_hfov)

__all__ = ["SimulateParams", "SimItem", "SimPlan", "plan_simulation"]


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
    sizes, cams = _source_cameras(jobs, camera)
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
    zoom, fov_auto = _choose_zoom(params, jobs, sizes, cams, draws, rots, out0)
    out_cam = _nominal_output_camera(params, ref, replace(out0, fx=zoom * ref.fx, fy=zoom * ref.fy), pan0, tilt0)

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
    return SimPlan(params, ref, out_cam, zoom, fov_auto, items, notes)


def _source_cameras(jobs: Sequence[Job], camera: Camera) -> tuple[list[tuple[int, int]], list[Camera]]:
    """Each image's size (from its header; its label must match) and the source camera at it."""
    sizes = [image_size(j.image, "image") for j in jobs]
    for j, s in zip(jobs, sizes):
        if j.label is not None:
            ls = image_size(j.label, "label")
            if ls != s:
                raise InputError(f"label is {ls[0]}x{ls[1]} but its image is {s[0]}x{s[1]}", j.label,
                                 "give the label that belongs to this image")
    return sizes, [camera.for_image_size(s, j.image) for j, s in zip(jobs, sizes)]


def _choose_zoom(params: SimulateParams, jobs: Sequence[Job], sizes, cams: Sequence[Camera], draws, rots,
                 out0: Camera) -> tuple[float, bool]:
    """The zoom: given, from hfov, or the widest covering every image; and whether it was chosen
    automatically. A given one that leaves an image uncovered names the widest that works."""
    ref, out_size = cams[0], out0.size
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
        return best, True
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
    return zoom, False


def _nominal_output_camera(params: SimulateParams, ref: Camera, out_cam: Camera, pan0: float, tilt0: float) -> Camera:
    """``out_cam`` at its nominal pose: that of the VP of the mean draw from the nominal source VP;
    the result must be a valid camera."""
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
    return out_cam


def _map_vp(H: np.ndarray, vp: tuple[float, float], what: str, file) -> tuple[float, float]:
    p = H @ np.array([vp[0], vp[1], 1.0])
    if not p[2] > 1e-12:
        raise GeometryError(f"{what} ({vp[0]:g}, {vp[1]:g}) lies behind the simulated camera", file,
                            "check the VP (source pixels) and reduce --pan/--tilt")
    return float(p[0] / p[2]), float(p[1] / p[2])
