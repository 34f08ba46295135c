"""The own vehicle: find the bottom image rows that show the rig's own car (its bonnet) from labels or frames.

A camera that sees its own vehicle says so with ``ego_rows`` (:class:`vcprep.camera.Camera`): those
bottom rows are never warped, never vote for a vanishing point and are back-projected like every
pixel. Left unsaid, the bonnet is warped as if it were road surface near the camera, where the
ground-plane homography magnifies it over much of the virtual image.

Datasets label the own vehicle as *ignore* in every frame (CamVid 11 "unlabelled", Cityscapes 1
"ego vehicle", the pix2pix release's void), and nothing else is ignored at the same pixels in
nearly every frame of a drive. So the own vehicle is the part of the region that is ignore in at
least ``SHARE`` of the frames that grows up from the bottom edge. ``ego_rows`` is the highest row
of that region, scanning up from the bottom row and stepping over gaps of up to ``GAP`` of the
image height (a bonnet ornament stands apart from the bonnet). Columns at the left and right
edges whose common ignore runs up from the bottom over more than half the image are a rim
(rectification border, out of roi), not a vehicle, and are left out.

Measured on the labels in ../shared/data (all frames of each set, and the same on every random
10-frame subset of 0001TP and Cityscapes): CamVid 0001TP 36 rows of 360 (the hand-read value of the
benchmark; the vehicle rises to the right corner), Cityscapes pix2pix 45 of 256 (its README: "roughly the
bottom 30-45 rows", the star included), and 0 on CamVid 0016E5 and 0006R0, IDD-Lite and LUMS, whose
frames show no own vehicle. BDD100K also gets 0, but not because nothing is there: most of its frames
show a bonnet or dashboard (27 dashcams, each its own), labelled background (0), not ignore, and 14
of its 41 frames have road down to the bottom row; a label search for one row count cannot find 27
different bonnets, so they are warped as road (a visible loss in its predictions).

From the frames alone (:func:`ego_rows_from_frames`, no labels): the vehicle's top edge is an image
edge with the same position and direction in every frame, while road texture, markings and traffic
move; per-pixel temporal spread does not separate a reflecting bonnet from road (Cityscapes bonnet
21 grey levels, CamVid 0016E5's road 21), but gradient persistence |mean g| / mean |g| does where the
edge keeps its contrast. Measured (benchmarks/camera_from_frames/ego_frames.py; constants chosen on synthetic drives,
CamVid 0016E5/0006R0 and one BDD100K dashcam, all sets reported): CamVid 0001TP 35 (labels 36; 35 on
each 30-frame window), 0 on CamVid val 0016E5, 0006R0, 0016E5, IDD-Lite and LUMS (and every window;
windows of near-video frames with < 20 distinct frames are refused), BDD100K dashcam 0a0c3694 104 of
720 rows (8 frames, minimum lowered; hand-read about 107). It misses Cityscapes' mirror-like bonnet
(0, labels 45): the bonnet reflects the road, so its edge changes contrast and sign.

A folder of several sources (dashcams, drives) has one own vehicle per source:
:func:`ego_rows_per_source` groups the frames (:func:`source_groups`: a folder per drive; BDD100K-style
names, whose first 8 hex digits are the source; CamVid-style names up to the first '_') and searches
each group alone, with :data:`GROUP_MIN_DISTINCT` distinct frames the least. Measured on random subsets
of sources whose vehicle is known (20 each, 8 frames): CamVid 0001TP 34-48 rows (labels 36) in 20 of 20;
0 in 20 of 20 of CamVid 0016E5, 19 of 20 of 0006R0 (one 125 of 360) and of Cityscapes (one 73 of 256);
BDD100K dashcam 0a0c3694's 8 frames 104 of 720 (its labels: road ends 99-117 rows up). A group of fewer
frames, a single frame above all, is not searched (said, with the fix): a single-frame detector (the
strongest near-horizontal edge darker below, traced across the width) matched the labels on only 13
of BDD100K's 41 frames. A dark bottom (a night frame's dashboard shows no edge) makes "none found"
"could not tell" (:data:`DARK`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Sequence

import cv2
import numpy as np

from ..errors import InputError
from ..io.images import read_image
from ..labels import IGNORE, LabelFormat, decode_label

__all__ = ["EgoEstimate", "MIN_FRAMES", "MIN_DISTINCT", "GROUP_MIN_DISTINCT", "SourceEgo", "source_groups",
           "ego_rows_per_source", "spread", "ego_rows_from_labels", "ego_rows_from_label_files",
           "ego_rows_from_frames", "ego_rows_from_frame_files", "rows_at_height"]

MIN_FRAMES = 5        # fewer labelled frames cannot tell the own vehicle from one scene's ignored content
SHARE = 0.9           # a pixel belongs to the common ignore region when ignore in >= this share of frames
GAP = 0.03            # gaps (share of the height) stepped over when scanning up
BOTTOM = 0.05         # the bottom rows must be common ignore over >= this share of the (non-rim) columns
MAX_SHARE = 0.5       # a column or region reaching above half the image is no vehicle


@dataclass(frozen=True)
class EgoEstimate:
    """``rows`` bottom rows (at ``size`` = (w, h)) show the own vehicle; 0: no own vehicle in view."""

    rows: int
    size: tuple[int, int]
    frames: int
    bottom_share: float   # labels: share of the bottom rows (non-rim columns) that is common ignore;
    #                       frames: share of the width spanned by the vehicle's fixed edge
    method: str = "labels"  # "labels" or "frames"
    bottom_grey: float = field(default=255.0, compare=False)  # frames: mean grey of the bottom ZONE (DARK)

    def describe(self) -> str:
        if self.method == "frames":
            return _describe_frames(self)
        if not self.rows:
            return (f"no own vehicle: no ignore region common to {SHARE:.0%} of the {self.frames} labelled "
                    f"frames grows up from the bottom edge")
        return (f"own vehicle in the bottom {self.rows} of {self.size[1]} rows: ignore in >= {SHARE:.0%} of the "
                f"{self.frames} labelled frames ({self.bottom_share:.0%} of the bottom rows)")

    def to_dict(self) -> dict:
        if self.method == "frames":
            return _frames_dict(self)
        return {"ego_rows": self.rows, "image_size": list(self.size), "frames": self.frames,
                "bottom_share": round(self.bottom_share, 4), "method": "labels: ignore common to "
                f">= {SHARE:.0%} of frames, grown up from the bottom edge"}


def ego_rows_from_labels(labels: Iterable[np.ndarray], source: str | Path | None = None) -> EgoEstimate:
    """The own vehicle's bottom rows from decoded labels (uint8, ``IGNORE`` = 255; all one size).

    Raises :class:`InputError` for fewer than ``MIN_FRAMES`` labels, labels of different sizes,
    and a common ignore region that reaches above half the image (no vehicle is that tall: an
    out-of-roi mask or a mis-read label format)."""
    count = None
    n = 0
    for lab in labels:
        if lab.ndim != 2:
            raise InputError(f"a decoded label must be one channel, got shape {lab.shape}", source,
                             "decode labels with vcprep.labels.decode_label")
        if count is None:
            count = np.zeros(lab.shape, np.uint32)
        elif lab.shape != count.shape:
            raise InputError(f"labels of two sizes ({count.shape[1]}x{count.shape[0]} and {lab.shape[1]}x"
                             f"{lab.shape[0]}) cannot share one own-vehicle region", source,
                             "find it per camera: give the labels of one camera at one size")
        count += lab == IGNORE
        n += 1
    if n < MIN_FRAMES:
        raise InputError(f"{n} labelled frame(s) are too few to find the own vehicle (need >= {MIN_FRAMES})", source,
                         "give more labelled frames of the drive, or write ego_rows in the camera file by hand")
    h, w = count.shape
    common = count >= SHARE * n
    run = np.where(common[::-1].all(axis=0), h, np.argmin(common[::-1], axis=0))  # per column, from the bottom
    tall = run > MAX_SHARE * h
    left = int(np.argmin(tall)) if not tall.all() else w    # rims running up a side are no vehicle
    right = w - int(np.argmin(tall[::-1])) if not tall.all() else w
    cols = common[:, left:right]
    filled = cols.sum(axis=1)                               # common-ignore pixels per row
    gap = max(2, int(round(GAP * h)))
    bottom_share = float(cols[h - gap:].mean()) if cols.size else 0.0
    rows = 0
    if bottom_share >= BOTTOM:
        empty = 0
        for r in range(h - 1, -1, -1):
            if filled[r]:
                rows, empty = h - r, 0
            else:
                empty += 1
                if empty > gap:
                    break
    if rows > MAX_SHARE * h:
        raise InputError(f"the ignore region common to the labelled frames reaches {rows} of {h} rows from the bottom: "
                         "too tall for the own vehicle", source,
                         "check --label-format (is road read as ignore?), or write ego_rows in the camera file by hand")
    return EgoEstimate(rows, (w, h), n, bottom_share)


def ego_rows_from_label_files(files: Sequence[str | Path], fmt: LabelFormat,
                              source: str | Path | None = None) -> EgoEstimate:
    """:func:`ego_rows_from_labels` over label files read with ``fmt``; frames whose size differs
    from the most common size are left out (one camera, one size)."""
    files = [Path(f) for f in files]
    decoded = [decode_label(read_image(f, label=True).array, fmt, f) for f in files]
    if not decoded:
        return ego_rows_from_labels([], source)
    sizes = [d.shape for d in decoded]
    common = max(set(sizes), key=sizes.count)
    return ego_rows_from_labels((d for d in decoded if d.shape == common), source)


def rows_at_height(est: EgoEstimate, height: int) -> int:
    """``est.rows`` for the same frames at ``height`` rows: every row that reaches below the
    vehicle's top edge (rounded up, so the vehicle stays covered)."""
    if not est.rows:
        return 0
    s = height / est.size[1]
    return int(np.ceil(height - s * (est.size[1] - est.rows) - 1e-9))


