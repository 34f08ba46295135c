"""Road vanishing points (VPs) and the reliability rule for within-camera correction (paper §4.2).

Three layers (style.md):

* :func:`detect_segments` (:mod:`vcprep.vp.segments`) / :func:`estimate_vp`
  (:mod:`vcprep.vp.estimate`) — pure, in memory: one image -> :class:`VPResult`;
* :func:`apply_reliability`, :func:`smooth_sequences` — the dataset rules over many results (here);
* :func:`estimate_files`, :func:`read_vp_csv`, :func:`write_vp_csv` — file I/O wrappers (here).

Every name of the two modules is importable from here.

Conventions: a VP is (u, v) in pixels of the image as stored on disk, origin at the CENTRE of
the top-left pixel (method.md). Pan/tilt in degrees from :func:`vcprep.warp.homography.pose_from_vp`.

The detector (measured in ``benchmarks/camera_from_frames/vp.py``):

1. grey image, downscaled (INTER_AREA) to at most ``work_width`` px wide; OpenCV LSD segments
   (internal scale ``lsd_scale``, standard refinement), mapped back to source pixels with the
   pixel-centre rule (LSD's own subsampling offset of 0.5 / scale - 0.5 px is corrected);
2. keep segments longer than ``min_length`` (fraction of the width) whose angle to the horizontal
   lies in [``min_angle_deg``, ``max_angle_deg``] and whose supporting line crosses the *prior
   window* — the VPs the camera can have under its average pose ± ``pan_range`` / ``tilt_range``;
3. sub-pixel re-fit (``subpixel``, :func:`refine_segments`): each kept segment's line is re-fitted
   to the gradient peaks of the FULL-resolution grey image across it, which removes the
   blur/quantisation error of a coarse LSD scale (synthetic median error 0.23 -> 0.11 % width);
4. weight = length ** ``length_power``, x ``above_weight`` for a segment lying above the candidate
   VP (the road is below its VP): lane markings, kerbs and road edges dominate, facades and wires
   count less; the square root of the length lets many agreeing segments outvote one long line
   crossing one clutter line;
5. candidates = intersections of the strongest segments plus a regular grid over the prior
   window; each is scored by a robust (Tukey) vote of every segment on the angle between the
   segment and the ray from its midpoint to the candidate (coarse-to-fine: all candidates
   against the ``n_coarse`` strongest segments, the best ``n_finalists`` against all), times a
   two-sided factor (``one_sided``: a mode whose support below it comes from one side of its
   vertical only - a kerb, a row of parked cars - loses up to 20 %) and a wide pose prior
   (``pose_sigma``: Gaussian in pan / tilt around the camera's average pose, sigma 1.25 x the
   reliability window, so an edge-of-window mode loses a near-tie); both in angles or ratios,
   never pixels (:func:`_scores`); the best is refined by iteratively reweighted least squares
   on its supporting segments, weighted by length ** ``refine_power`` (the direction of a
   longer segment is more precise: its angular error falls faster than 1 / sqrt(length), so the
   refinement trusts long lines more than the vote that picks the mode does). No randomness:
   deterministic.

Per image the result says how much it trusts the VP (``confidence`` = share of the line weight
that supports it, ``n_support`` = number of supporting segments). :func:`apply_reliability` then
applies method.md's rule: implied pan more than 20° or tilt more than 15° from the camera's
average pose, or fewer than ``min_support`` (7) supporting segments -> rejected and replaced by the
mean of the accepted VPs of its sequence (:func:`sequence_key`: one drive, one mount; when the
sequence has at least 3), else of the dataset (status ``fallback``). Means are taken over
normalised rays ((u - cx)/fx, (v - cy)/fy), so images of different (uniformly rescaled) sizes
average correctly. When no VP of the dataset is accepted, the camera's average-pose VP is the
fallback.
"""
from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from ..camera.pinhole import Camera
from ..errors import InputError, VCError, one_of
from ..warp.homography import pose_from_vp, vp_from_pose
from ..io.images import read_text
from .estimate import (VPConfig, VPResult, _result, estimate_vp)



# --------------------------------------------------------------------------------------------
# dataset rules


def _ray(cam: Camera, vp) -> np.ndarray:
    return np.array([(vp[0] - cam.cx) / cam.fx, (vp[1] - cam.cy) / cam.fy])


