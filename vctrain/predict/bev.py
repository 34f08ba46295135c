"""``vctrain predict --bev``: every predicted frame's road in a bird's-eye view (BEV) and in metres.

For a frame written as ``<stem>_mask.png`` / ``<stem>_prob.png``, :meth:`BevRun.write` also writes

- ``<stem>_bev_prob.png``: P(road) on the grid, 0-255 (the ``_prob.png`` values sampled bilinearly;
  unseen cells 0), far row first;
- ``<stem>_bev_mask.png``: the perspective mask (P >= 0.5) on the grid by nearest neighbour, in
  ``vcprep bev``'s values (0 not road, 1 road, 255 unseen: a perspective mask's 0/255 has no
  value for a cell the camera does not see), byte for byte what ``vcprep bev --masks`` writes from
  the ``_mask.png`` with the same pose;

and hands ``{"id", "free_m", "width_m", "area_m2", "pose", ...}`` (:func:`vcprep.bev.road_in_metres`
of that BEV mask, the camera's own-vehicle rows hidden; a video's frames also ``"frame"``) to the
options' ``emit`` (the CLI: one JSON line on stdout). An overlay gets a small inset of the BEV in
its top right corner (:func:`draw_inset`): the road, the corridor up to the free distance, the free
distance in metres. Each frame's pose is kept (:func:`recording`) for ``predict.json``, where
``vctrain eval --bev`` takes it (:func:`poses_rule`).

The pose each frame is projected with (:meth:`BevRun.view`): its own road VP by default (``vctrain
predict --within auto`` or ``estimate``: ``vcprep bev``'s rule, :func:`vcprep.bev.within_rule`; the
model's own VPs where it is warped with them, else estimated by the model's VP rule), the camera's
nominal pose with ``--within none``, given VPs with a CSV; a per-frame calibration folder or a KITTI
file gives every frame its calibrated pose (the devkit's transform for ``Tr_cam_to_road``; ``--within``
then concerns the model alone). The maps
are :func:`vcprep.bev.bev_maps`' (cached: a fixed pose builds them once), one ``cv2.remap`` per
output. It runs on the pipeline's writing thread (:mod:`vctrain.predict.pipeline`), in frame order.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import cv2
import numpy as np

from vcprep.bev import CORRIDOR, KITTI_GRID, BevGrid, BevSource, GroundView, bev_maps, road_in_metres, to_bev, \
    within_rule
from vcprep.bev.border import camera_ego_rows, frame_hidden
from vcprep.errors import InputError
from vcprep.io import write_png

from .written import prob_u8

__all__ = ["BevOptions", "BevRun", "BevMeasure", "draw_inset", "BEV_NEEDS_CAMERA", "recording", "poses_line",
           "poses_rule"]

BEV_NEEDS_CAMERA = ("add --camera (a preset, a calibration file, or 'estimate' from these frames): its height and "
                    "pose put the road in metres")
INSET_ROAD, INSET_OFF, INSET_UNSEEN = (0, 200, 0), (90, 90, 90), (0, 0, 0)  # BGR
CORRIDOR_YELLOW, FREE_RED, INSET_EDGE = (0, 255, 255), (0, 0, 255), (255, 255, 255)
INSET_SHARE = 1 / 3  # the inset's height, a share of the frame's


@dataclass(frozen=True)
class BevOptions:
    """What ``--bev`` asks for: the grid (``--range``, ``--res``), the corridor (``--corridor``), where
    each frame's record goes (``emit``) and the ``--camera`` given (``spec``: a KITTI ``.txt`` file
    gives the devkit's transform)."""

    grid: BevGrid = KITTI_GRID
    corridor: float = CORRIDOR
    emit: Callable[[dict[str, Any]], None] | None = None
    spec: str | None = None


def _lut() -> np.ndarray:
    lut = np.zeros((256, 1, 3), np.uint8)
    lut[:, 0] = INSET_UNSEEN
    lut[0, 0], lut[1, 0] = INSET_OFF, INSET_ROAD
    return lut


_INSET_LUT = _lut()