# -- from the frames alone -----------------------------------------------------------------------------
# The own vehicle is fixed in the image while the scene moves: its top edge (bonnet contour, dashboard
# rim) is an image edge at the same place with the same direction in every frame. Per pixel, the
# persistence |mean_t g| / mean_t |g| of the image gradient g is 1 for such an edge and small for road
# texture and markings, which move between frames (a lane line kept in view drifts sideways).

WORK_WIDTH = 480      # frames wider than this are measured at this width (INTER_AREA), rows scaled back up
DISTINCT = 8.0        # a frame counts when its 64-px thumbnail differs from every counted one by > this mean
#                       grey level (a stopped car repeats its scene: every edge would persist)
MIN_DISTINCT = 20     # fewer distinct frames cannot tell a fixed vehicle from a scene that barely changed
PERSIST = 0.85        # an edge is fixed when |mean g| >= this share of mean |g| (its direction in ~all frames)
MIN_EDGE = 2.0        # ... and |mean g| (3x3 Sobel, grey levels) above this floor (flat areas are no edge)
ZONE = 0.35           # the vehicle's edge is looked for in the bottom ZONE of the image
SPAN = 0.25           # a fixed, near-horizontal edge spanning >= this share of the width is the vehicle's
NIGHT = 40.0          # a frame darker on average is a night frame, brightened to mean grey LIFT first (_work_grey);
LIFT = 100.0          # no frame of the measured day sets (CamVid, Cityscapes, IDD-Lite: medians 81-96) is that
#                       dark but one IDD-Lite frame of 1403 (37), not in the sample of camera_from_frames/ego_frames.py