def _from_ray(cam: Camera, r) -> tuple[float, float]:
    return float(cam.cx + cam.fx * r[0]), float(cam.cy + cam.fy * r[1])


#: a rejected VP falls back to its sequence's mean when the sequence has at least this many accepted VPs
MIN_SEQUENCE_ACCEPTED = 3
#: how frames are grouped into sequences (:attr:`VPRule.sequences`)
SEQUENCES = ("name", "folder")


@dataclass(frozen=True)
class VPRule:
    """How the VPs of a set of frames are estimated together: the pose ranges the detector searches
    and :func:`apply_reliability` accepts (degrees from the camera's average pose; the rest of
    :class:`VPConfig` is the detector's own), and the temporal smoothing window
    (:func:`smooth_sequences`; 0: none). A store records the rule of its estimated VPs
    (``vp_rule``), so a model's frames are predicted with the rule it was trained with."""

    pan_range: float = VPConfig.pan_range
    tilt_range: float = VPConfig.tilt_range
    smooth: int = 0
    sequences: str = "name"  # a frame's sequence (:func:`sequence_key`): 'name', its file name up to the first '_'
    #                          (CamVid 0016E5_07959); 'folder', its folder (a drive: IDD's tree, whose names repeat)

    def __post_init__(self):
        if self.sequences not in SEQUENCES:
            raise InputError(f"unknown VP sequence rule '{self.sequences}'", None, one_of(self.sequences, SEQUENCES))

    def config(self, base: VPConfig = VPConfig()) -> VPConfig:
        """``base`` with this rule's pose ranges."""
        return replace(base, pan_range=float(self.pan_range), tilt_range=float(self.tilt_range))

    def frame_ids(self, images: Sequence[str | Path]) -> list[str]:
        """The ids that :func:`apply_reliability` and :func:`smooth_sequences` group (:func:`sequence_key`)
        and order ``images`` by: file stems, or ``<folder>_<stem>`` by ``sequences``."""
        if self.sequences == "folder":
            return [f"{Path(p).parent.name.replace('_', '-')}_{Path(p).stem}" for p in images]
        return [Path(p).stem for p in images]

    def to_dict(self) -> dict:
        return {"pan_range": float(self.pan_range), "tilt_range": float(self.tilt_range), "smooth": int(self.smooth),
                "sequences": self.sequences}

    @classmethod
    def from_dict(cls, d: Mapping | None) -> "VPRule | None":
        """The rule a record or checkpoint holds (None: none recorded)."""
        if not d:
            return None
        return cls(float(d["pan_range"]), float(d["tilt_range"]), int(d.get("smooth", 0)), d.get("sequences", "name"))

    def describe(self) -> str:
        """'pan within 10 deg and tilt within 5 deg of the camera's pose, a rejected VP replaced by the
        mean accepted one of its sequence (by file name) or of all frames, no smoothing'."""
        smooth = f"smoothed over {self.smooth} frames either side" if self.smooth else "no smoothing"
        by = "file name" if self.sequences == "name" else "folder"
        return (f"pan within {self.pan_range:g} deg and tilt within {self.tilt_range:g} deg of the camera's pose, "
                f"a rejected VP replaced by the mean accepted one of its sequence (by {by}) or of all frames, {smooth}")


