"""Designing a virtual camera from a set of physical cameras (paper §4.1.2).

Rule: height = mean of the cameras' heights; level (tilt = pan = 0); square pixels with
f = the largest focal length (px) of any camera (keeps resolution); central principal point;
size = the smallest centred rectangle that holds the lower half of every camera's image
(rows from the middle row down) under the expected pose variation. A camera with ``ego_rows``
counts as the image with those rows cropped off (they are never warped).

Two ways to account for the pose variation:

* ``shift`` (default): map the lower half at each camera's average pose exactly, then widen by
  the displacement a pan/tilt of the given range causes at the principal point,
  ``f * tan(range)``. This first-order rule reproduces the paper's 5500 x 2800 closely.
* ``exact``: the worst case over exact homographies on a grid of poses in the range (much
  larger: a wide camera panned by 20 degrees reaches far to the side).

Cropping to the road (``above``): the paper's rectangle is centred on the principal point, so its
upper half holds only what lies above the horizon — never road for a level virtual camera, whose
horizon is the row ``cy`` and onto which every road VP maps. With ``above`` set, the rectangle
keeps only ``f·tan(above)`` rows above the horizon (plus the tilt margin ``f·tan(tilt_range)``
of the shift rule) and everything below it: an exact crop, which changes only ``cy`` and the
height, so the warp, completion and back-projection stay exact (source pixels that map above
the crop are outside the virtual image: back-projection scores them "not road"). At a fixed pixel
budget this about doubles the resolution the network gets on the road.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .pinhole import Camera
from .files import camera_from_dict
from ..errors import InputError, one_of
from ..warp.homography import apply_homography, virt_H_src

__all__ = ["VirtualDesign", "design_virtual_camera", "same_camera_other_canvas", "extend_canvas", "EXTENTS",
           "DESIGN_PAN_RANGE", "DESIGN_TILT_RANGE", "DESIGN_ABOVE", "STORE_PIXELS", "scale_for_pixels"]

EXTENTS = ("max", "median")  # design_virtual_camera's rectangle: every camera's reach, or the median's
# The measured best design (issues 24-26; docs/studies.md), one source of truth for `vcprep warp`'s
# defaults and a crossval study's: the virtual camera designed to hold the pose variation
# +/-DESIGN_PAN_RANGE, +/-DESIGN_TILT_RANGE (degrees; also the range road VPs are accepted in),
# cropped to DESIGN_ABOVE degrees above the horizon, its stores STORE_PIXELS pixels (480x360's).
DESIGN_PAN_RANGE = 10.0
DESIGN_TILT_RANGE = 5.0
DESIGN_ABOVE = 8.0
STORE_PIXELS = 172800


def scale_for_pixels(virtual: Camera, pixels: int = STORE_PIXELS) -> float:
    """The store scale at which ``virtual``'s full rectangle has ``pixels`` pixels."""
    w, h = virtual.size
    return math.sqrt(pixels / (w * h))


@dataclass(frozen=True)
class VirtualDesign:
    camera: Camera
    half_extent: tuple[float, float]  # max |x - cx|, |y - cy| reached (px)
    rule: str
    pan_range: float
    tilt_range: float
    sources: tuple[str, ...]
    above: float | None = None  # degrees kept above the horizon (None: the paper's centred rectangle)
    extent: str = "max"         # the rectangle holds every camera ('max') or the median camera's reach

    def report(self) -> str:
        hf, vf = self.camera.fov_deg()
        crop = "" if self.above is None else f", cropped to {self.above:g} deg above the horizon"
        crop += ", sized by the median camera" if self.extent == "median" else ""
        return (f"# designed from {', '.join(self.sources)} by rule '{self.rule}' "
                f"(pan +/-{self.pan_range:g} deg, tilt +/-{self.tilt_range:g} deg{crop})\n"
                f"# size {self.camera.size[0]}x{self.camera.size[1]}, FOV {hf:.1f} x {vf:.1f} deg, "
                f"height {self.camera.height:.3f} m, f {self.camera.fx:g} px\n")


def _lower_half_corners(cam: Camera) -> np.ndarray:
    w, h = cam.size
    top = (h - 1) / 2.0
    return np.array([[-0.5, top], [w - 0.5, top], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])