def draw_inset(image: np.ndarray, bev_mask: np.ndarray, grid: BevGrid, road: dict[str, Any],
               corridor: float = CORRIDOR, origin_z: float = 0.0) -> np.ndarray:
    """``image`` (BGR, changed in place and returned) with the BEV mask ``bev_mask`` (0/1/255) drawn
    small in its top right corner: road green, not road grey, unseen black, far row up; the
    corridor (yellow) up to ``road['free_m']`` (a red bar) and that distance written below it ('46.0+ m':
    free to the grid's far edge)."""
    h, w = image.shape[:2]
    rows, cols = grid.shape
    ih = max(24, int(h * INSET_SHARE))
    iw = max(8, int(round(ih * cols / rows)))
    small = cv2.LUT(cv2.cvtColor(cv2.resize(bev_mask, (iw, ih), interpolation=cv2.INTER_NEAREST),
                                 cv2.COLOR_GRAY2BGR), _INSET_LUT)
    sx, sy = iw / (grid.x_max - grid.x_min), ih / (grid.z_max - grid.z_min)
    x0, x1 = (int(round((x - grid.x_min) * sx)) for x in (-corridor / 2, corridor / 2))
    free = road.get("free_m")
    if free is not None:
        y = int(round((grid.z_max - free - origin_z) * sy))
        cv2.rectangle(small, (x0, y), (x1, ih - 1), CORRIDOR_YELLOW, 1)
        cv2.line(small, (max(0, x0 - 3), y), (min(iw - 1, x1 + 3), y), FREE_RED, 2)
    text = "free " + (f"{free:.1f}{'+' if road.get('free_to_edge') else ''} m" if free is not None else "-")
    m = max(4, h // 100)
    y0, x0 = m, w - m - iw
    if x0 < 0 or y0 + ih >= h:
        return image  # a frame too small for an inset
    image[y0:y0 + ih, x0:x0 + iw] = small
    cv2.rectangle(image, (x0 - 1, y0 - 1), (x0 + iw, y0 + ih), INSET_EDGE, 1)
    scale = max(0.35, ih / 400)
    cv2.putText(image, text, (x0, min(h - 2, y0 + ih + int(16 * scale) + 2)), cv2.FONT_HERSHEY_SIMPLEX, scale,
                INSET_EDGE, 1, cv2.LINE_AA)
    return image


class BevRun:
    """One ``vctrain predict --bev`` run over frames of ``camera`` (a Camera or per-frame calibration
    files; module docstring), the poses by ``within`` (predict's ``--within``: 'auto' is
    ``vcprep bev``'s default)."""

    def __init__(self, options: BevOptions, camera: Any, within: str, what: Any = None):
        if camera is None:
            raise InputError("--bev needs the frames' camera", what, BEV_NEEDS_CAMERA)
        self.options = options
        self.source = BevSource.of(camera, options.spec)
        # calibration files give every frame its exact pose: --within then concerns the model alone
        self.rule = "none" if self.source.calibrated else within_rule(None if within == "auto" else within,
                                                                        self.source, options.spec)

    def view(self, image: str | Path, size: tuple[int, int], vp: tuple[float, float] | None = None,
             status: str | None = None) -> GroundView:
        """The frame's view: at its VP's pose (``vp``; ignored under the rule 'none' and for a store
        item's ``status`` 'camera' or 'calibrated': the camera's own pose), else nominal."""
        if self.rule == "none" or status in ("camera", "calibrated"):
            vp, status = None, None
        return self.source.view(image, size, vp, status)

    def measure(self, prob: np.ndarray, image: str | Path, vp: tuple[float, float] | None = None,
                status: str | None = None) -> "BevMeasure":
        """The bird's-eye view of a frame's P(road) ``prob`` (its file ``image``, at the pose of
        ``vp``: :meth:`view`) and its road in metres, in memory: what :meth:`write` writes."""
        grid = self.options.grid
        view = self.view(image, (prob.shape[1], prob.shape[0]), vp, status)
        maps = bev_maps(view, grid, image)
        mask = to_bev((prob >= 0.5).astype(np.uint8), maps, "label")
        hidden, why = frame_hidden(maps, view.size, camera_ego_rows(self.source.camera, view.size))
        road = road_in_metres(mask, grid, view, self.options.corridor, hidden=hidden, hidden_why=why)
        return BevMeasure(to_bev(prob_u8(prob), maps, "prob"), mask, road, grid, view)

    def write(self, out: Path, stem: str, prob: np.ndarray, image: str | Path, vp: tuple[float, float] | None = None,
              status: str | None = None, **extra: Any) -> Callable[[np.ndarray], np.ndarray]:
        """Write ``stem``'s BEV PNGs into ``out``, emit its record (``extra`` fields after ``id``) and
        return what draws its inset on an overlay."""
        m = self.measure(prob, image, vp, status)
        (out / stem).parent.mkdir(parents=True, exist_ok=True)
        write_png(out / f"{stem}_bev_prob.png", m.prob)
        write_png(out / f"{stem}_bev_mask.png", m.mask, kind="mask")
        if self.options.emit is not None:
            self.options.emit({"id": stem, **extra, **m.metres})
        return lambda img: draw_inset(img, m.mask, m.grid, m.metres, self.options.corridor, m.view.origin_z)


@dataclass(frozen=True)
class BevMeasure:
    """A frame's road in a bird's-eye view: ``prob`` (uint8 0-255, P(road) on the grid, unseen 0: the
    ``_bev_prob.png``), ``mask`` (uint8: 0 not road, 1 road, 255 unseen: the ``_bev_mask.png``), far
    row first, on ``grid``; ``metres`` (``free_m``, ``width_m``, ``area_m2``, ``pose``:
    :func:`vcprep.bev.road_in_metres`, the JSON line of ``predict --bev``) and the ``view`` it was
    projected with."""

    prob: np.ndarray
    mask: np.ndarray
    metres: dict[str, Any]
    grid: BevGrid
    view: GroundView


def recording(options: BevOptions, poses: dict[str, dict[str, Any]]) -> BevOptions:
    """``options`` whose ``emit`` also keeps each frame's pose in ``poses`` (id -> its ``pose``), for
    ``predict.json``: ``vctrain eval --bev`` then takes the same poses."""
    from dataclasses import replace

    emit = options.emit

    def keep(record: dict[str, Any]) -> None:
        poses[str(record["id"])] = record.get("pose") or {}
        if emit is not None:
            emit(record)

    return replace(options, emit=keep)


POSE_WORDS = {"vp": "its road VP", "nominal": "the camera's nominal pose", "calibration": "its calibration file",
              "kitti": "its KITTI calibration (the devkit's transform)"}


def _poses_said(poses: dict[str, dict[str, Any]]) -> str:
    """'BEV poses: each frame's pose from its road VP (12 frames), the camera's nominal pose (1 frame)'."""
    from collections import Counter

    from vcprep.progress import count

    by = Counter(str(p.get("source", "nominal")) for p in poses.values())
    return "BEV poses: each frame's pose from " + ", ".join(f"{POSE_WORDS.get(src, src)} ({count(n, 'frame')})"
                                                            for src, n in by.most_common())


def poses_line(poses: dict[str, dict[str, Any]]) -> str:
    """What ``vctrain predict --bev`` says of its poses on stderr."""
    return (_poses_said(poses) + "; kept in predict.json, where 'vctrain eval --bev' takes them (--within none: "
            "the camera's nominal pose)")


def poses_rule(poses: dict[str, dict[str, Any]], calibrated: bool, within: str) -> str:
    """What ``vctrain eval --bev`` says of its poses: the ones ``predict --bev`` kept (``poses``), the
    frames' calibration, or the camera's nominal pose (and why)."""
    if calibrated:
        return "BEV poses: each frame's calibration (as 'vctrain predict --bev' takes it)"
    if within == "none":
        return "BEV poses: the camera's nominal pose (--within none)"
    if not poses:
        return ("BEV poses: the camera's nominal pose (predict.json keeps no frame poses: 'vctrain predict --bev' "
                "keeps each frame's road-VP pose for eval to take)")
    return _poses_said(poses) + ", as 'vctrain predict --bev' found them (predict.json; --within none: the camera's " \
        "nominal pose)"