def apply_reliability(results: Sequence[VPResult], cams: Sequence[Camera],
                      ids: Sequence[str] | None = None) -> list[VPResult]:
    """Replace every non-accepted result by a mean of accepted VPs (status 'fallback').

    ``cams[i]`` is the camera of image i at its own size. Means are over normalised rays, so
    they are the same direction for every image size. With ``ids``, the images are grouped into
    sequences (:func:`sequence_key`: one drive, one mount) and a rejected VP takes the mean of
    its own sequence's accepted VPs when there are at least :data:`MIN_SEQUENCE_ACCEPTED`
    (CamVid's 0001TP rig looks 4.3 deg further down than the other two: the dataset mean would
    tilt its rejected frames by that much); otherwise, and without ``ids``, the mean of all
    accepted VPs. With no accepted VP at all, each image falls back to its camera's
    average-pose VP. The reason says which. 'given' results pass through and count as accepted.
    """
    ok = [r.status in ("accepted", "given") for r in results]
    rays = [_ray(c, r.vp) if k else None for r, c, k in zip(results, cams, ok)]
    acc = [x for x in rays if x is not None]
    mean = np.mean(acc, axis=0) if acc else None
    seq_mean: dict[str, tuple[np.ndarray, int]] = {}
    if ids is not None:
        if len(ids) != len(results):
            raise ValueError(f"{len(ids)} ids for {len(results)} results")
        groups: dict[str, list[np.ndarray]] = {}
        for iid, x in zip(ids, rays):
            if x is not None:
                groups.setdefault(sequence_key(iid), []).append(x)
        seq_mean = {k: (np.mean(v, axis=0), len(v)) for k, v in groups.items() if len(v) >= MIN_SEQUENCE_ACCEPTED}
    out = []
    for i, (r, c) in enumerate(zip(results, cams)):
        if ok[i]:
            out.append(r)
            continue
        key = sequence_key(ids[i]) if ids is not None else None
        if key in seq_mean:
            m, n = seq_mean[key]
            vp, why = _from_ray(c, m), f"mean of the {n} accepted VPs of sequence {key}"
        elif mean is not None:
            vp, why = _from_ray(c, mean), f"mean of {len(acc)} accepted VPs"
        else:
            vp, why = vp_from_pose(c), "camera average pose (no accepted VP in the dataset)"
        reason = f"{r.reason or 'rejected'}; replaced by the {why}"
        pan, tilt = pose_from_vp(c, vp)
        out.append(replace(r, vp=(float(vp[0]), float(vp[1])), pan_deg=float(pan), tilt_deg=float(tilt),
                           status="fallback", reason=reason))
    return out


_SEQ_RE = re.compile(r"^(.+?)_")


def sequence_key(image_id: str) -> str:
    """The sequence an image belongs to: its id up to the first '_' (CamVid ``0016E5_07959`` ->
    ``0016E5``); an id without '_' is a sequence of its own."""
    m = _SEQ_RE.match(image_id)
    return m.group(1) if m else image_id


def smooth_sequences(ids: Sequence[str], results: Sequence[VPResult], cams: Sequence[Camera],
                     window: int = 2) -> list[VPResult]:
    """Temporal smoothing of VPs over consecutive frames (VPSeg: VPs of a video are coherent).

    Frames are grouped by :func:`sequence_key` and ordered by id (zero-padded frame numbers sort
    in time order). Each accepted or fallback VP becomes the median (per normalised-ray
    coordinate) of the accepted VPs among the ``window`` frames either side and itself; a frame
    with no accepted neighbour keeps its VP. 'given' VPs are never changed. Apply after
    :func:`apply_reliability`.
    """
    if window <= 0:
        return list(results)
    groups: dict[str, list[int]] = {}
    for i, iid in enumerate(ids):
        groups.setdefault(sequence_key(iid), []).append(i)
    out = list(results)
    for members in groups.values():
        members.sort(key=lambda i: ids[i])
        for k, i in enumerate(members):
            r = results[i]
            if r.status == "given":
                continue
            near = [members[j] for j in range(max(0, k - window), min(len(members), k + window + 1))]
            rays = [_ray(cams[j], results[j].vp) for j in near if results[j].status == "accepted"]
            if not rays:
                continue
            vp = _from_ray(cams[i], np.median(np.array(rays), axis=0))
            pan, tilt = pose_from_vp(cams[i], vp)
            out[i] = replace(r, vp=vp, pan_deg=float(pan), tilt_deg=float(tilt),
                             status="accepted" if r.status == "accepted" else "fallback",
                             reason=(r.reason + "; " if r.reason else "") + f"smoothed over {len(rays)} frames")
    return out


# --------------------------------------------------------------------------------------------
# files


def estimate_files(images: Sequence[str | Path], camera: Camera, cfg: VPConfig = VPConfig(), smooth: int = 0,
                   ids: Sequence[str] | None = None,
                   on_image: Callable[[int], None] | None = None,
                   on_error: Callable[[int, VCError], None] | None = None, cache=None) -> list[VPResult | None]:
    """Detect the VP of every image file, then apply the reliability rule (and ``smooth``).

    ``camera`` is rescaled to each image's size (uniform rescales only, else InputError).
    ``ids`` (default: file stems) define sequences for smoothing. ``on_image(i)`` is called after
    each image (progress). ``on_error(i, error)`` (given): an image that cannot be read is told to
    it and left out of the rules (its result is None) instead of raising. ``cache`` (a
    :class:`vcprep.vp.cache.VPCache`, given): the detector's results are taken from it where it has
    them and kept in it where it has not (the rules run over all the frames either way).
    """
    ids = list(ids) if ids is not None else [Path(p).stem for p in images]
    results, cams, kept = [], [], []
    for i, p in enumerate(images):
        try:
            result, cam = _detect(p, camera, cfg, cache)
        except VCError as e:
            if on_error is None:
                raise
            on_error(i, e)
            continue
        results.append(result)
        cams.append(cam)
        kept.append(i)
        if on_image is not None:
            on_image(i)
    return _sequence_rules(results, cams, ids, kept, smooth)