def design_virtual_camera(cameras: list[Camera], pan_range: float = 20.0, tilt_range: float = 15.0,
                          rule: str = "shift", name: str = "virtual", multiple: int = 2,
                          above: float | None = None, f: float | None = None,
                          height: float | None = None, extent: str = "max") -> VirtualDesign:
    """The virtual camera holding ``cameras`` (module docstring). ``f`` and ``height`` fix the focal
    length and height instead of the rule's (a *canvas*: the same virtual camera, sized to hold
    only these cameras; its rectangle differs from another canvas of the same ``f``, ``height``,
    ranges and ``above`` only by ``cx``, ``cy`` and the size: an exact crop or extension).
    ``extent``: ``max`` holds every camera (the paper's rule); ``median`` holds, sideways and
    downward, the median camera's reach (plus the pose margins): the widest and the lowest cameras
    are cut (their outer parts never reach the store) so that the others get more pixels."""
    if not cameras:
        raise InputError("no cameras given", None, "name at least one camera")
    if rule not in ("shift", "exact"):
        raise InputError(f"unknown design rule '{rule}'", None, "use 'shift' or 'exact'")
    if not (0 <= pan_range < 60 and 0 <= tilt_range < 60):
        raise InputError("pose ranges must be in [0, 60) degrees", None, "e.g. --pan-range 20 --tilt-range 15")
    if extent not in EXTENTS:
        raise InputError(f"unknown extent '{extent}'", None, one_of(extent, EXTENTS))
    if above is not None and not 0 <= above < 60:
        raise InputError(f"'above' must be degrees in [0, 60), got {above}", None, "e.g. --above 8")
    height = float(np.mean([c.height for c in cameras])) if height is None else float(height)
    f = float(max(max(c.fx, c.fy) for c in cameras)) if f is None else float(f)
    # a virtual camera centred at the origin: extents are read off directly
    probe = Camera("probe", (1, 1), f, f, 0.0, 0.0, height)
    reach = []  # per camera: (max |x|, max |y|, max y) reached, pose variation included
    for cam in cameras:
        pts = _lower_half_corners(cam.without_ego())  # ego-vehicle rows: as if cropped off (never warped)
        if rule == "shift":
            p = apply_homography(virt_H_src(cam, probe), pts)
            dx, dy = f * math.tan(math.radians(pan_range)), f * math.tan(math.radians(tilt_range))
            reach.append((np.abs(p[:, 0]).max() + dx, np.abs(p[:, 1]).max() + dy, p[:, 1].max() + dy))
        else:
            r = (0.0, 0.0, 0.0)
            for dp in np.linspace(-pan_range, pan_range, 9):
                for dt in np.linspace(-tilt_range, tilt_range, 7):
                    p = apply_homography(virt_H_src(cam, probe, pan=cam.pan + dp, tilt=cam.tilt + dt), pts)
                    r = (max(r[0], np.abs(p[:, 0]).max()), max(r[1], np.abs(p[:, 1]).max()), max(r[2], p[:, 1].max()))
            reach.append(r)
    mx, my, bottom = (float(np.max(v) if extent == "max" else np.median(v)) for v in zip(*reach))
    W = int(math.ceil(2 * mx / multiple) * multiple)
    if above is None:
        H = int(math.ceil(2 * my / multiple) * multiple)
        cy = (H - 1) / 2.0
    else:  # rows [-top, bottom] about the horizon; pixel centres: the horizon row is cy
        top = f * (math.tan(math.radians(above)) + math.tan(math.radians(tilt_range)))
        H = int(math.ceil((top + bottom) / multiple) * multiple)
        cy = top - 0.5
    virt = camera_from_dict({"name": name, "image_size": [W, H], "fx": f, "fy": f, "cx": (W - 1) / 2.0,
                             "cy": cy, "height": height, "tilt": 0.0, "pan": 0.0})
    return VirtualDesign(virt, (mx, my), rule, pan_range, tilt_range, tuple(c.name for c in cameras), above, extent)


def same_camera_other_canvas(a: dict | None, b: dict | None) -> bool:
    """Whether two virtual cameras (``Camera.to_dict()``) are one camera with two rectangles: the
    same focal lengths, height and pose, only the principal point and size differ (canvases of
    :func:`design_virtual_camera` with one ``f`` and ``height``). Their images differ by a shift
    and a crop or extension, so a model trained in one runs unchanged in the other."""
    if not a or not b:
        return False
    keys = ("fx", "fy", "height", "tilt", "pan")
    return all(abs(float(a.get(k, 0.0)) - float(b.get(k, 0.0))) <= 1e-9 * max(1.0, abs(float(b.get(k, 0.0))))
               for k in keys) and not a.get("ego_rows") and not b.get("ego_rows")


def extend_canvas(virtual: Camera, views: list[tuple[Camera, float, float]], multiple: int = 2) -> Camera:
    """``virtual`` with its rectangle extended, left, right and down (never up: the rows above the
    horizon stay the training's), until it holds the lower half of every view's image (the own
    vehicle's rows cut off) -- ``views``: (camera, pan, tilt) of each frame at its own pose, mapped
    exactly. Focal lengths, height and pose are unchanged (:func:`same_camera_other_canvas`): a
    model trained in ``virtual`` runs on the result at the same pixels per degree, and a camera
    wider or steeper than the training cameras is no longer cut off. Unchanged when it holds them."""
    W, H = virtual.size
    left, right, bottom = -0.5, W - 0.5, H - 0.5
    for cam, pan, tilt in views:
        c = cam.without_ego()
        p = apply_homography(virt_H_src(c, virtual, pan, tilt), _lower_half_corners(c))
        if not np.all(np.isfinite(p)) or np.abs(p).max() > 8 * max(W, H):
            continue  # a view whose lower half reaches the horizon: the warp refuses it (folded), nothing to hold
        left, right, bottom = min(left, p[:, 0].min()), max(right, p[:, 0].max()), max(bottom, p[:, 1].max())
    grow_l = int(math.ceil((-0.5 - left) / multiple - 1e-9) * multiple)
    grow_r = int(math.ceil((right - (W - 0.5)) / multiple - 1e-9) * multiple)
    grow_b = int(math.ceil((bottom - (H - 0.5)) / multiple - 1e-9) * multiple)
    if not (grow_l or grow_r or grow_b):
        return virtual
    d = virtual.to_dict()
    d.update(image_size=[W + grow_l + grow_r, H + grow_b], cx=virtual.cx + grow_l)
    return camera_from_dict(d)