def _thumb(grey: np.ndarray) -> np.ndarray:
    h, w = grey.shape
    return cv2.resize(grey, (64, max(1, round(64 * h / w))), interpolation=cv2.INTER_AREA)


def ego_rows_from_frames(frames: Iterable[np.ndarray], source: str | Path | None = None,
                         min_distinct: int = MIN_DISTINCT) -> EgoEstimate:
    """The own vehicle's bottom rows from one camera's frames (uint8 BGR or grey, all one size), no labels.

    Near-repeats (thumbnail mean difference <= ``DISTINCT``) are dropped; over the ``frames`` left the
    gradient persistence map is taken, its fixed near-horizontal edges (``PERSIST``, ``MIN_EDGE``,
    direction within 45 deg of horizontal) in the bottom ``ZONE`` are grouped (8-connected), and the
    highest group spanning ``SPAN`` of the width is the vehicle's top: ``rows`` counts the rows from
    it down (at the frames' size, rounded up). None: 0 (no own vehicle). Raises :class:`InputError`
    for fewer than ``min_distinct`` distinct frames and frames of different sizes."""
    sx = sy = mag = None
    bottom = 0.0
    thumbs: list[np.ndarray] = []
    size = None
    for f in frames:
        size = size or (f.shape[1], f.shape[0])
        grey, dark = _work_grey(f, size, source)
        t = _thumb(grey)
        if any(float(np.abs(t - k).mean()) <= DISTINCT for k in thumbs):
            continue
        thumbs.append(t)
        bottom += dark
        g = cv2.GaussianBlur(grey, (0, 0), 1.0)
        gx, gy = cv2.Sobel(g, cv2.CV_32F, 1, 0), cv2.Sobel(g, cv2.CV_32F, 0, 1)
        if sx is None:
            sx, sy, mag = np.zeros_like(gx), np.zeros_like(gy), np.zeros_like(gx)
        sx += gx
        sy += gy
        mag += np.hypot(gx, gy)
    n = len(thumbs)
    if n < min_distinct:
        raise InputError(f"{n} distinct frame(s) are too few to find the own vehicle from frames (need >= "
                         f"{min_distinct}; near-repeats of a stopped car do not count)", source,
                         "give a few dozen frames spread over the drive, or write ego_rows in the camera file by hand")
    mx, my = sx / n, sy / n
    fixed = np.hypot(mx, my)
    persistent = (fixed >= PERSIST * (mag / n)) & (fixed > MIN_EDGE) & (np.abs(my) >= np.abs(mx))
    h, w = persistent.shape
    persistent[:h - int(ZONE * h)] = False
    k, comp, stats, _ = cv2.connectedComponentsWithStats(persistent.astype(np.uint8), connectivity=8)
    top, span = h, 0.0
    for i in range(1, k):
        if stats[i, cv2.CC_STAT_WIDTH] >= SPAN * w:
            y = _edge_top(comp == i, fixed)
            if y < top:
                top, span = y, stats[i, cv2.CC_STAT_WIDTH] / w
    rows = 0 if top == h else int(np.ceil(size[1] - top * size[1] / h - 1e-9))
    return EgoEstimate(rows, size, n, span, "frames", bottom / n)


