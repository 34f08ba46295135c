"""A camera nobody calibrated, estimated from its own frames: what the frames fix, and what they do not.

Conventions are :mod:`vcprep.warp.homography`'s (tilt > 0 looks down; pixel centres at integers).

* **Horizon, tilt, pan** -- fixed by the frames. Each frame's road vanishing point is found with
  :func:`vcprep.vp.estimate_vp` through a provisional camera (principal point at the
  image centre, tilt and pan 0, the focal length below), its search window widened to the whole
  frame (at least +/-20 deg pan and +/-15 deg tilt). The camera's pose is the median of the accepted VPs' normalised
  rays (robust to the frames whose VP is off); how sure: the spread of the per-frame poses
  (1.4826 MAD) over sqrt(n). The horizon row is measured in pixels and does not depend on the
  focal length; the tilt angle does, weakly (tan tilt = (cy - v_horizon) / fy).
* **Roll** -- the slope of the line through the VPs of frames whose roads head different ways,
  reported only: curves and grade changes move the VP off the horizon as much (CamVid val, one
  curving clip: -6.8 +/- 0.8 deg for a level camera), and the camera model has no roll (method.md).
* **Focal length** -- *not* fixed by road frames. A flat road seen with a known horizon fixes only
  ratios along the rows (road width / camera height), whatever the focal length; a focal error
  ``s`` scales the virtual image about the road VP by ``1/s``. The classical orthogonal-VP
  self-calibration (road VP . vertical VP = -f^2) is ill-conditioned at road-camera tilts of a few
  degrees: the verticals converge by under a degree across the frame, not at all for a level
  camera, and it gives fy, not fx (the pixel aspect is a second unknown: CamVid's is 1.32).
  ``benchmarks/archive/camera_from_frames/focal_from_verticals.py`` pools every frame's near-vertical segments against the
  nadir each candidate fy implies: on 10 exact simulated cameras cut from CamVid val (tilt -8..+8
  deg) and on CamVid val and Cityscapes, |fy error| has a median of 41 % with detected road VPs
  (32 % with the horizon given), 0 of 12 within 10 %; a level camera gives a flat cost (no
  information) or, with detected VPs, a confident wrong minimum. So the focal length
  is taken, in this order, from ``--fx``/``--hfov``, from the JPEG's EXIF
  (``FocalLengthIn35mmFilm``: fx = f35 * image diagonal / 43.27 mm), or ASSUMED from a field of
  view of :data:`ASSUMED_HFOV` degrees -- said as such, with what to give instead.
* **Pixel aspect** -- frames resized from another aspect (the Cityscapes pix2pix set: 2048x1024 ->
  256x256) have fy != fx; nothing in the pixels says so: ``--source-size WxH`` (the size the
  frames were resized from) or ``--pixel-aspect`` gives it, else square pixels are ASSUMED.
* **Height** -- sets only the scale of the ground plane (the virtual image stretches vertically
  about the horizon by h / h_estimated): ``--height``; else, with labels, ESTIMATED from the road
  footprint (:func:`road_widths`): the camera height at which the frames' median visible road
  width is :data:`ROAD_WIDTH` m, CamVid's (the training data's) under its calibration. The
  measured width is ``fy/fx * du / (v - v_horizon)`` in camera heights -- the focal length cancels,
  the pixel aspect does not -- so this height also absorbs a pixel aspect nothing else tells
  (Cityscapes pix2pix, squashed 2:1, gets 2.9 m for a true 1.22 m at fy/fx 2: the same road in
  the virtual image); roads narrower or wider than CamVid's are scaled to CamVid's (Cityscapes'
  measures 6.1 m under its calibration). Without labels ASSUMED :data:`ASSUMED_HEIGHT` m.
* **Own vehicle** -- from labels (:mod:`vcprep.camera.ego`) when they are given.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from .pinhole import Camera
from .files import yaml_name
from ..errors import InputError
from ..warp.homography import pose_from_vp

__all__ = ["ASSUMED_HFOV", "ASSUMED_HEIGHT", "MIN_FRAMES", "ROAD_WIDTH", "Value", "CameraEstimate",
           "estimate_camera", "exif_focal_35mm", "estimate_to_yaml", "road_widths", "estimated_line"]

ASSUMED_HFOV = 60.0     # degrees: a typical dashcam / phone main camera in landscape (CamVid 58, BDD ~65)
ASSUMED_HEIGHT = 1.4    # metres: a car-mounted camera (CamVid 1.21, Cityscapes 1.22, KITTI 1.65)
MIN_FRAMES = 5          # fewer frames: one odd road decides the pose
MIN_ACCEPTED = 3        # fewer accepted road VPs: the pose is not estimated
ROLL_MIN_SPREAD = 0.1   # VPs must spread over this share of the width to fix the horizon's slope
DIAG_35MM = math.hypot(36.0, 24.0)  # mm: the 35 mm film frame's diagonal (EXIF FocalLengthIn35mmFilm)
# metres: the median visible road width of CamVid train's labels under its calibration, 7.19 m over 306 of
# its 367 frames (Cityscapes pix2pix under its own: 6.10 m); benchmarks/camera_from_frames/camera_estimate.py measures both
ROAD_WIDTH = 7.2
HORIZON_SKIP = 0.15  # road_widths: the rows nearest the horizon (this share of those below it) are left out


@dataclass(frozen=True)
class Value:
    """One estimated quantity: ``value``, ``how`` it was found, ``sure`` (an uncertainty in the
    value's unit, or None when it was given or assumed) and ``source``: 'estimated', 'given',
    'exif' or 'assumed'."""

    value: float | int
    how: str
    source: str
    sure: float | None = None

    def note(self) -> str:
        s = f" (+/- {self.sure:.3g})" if self.sure is not None else ""
        return f"{self.source.upper()}: {self.how}{s}"

    def to_dict(self) -> dict:
        return {"value": self.value, "how": self.how, "source": self.source, "sure": self.sure}


@dataclass(frozen=True)
class CameraEstimate:
    camera: Camera
    values: dict[str, Value]            # fx fy cx cy height tilt pan ego_rows, and roll / horizon_row (reported)
    frames: int
    accepted: int
    ids: list[str] = field(default_factory=list)
    vps: list = field(default_factory=list)     # VPResult per frame, after the reliability rule
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"camera": self.camera.to_dict(), "values": {k: v.to_dict() for k, v in self.values.items()},
                "frames": self.frames, "accepted_vps": self.accepted, "warnings": list(self.warnings)}


def exif_focal_35mm(path: str | Path) -> float | None:
    """EXIF ``FocalLengthIn35mmFilm`` (tag 0xA405, mm) of a JPEG, or None (no EXIF, no tag, not a
    JPEG). Reads the APP1 segment's TIFF structure: IFD0 -> Exif IFD."""
    try:
        data = Path(path).read_bytes()[:262144]
    except OSError:
        return None
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    while i + 4 <= len(data) and data[i] == 0xFF:
        marker, size = data[i + 1], struct.unpack(">H", data[i + 2:i + 4])[0]
        if marker == 0xE1 and data[i + 4:i + 10] == b"Exif\0\0":
            return _tiff_focal35(data[i + 10:i + 2 + size])
        if marker in (0xDA, 0xD9):
            break
        i += 2 + size
    return None


def _tiff_focal35(t: bytes) -> float | None:
    try:
        end = {b"II": "<", b"MM": ">"}[t[:2]]

        def entries(off):
            n = struct.unpack(end + "H", t[off:off + 2])[0]
            for k in range(n):
                e = off + 2 + 12 * k
                tag, typ, cnt = struct.unpack(end + "HHI", t[e:e + 8])
                yield tag, typ, t[e + 8:e + 12]

        ifd0 = struct.unpack(end + "I", t[4:8])[0]
        for tag, _, raw in entries(ifd0):
            if tag == 0x8769:  # Exif IFD pointer
                for tag2, typ2, raw2 in entries(struct.unpack(end + "I", raw)[0]):
                    if tag2 == 0xA405:
                        v = struct.unpack(end + ("H" if typ2 == 3 else "I"), raw2[:2] if typ2 == 3 else raw2)[0]
                        return float(v) if v > 0 else None
    except (KeyError, struct.error, IndexError):
        return None
    return None


def _focal(images: Sequence[Path], size: tuple[int, int], fx: float | None, hfov: float | None) -> Value:
    w, h = size
    if fx is not None:
        return Value(float(fx), "given (--fx)", "given")
    if hfov is not None:
        return Value(round((w / 2) / math.tan(math.radians(hfov) / 2), 3), f"given horizontal FOV {hfov:g} deg",
                     "given")
    f35 = [f for f in (exif_focal_35mm(p) for p in images[:20]) if f]
    if f35:
        f = float(np.median(f35))
        return Value(round(f * math.hypot(w, h) / DIAG_35MM, 3), f"EXIF FocalLengthIn35mmFilm {f:g} mm "
                     f"({len(f35)} of {min(len(images), 20)} files)", "exif")
    return Value(round((w / 2) / math.tan(math.radians(ASSUMED_HFOV) / 2), 3),
                 f"not observable from road frames (no EXIF focal length): a {ASSUMED_HFOV:g} deg horizontal FOV; "
                 "give --fx PIXELS or --hfov DEGREES", "assumed")


def _aspect(size: tuple[int, int], pixel_aspect: float | None, source_size: tuple[int, int] | None) -> Value:
    """fy / fx."""
    if source_size is not None:
        a = (size[1] / source_size[1]) / (size[0] / source_size[0])
        return Value(a, f"frames resized from {source_size[0]}x{source_size[1]} (--source-size)", "given")
    if pixel_aspect is not None:
        return Value(float(pixel_aspect), "given (--pixel-aspect)", "given")
    return Value(1.0, "square pixels (nothing in the pixels tells a resize from another aspect; give "
                 "--source-size WxH if the frames were resized)", "assumed")


def road_widths(labels: Sequence[str | Path], label_format, cam: Camera, ego_rows: int = 0) -> np.ndarray:
    """Per labelled frame of ``cam``'s size, the median lateral width of its road in units of the
    camera height: in each row below the horizon (leaving out the :data:`HORIZON_SKIP` share
    nearest it, and the own vehicle's ``ego_rows``), the leftmost and rightmost road pixels
    back-projected onto the road plane of ``cam`` at height 1; rows whose road reaches a side edge
    of the frame (its width is cut) are left out, frames with fewer than 5 rows too. The focal
    length cancels (width = fy/fx * du / (v - v_horizon) for a level camera)."""
    from ..warp.homography import ground_to_image
    from ..io.images import read_image
    from ..labels import decode_label

    G = ground_to_image(replace(cam, height=1.0))
    Gi = np.linalg.inv(G)
    far = G @ np.array([0.0, 1e9, 1.0])
    v_h = far[1] / far[2]
    out = []
    for f in labels:
        lab = decode_label(read_image(f, label=True).array, label_format, f)
        h, w = lab.shape
        if (w, h) != tuple(cam.size):
            continue
        rows, lo, hi = [], [], []
        for v in range(max(0, int(math.ceil(v_h + HORIZON_SKIP * (h - v_h)))), h - ego_rows):
            r = np.flatnonzero(lab[v] == 1)
            if len(r) >= 3 and r[0] > 0 and r[-1] < w - 1:
                rows.append(v), lo.append(r[0]), hi.append(r[-1])
        if len(rows) < 5:
            continue
        p = Gi @ np.array([lo + hi, rows + rows, [1.0] * (2 * len(rows))], float)
        x = p[0] / p[2]
        out.append(float(np.median(np.abs(x[len(rows):] - x[:len(rows)]))))
    return np.array(out)


def _height_from_road(labels, label_format, cam: Camera) -> Value | None:
    """The camera height that makes the frames' median road width :data:`ROAD_WIDTH` m, or None
    (fewer than :data:`MIN_FRAMES` frames with a measurable road)."""
    widths = road_widths(labels, label_format, cam, cam.ego_rows)
    if len(widths) < MIN_FRAMES:
        return None
    med, se = _robust(widths)
    height = ROAD_WIDTH / med
    return Value(round(height, 3), f"road footprint: the median road width of {len(widths)} labelled frames, "
                 f"{med:.2f} camera heights, made {ROAD_WIDTH:g} m (CamVid's); it absorbs a pixel aspect the frames "
                 "do not tell, and scales a road narrower or wider than CamVid's to CamVid's (give --height "
                 "METRES if you know it)", "estimated", round(height * se / med, 3))


def _robust(x: np.ndarray) -> tuple[float, float]:
    """Median and its uncertainty 1.4826 MAD / sqrt(n)."""
    med = float(np.median(x))
    return med, float(1.4826 * np.median(np.abs(x - med)) / math.sqrt(len(x)))


def whole_frame_vp_config(cam: Camera):
    """The VP search settings with the window widened to ``cam``'s whole frame (at least the usual
    +/-20 deg pan and +/-15 deg tilt): with the pose unknown the road VP may be anywhere, and the usual
    window around a known pose would cut off a steep tilt seen through an assumed focal length."""
    from ..vp.estimate import VPConfig

    w, h = cam.size
    half_w, half_h = math.degrees(math.atan(w / 2 / cam.fx)), math.degrees(math.atan(h / 2 / cam.fy))
    return replace(VPConfig(), pan_range=max(VPConfig.pan_range, half_w), tilt_range=max(VPConfig.tilt_range, half_h))


def estimate_camera(images: Sequence[str | Path], *, name: str = "estimated", fx: float | None = None,
                    hfov: float | None = None, height: float | None = None, pixel_aspect: float | None = None,
                    source_size: tuple[int, int] | None = None, ids: Sequence[str] | None = None,
                    labels: Sequence[str | Path] | None = None, label_format=None, find_ego: bool = True,
                    on_image: Callable[[int], None] | None = None) -> CameraEstimate:
    """Estimate one camera from its frames (all of one size; see the module docstring). With
    ``labels``, the own vehicle is searched for (unless ``find_ego`` is False) and the height
    comes from the road footprint (unless ``height`` is given).

    Raises :class:`InputError` with what is missing: too few frames, frames of several sizes,
    too few road VPs (say the tilt and pan instead, or give frames where the road runs ahead)."""
    from ..io.images import read_image
    from ..vp.reliability import apply_reliability
    from ..vp.estimate import estimate_vp

    images = [Path(p) for p in images]
    values, cam = _intrinsics(images, name, fx, hfov, height, pixel_aspect, source_size, labels, label_format,
                              find_ego)
    cfg = whole_frame_vp_config(cam)
    results = []
    for i, p in enumerate(images):
        results.append(estimate_vp(read_image(p).array, cam, cfg))
        if on_image is not None:
            on_image(i)
    ok = [r for r in results if r.status == "accepted"]
    if len(ok) < MIN_ACCEPTED:
        raise InputError(f"a road vanishing point was found in {len(ok)} of {len(images)} frames (need "
                         f">= {MIN_ACCEPTED}): the tilt and pan cannot be estimated", images[0],
                         "give frames where the road runs ahead with visible edges or markings, or write tilt and "
                         "pan by hand")
    values.update(_pose_values(ok, cam, len(images)))
    cam = replace(cam, tilt=float(values["tilt"].value), pan=float(values["pan"].value))
    if height is None and labels:
        road = _height_from_road(labels, label_format, cam)
        if road is not None:
            values["height"] = road
            cam = replace(cam, height=float(road.value))
    warnings = [f"{k}: {v.how}" for k, v in values.items() if v.source == "assumed" and k in ("fx", "height")]
    ids = list(ids) if ids is not None else [p.stem for p in images]
    final = apply_reliability([replace(r, pan_deg=pose_from_vp(cam, r.vp)[0], tilt_deg=pose_from_vp(cam, r.vp)[1])
                               for r in results], [cam] * len(results), ids)
    return CameraEstimate(cam, values, len(images), len(ok), ids, final, warnings)


def _frames_size(images: list[Path]) -> tuple[int, int]:
    """The one size of the frames; too few frames, or frames of several sizes, are an error."""
    from ..io.images import image_size

    if len(images) < MIN_FRAMES:
        raise InputError(f"{len(images)} frame(s) are too few to estimate a camera (need >= {MIN_FRAMES})",
                         images[0] if images else None, "give more frames of the same camera")
    sizes = [image_size(p) for p in images]
    size = max(set(sizes), key=sizes.count)
    if sizes.count(size) != len(sizes):
        other = next(p for p, s in zip(images, sizes) if s != size)
        raise InputError(f"frames of more than one size ({size[0]}x{size[1]} and "
                         f"{image_size(other)[0]}x{image_size(other)[1]}): one camera, one size", other,
                         "estimate each camera from its own frames")
    return size


def _intrinsics(images: list[Path], name: str, fx, hfov, height, pixel_aspect, source_size, labels, label_format,
                find_ego: bool) -> tuple[dict[str, Value], Camera]:
    """Everything but the pose: the focal lengths, the principal point (the image centre), the
    height (given or assumed) and the own vehicle's rows (from the labels); and the camera of them."""
    size = _frames_size(images)
    w, h = size
    values: dict[str, Value] = {}
    values["fx"] = f = _focal(images, size, fx, hfov)
    a = _aspect(size, pixel_aspect, source_size)
    values["fy"] = Value(round(f.value * a.value, 3), f"fx x pixel aspect {a.value:.4g}: {a.how}", a.source
                         if a.source == "assumed" else f.source)
    values["cx"] = Value((w - 1) / 2, "the image centre (a principal point cannot be told from road frames)",
                         "assumed")
    values["cy"] = Value((h - 1) / 2, "the image centre", "assumed")
    values["height"] = (Value(float(height), "given (--height)", "given") if height is not None else
                        Value(ASSUMED_HEIGHT, "sets only the ground plane's scale, not observable from the frames "
                              "without labels (give --labels to measure the road footprint), or give --height "
                              "METRES", "assumed"))
    ego = 0
    if labels and find_ego:
        from .ego import ego_rows_from_label_files, rows_at_height

        est = ego_rows_from_label_files(labels, label_format)
        ego = rows_at_height(est, h)
        values["ego_rows"] = Value(ego, est.describe(), "estimated")
    else:
        values["ego_rows"] = Value(0, "not searched (no labels): give --labels to find the own vehicle, or write "
                                   "ego_rows by hand" if not labels else "not searched", "assumed")
    cam = Camera(name, size, float(f.value), float(values["fy"].value), float(values["cx"].value),
                 float(values["cy"].value), float(values["height"].value), ego_rows=int(ego))
    return values, cam


def _pose_values(ok: list, cam: Camera, n_frames: int) -> dict[str, Value]:
    """tilt, pan, horizon_row and roll from the accepted road VPs ``ok`` of ``n_frames`` frames."""
    rays = np.array([[(r.vp[0] - cam.cx) / cam.fx, (r.vp[1] - cam.cy) / cam.fy] for r in ok])
    mu, mu_se = _robust(rays[:, 0])
    mv, mv_se = _robust(rays[:, 1])
    pan, tilt = pose_from_vp(cam, (cam.cx + cam.fx * mu, cam.cy + cam.fy * mv))
    tilts = np.array([r.tilt_deg for r in ok])
    pans = np.array([r.pan_deg for r in ok])
    n = len(ok)
    how = f"median road VP of {n} of {n_frames} frames"
    values: dict[str, Value] = {}
    values["tilt"] = Value(round(tilt, 3), how, "estimated", round(_robust(tilts)[1], 3))
    values["pan"] = Value(round(pan, 3), how, "estimated", round(_robust(pans)[1], 3))
    vrows = np.array([r.vp[1] for r in ok])
    values["horizon_row"] = Value(round(float(np.median(vrows)), 2), f"{how} (pixels; independent of the focal "
                                  "length)", "estimated", round(_robust(vrows)[1], 2))
    us = np.array([r.vp[0] for r in ok])
    q25, q75 = np.percentile(us, [25, 75])
    if n >= 10 and q75 - q25 >= ROLL_MIN_SPREAD * cam.size[0]:
        A = np.column_stack([us - us.mean(), np.ones(n)])
        coef, res, *_ = np.linalg.lstsq(A, vrows, rcond=None)
        sigma = math.sqrt(float(res[0]) / (n - 2)) if len(res) and n > 2 else 0.0
        slope_se = sigma / math.sqrt(float(((us - us.mean()) ** 2).sum()))
        roll = math.degrees(math.atan(coef[0]))
        values["roll"] = Value(round(roll, 3), f"slope of the line through {n} road VPs (curves and slopes bias "
                               "it; not in the camera model: 0 is used)", "estimated", round(math.degrees(slope_se), 3))
    else:
        values["roll"] = Value(0.0, "not estimated: the road VPs do not spread along the horizon (straight roads); "
                               "0 is used", "assumed")
    return values


_KEYS = ("fx", "fy", "cx", "cy", "height", "tilt", "pan", "ego_rows")


def estimate_to_yaml(est: CameraEstimate) -> str:
    """The camera YAML (read back by :func:`vcprep.camera.read_camera_yaml`), each value with how it
    was found and how sure it is as a comment."""
    c, v = est.camera, est.values
    num = {"fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy, "height": c.height, "tilt": c.tilt, "pan": c.pan,
           "ego_rows": c.ego_rows}
    lines = [f"# vcprep camera estimate: {est.frames} frames, {est.accepted} road VPs accepted. ESTIMATED values "
             "come from the frames, GIVEN from you, ASSUMED ones are guesses: replace them when you know better.",
             f"name: {yaml_name(c.name)}", f"image_size: [{c.size[0]}, {c.size[1]}]"]
    for k in _KEYS:
        if k == "ego_rows" and not c.ego_rows:
            lines.append(f"# ego_rows: 0   # {v[k].note()}")
            continue
        lines.append(f"{k}: {num[k]:.6g}   # {v[k].note()}")
    for k in ("horizon_row", "roll"):
        lines.append(f"# {k}: {v[k].value:g}   # {v[k].note()}")
    return "\n".join(lines) + "\n"


def estimated_line(est: CameraEstimate, source: str) -> str:
    """The one line that says a camera was ESTIMATED (from ``source``) and what was assumed."""
    v = est.values
    return (f"camera ESTIMATED from {source}: tilt {v['tilt'].value:g} deg, pan {v['pan'].value:g} deg; "
            + "; ".join(f"assumed {w}" for w in est.warnings))