def estimate_arrays(frames: Sequence[np.ndarray], camera: Camera, cfg: VPConfig = VPConfig(), smooth: int = 0,
                    ids: Sequence[str] | None = None) -> list[VPResult]:
    """:func:`estimate_files` on decoded frames (BGR or grey, any size the camera rescales to):
    the detector on each, then the reliability rule and ``smooth`` over ``ids`` (default
    ``frame_000000``, ... : one sequence, in order). The same numbers as on the frames' files."""
    ids = list(ids) if ids is not None else [f"frame_{i:06d}" for i in range(len(frames))]
    cams = [camera.for_image_size((f.shape[1], f.shape[0])) for f in frames]
    results = [estimate_vp(f, c, cfg) for f, c in zip(frames, cams)]
    return _sequence_rules(results, cams, ids, list(range(len(frames))), smooth)


def _sequence_rules(results: list[VPResult], cams: list[Camera], ids: Sequence[str], kept: list[int],
                    smooth: int) -> list[VPResult | None]:
    """The detector's ``results`` of the frames ``kept`` (indices into ``ids``) after the reliability
    rule and ``smooth``; None for a frame not kept."""
    kept_ids = [ids[i] for i in kept]
    results = apply_reliability(results, cams, kept_ids)
    if smooth > 0:
        results = smooth_sequences(kept_ids, results, cams, smooth)
    out: list[VPResult | None] = [None] * len(ids)
    for i, r in zip(kept, results):
        out[i] = r
    return out


def _detect(path: str | Path, camera: Camera, cfg: VPConfig, cache=None) -> tuple[VPResult, Camera]:
    """(the detector's VP of one image file, the camera at its size), through ``cache`` when given
    (a frame found there is not decoded)."""
    from ..io.images import image_size_from_header, read_image

    if cache is None:
        img = read_image(path).array
        cam = camera.for_image_size((img.shape[1], img.shape[0]), path)
        return estimate_vp(img, cam, cfg), cam
    try:
        data = Path(path).read_bytes()
    except OSError:
        data = b""
    img = None if data else read_image(path).array  # (raises the reader's own error)
    size = image_size_from_header(data)
    if size is None:
        img = read_image(path, data=data).array
        size = (img.shape[1], img.shape[0])
    cam = camera.for_image_size(size, path)
    key = cache.key(data, cam, cfg)
    found = cache.get(key)
    if found is None:
        found = estimate_vp(read_image(path, data=data).array if img is None else img, cam, cfg)
        cache.put(key, found)
    return found, cam


def read_vp_csv(path: str | Path) -> dict[str, tuple[float, float]]:
    """Read known VPs from a CSV ``id,u,v`` (u, v in source pixels of the image as stored).

    A first row ``id,u,v`` is a header; further columns are ignored; blank lines and lines
    starting with '#' are skipped. A row with a missing field, a number that does not parse or
    is not finite, or an id seen before raises :class:`InputError` naming the line.
    """
    path = Path(path)
    text = read_text(path, "VP file", "give a CSV with columns id,u,v")
    vps: dict[str, tuple[float, float]] = {}
    lines: dict[str, int] = {}
    first = True
    for n, row in enumerate(csv.reader(io.StringIO(text)), 1):
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in row]
        if first and [c.lower() for c in cells[:3]] == ["id", "u", "v"]:
            first = False
            continue
        first = False
        if len(cells) < 3 or not cells[0] or not cells[1] or not cells[2]:
            raise InputError(f"line {n}: expected 'id,u,v', got {','.join(row)!r}", path,
                             "give every row an image id and the VP's u and v in pixels")
        iid = cells[0]
        try:
            u, v = float(cells[1]), float(cells[2])
        except ValueError:
            raise InputError(f"line {n} ('{iid}'): u, v must be numbers, got {cells[1]!r}, {cells[2]!r}", path,
                             "write the VP as pixel coordinates, e.g. 241.5,180.0") from None
        if not (math.isfinite(u) and math.isfinite(v)):
            raise InputError(f"line {n} ('{iid}'): u, v must be finite, got {cells[1]}, {cells[2]}", path,
                             "write the VP as finite pixel coordinates")
        if iid in vps:
            raise InputError(f"line {n}: duplicate id '{iid}' (first on line {lines[iid]})", path,
                             "keep one VP per image id")
        vps[iid] = (u, v)
        lines[iid] = n
    if not vps:
        raise InputError("VP file has no rows", path, "write one 'id,u,v' row per image")
    return vps