def _work_grey(frame: np.ndarray, size: tuple[int, int], source) -> tuple[np.ndarray, float]:
    """(the frame in grey at the working width, float; the mean grey of its bottom ``ZONE`` as taken).
    A night frame (mean grey below :data:`NIGHT`) is brightened to a day frame's mean (``LIFT``), so that its frames
    count as distinct and its edges pass ``MIN_EDGE`` as a day frame's of the same contrast would."""
    grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame
    grey = grey.astype(np.float32)
    if (grey.shape[1], grey.shape[0]) != size:
        raise InputError(f"frames of two sizes ({size[0]}x{size[1]} and {grey.shape[1]}x{grey.shape[0]}) cannot "
                         "share one own-vehicle region", source, "give the frames of one camera at one size")
    if size[0] > WORK_WIDTH:
        grey = cv2.resize(grey, (WORK_WIDTH, round(size[1] * WORK_WIDTH / size[0])), interpolation=cv2.INTER_AREA)
    bottom = float(grey[grey.shape[0] - int(ZONE * grey.shape[0]):].mean())
    mean = float(grey.mean())
    return (grey * (LIFT / max(mean, 1.0)) if mean < NIGHT else grey), bottom


def _edge_top(region: np.ndarray, strength: np.ndarray) -> int:
    """The highest row of the edge ``region`` (bool, h x w): the blur spreads an edge over a band, so in
    each column the edge is the strongest row of the band's first run of rows (the edge itself)."""
    top = region.shape[0]
    for c in np.flatnonzero(region.any(axis=0)):
        y0 = int(np.argmax(region[:, c]))
        y1 = y0 + int(np.argmin(region[y0:, c])) if not region[y0:, c].all() else region.shape[0]
        top = min(top, y0 + int(np.argmax(strength[y0:y1, c])))
    return top


