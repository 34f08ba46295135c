"""The own vehicle: find the bottom image rows that show the rig's own car (its bonnet) from labels.

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
different bonnets, so they are warped as road (a visible loss in its predictions). Frames alone (without labels) were tried: per-pixel
temporal spread and edges that stay in place over a drive do not separate a reflecting bonnet from
the road (Cityscapes bonnet spread 21 grey levels, CamVid 0016E5's road 21), so they are not used.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from .errors import InputError
from .imageio import read_image
from .labels import IGNORE, LabelFormat, decode_label

__all__ = ["EgoEstimate", "MIN_FRAMES", "ego_rows_from_labels", "ego_rows_from_label_files", "rows_at_height"]

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
    bottom_share: float   # share of the bottom rows (non-rim columns) that is common ignore

    def describe(self) -> str:
        if not self.rows:
            return (f"no own vehicle: no ignore region common to {SHARE:.0%} of the {self.frames} labelled "
                    f"frames grows up from the bottom edge")
        return (f"own vehicle in the bottom {self.rows} of {self.size[1]} rows: ignore in >= {SHARE:.0%} of the "
                f"{self.frames} labelled frames ({self.bottom_share:.0%} of the bottom rows)")

    def to_dict(self) -> dict:
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