def format_vp_csv(ids: Iterable[str], results: Iterable[VPResult]) -> str:
    """CSV text ``id,u,v,status,confidence,n_support,pan_deg,tilt_deg`` with a header row
    (readable by :func:`read_vp_csv`, which uses the first three columns)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["id", "u", "v", "status", "confidence", "n_support", "pan_deg", "tilt_deg"])
    for iid, r in zip(ids, results):
        w.writerow([iid, f"{r.vp[0]:.3f}", f"{r.vp[1]:.3f}", r.status, f"{r.confidence:.4f}", r.n_support,
                    f"{r.pan_deg:.4f}", f"{r.tilt_deg:.4f}"])
    return buf.getvalue()


def write_vp_csv(path: str | Path, ids: Iterable[str], results: Iterable[VPResult]) -> None:
    """Write :func:`format_vp_csv` to ``path`` atomically."""
    from ..io.images import write_bytes_atomic

    try:
        write_bytes_atomic(path, format_vp_csv(ids, results).encode())
    except (FileNotFoundError, NotADirectoryError):
        raise InputError("cannot write here (parent folder missing)", path, "create the folder first") from None


def given_results(vps: Mapping[str, tuple[float, float]], ids: Sequence[str], cams: Sequence[Camera],
                  file: str | Path | None = None) -> list[VPResult]:
    """Results with status 'given' for ``ids`` from a VP table; a missing id raises InputError."""
    missing = [i for i in ids if i not in vps]
    if missing:
        more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
        raise InputError(f"no VP row for image id '{missing[0]}'{more}", file,
                         "add an 'id,u,v' row for every image (ids are file stems)")
    return [_result(c, vps[i], 1.0, 0, "given", detected=vps[i]) for i, c in zip(ids, cams)]


def vps_for_items(images: Sequence[str | Path], ids: Sequence[str], camera: Camera, within: str,
                  smooth: int = 0, cfg: VPConfig = VPConfig(), id_prefix: str = "",
                  on_image: Callable[[int], None] | None = None,
                  on_error: Callable[[int, VCError], None] | None = None, cache=None) -> list[VPResult | None]:
    """Per-image VPs for within-camera correction: ``within`` is 'estimate' (detector + reliability
    rule + optional smoothing) or the path of a CSV ``id,u,v`` (status 'given'; every id must
    have a row; an id is looked up as given, then without ``id_prefix``). ``on_error`` and
    ``cache``: as in :func:`estimate_files` (estimation only)."""
    from ..camera.sources import camera_of_image

    if within == "estimate":
        if not isinstance(camera, Camera):
            raise InputError("VP estimation needs one camera; a per-frame calibration folder already gives every "
                             "frame its exact pose", camera.folder, "use the calibrated poses (no --within)")
        return estimate_files(images, camera, cfg, smooth, ids, on_image, on_error, cache)
    path = Path(within)
    table = read_vp_csv(path)
    keys = [i if i in table or not (id_prefix and i.startswith(id_prefix)) else i[len(id_prefix):] for i in ids]
    from ..io.images import image_size

    cams = [camera_of_image(camera, p, image_size(p)) for p in images]  # (per-frame calibration: each its own)
    res = given_results(table, keys, cams, path)
    for (u, v), c, k in zip((r.vp for r in res), cams, keys):
        w, h = c.size
        if not (-10 * w <= u <= 11 * w and -10 * h <= v <= 11 * h):
            raise InputError(f"VP of '{k}' ({u:g}, {v:g}) is far outside its {w}x{h} image", path,
                             "give u, v in pixels of the image as stored on disk")
    return res