def ego_rows_from_frame_files(files: Sequence[str | Path], source: str | Path | None = None,
                              min_distinct: int = MIN_DISTINCT) -> EgoEstimate:
    """:func:`ego_rows_from_frames` over image files (read one at a time); frames whose size differs
    from the first file's are left out (one camera, one size: a mixed folder keeps its first camera)."""
    files = [Path(f) for f in files]
    if not files:
        return ego_rows_from_frames([], source, min_distinct)
    first = read_image(files[0]).size

    def frames():
        for f in files:
            img = read_image(f).array
            if img.dtype != np.uint8:
                img = (img // 257).astype(np.uint8)
            if (img.shape[1], img.shape[0]) == first:
                yield img

    return ego_rows_from_frames(frames(), source, min_distinct)


def _describe_frames(est: EgoEstimate) -> str:
    if not est.rows and est.bottom_grey < DARK:
        return (f"could not tell: the bottom {ZONE:.0%} of the {est.frames} distinct frames is dark (mean grey "
                f"{est.bottom_grey:.0f} < {DARK:.0f}: a dashboard at night shows no edge to find)")
    if not est.rows:
        return (f"no own vehicle: no near-horizontal edge fixed in {est.frames} distinct frames spans "
                f"{SPAN:.0%} of the width in the bottom {ZONE:.0%} of the image")
    return (f"own vehicle in the bottom {est.rows} of {est.size[1]} rows: an edge fixed in {est.frames} distinct "
            f"frames spans {est.bottom_share:.0%} of the width there (found from the frames, no labels)")


def _frames_dict(est: EgoEstimate) -> dict:
    return {"ego_rows": est.rows, "image_size": list(est.size), "frames": est.frames,
            "span": round(est.bottom_share, 4), "method": f"frames: near-horizontal edge fixed (persistence "
            f">= {PERSIST}) in distinct frames, spanning >= {SPAN:.0%} of the width in the bottom {ZONE:.0%}"}


# -- several sources in one folder ---------------------------------------------------------------------
GROUP_MIN_DISTINCT = 8  # a source of a mixed folder is searched with >= this many distinct frames (module docstring)
DARK = 40.0             # frames whose bottom ZONE is darker on average than this grey level: 'none' is 'could not tell'
_BDD = re.compile(r"[0-9a-f]{8}-[0-9a-f]{8}")  # BDD100K: <source>-<clip>, 8 hex digits each
_PREFIX = re.compile(r"(.+?)_")                 # CamVid: 0001TP_006690 (vcprep.vp.sequence_key's rule)


@dataclass(frozen=True)
class SourceEgo:
    """One source of a folder (:func:`ego_rows_per_source`): its frames and own vehicle (``estimate``),
    or None and why it was not searched (``problem``)."""

    name: str
    files: tuple[Path, ...]
    estimate: EgoEstimate | None
    problem: str = ""


def source_groups(files: Sequence[str | Path]) -> tuple[str, dict[str, list[Path]]]:
    """(the rule, source name -> its frames) for the frames of one folder or several: the folder when
    they lie in more than one (a folder per drive); else BDD100K-style names (``0a0a0b1a-7c39d841``:
    the first 8 hex digits); else CamVid-style names up to the first '_' (``0001TP_006690``) when that
    gives more than one source; else one source ("one source" as the rule)."""
    files = [Path(f) for f in files]
    rules = [("folder per drive", lambda f: str(f.parent)),
             ("BDD100K-style source prefix (the first 8 hex digits of the name)",
              lambda f: f.stem[:8] if _BDD.fullmatch(f.stem) else None),
             ("CamVid-style name prefix (the name up to the first '_')",
              lambda f: m.group(1) if (m := _PREFIX.match(f.stem)) else None)]
    for rule, key in rules:
        keys = [key(f) for f in files]
        if None not in keys and len(set(keys)) > 1:
            groups: dict[str, list[Path]] = {}
            for k, f in zip(keys, files):
                groups.setdefault(k, []).append(f)
            return rule, groups
    return "one source", {str(files[0].parent) if files else "": files}


def spread(files: Sequence[Path], n: int) -> list[Path]:
    """Up to ``n`` of ``files``, spread evenly over them (first and last included)."""
    picks = np.linspace(0, len(files) - 1, min(n, len(files)))
    return [files[k] for k in sorted({int(round(k)) for k in picks})] if len(files) else []


def ego_rows_per_source(files: Sequence[str | Path], samples: int = 48,
                        min_distinct: int = GROUP_MIN_DISTINCT) -> tuple[str, list[SourceEgo]]:
    """(the grouping rule, each source's own vehicle) for a folder of several sources (:func:`source_groups`):
    each source searched alone (:func:`ego_rows_from_frame_files`) in up to ``samples`` of its frames
    spread over it; a source with fewer than ``min_distinct`` distinct frames is left unsearched, its
    ``problem`` said."""
    rule, groups = source_groups(files)
    out = []
    for name, group in groups.items():
        try:
            out.append(SourceEgo(name, tuple(group), ego_rows_from_frame_files(spread(group, samples), name,
                                                                                min_distinct)))
        except InputError as e:
            out.append(SourceEgo(name, tuple(group), None, e.problem))
    return rule, out
