"""``vcprep bev``'s file layer: a folder of frames (with their labels, or the road masks or
probability maps ``vctrain predict`` wrote for them) onto the road grid, written as PNGs, and the
road in metres of each frame: :func:`bev_folder` with :class:`BevSettings`.

Written to ``out`` for a frame of id ``ID``: ``ID_image.png`` (the frame, bilinear, unseen 0),
``ID_label.png`` (its label: 0 not road, 1 road, 255 unseen or ignore), ``ID_mask.png`` (its road
mask, the same values; from a probability map: P >= 0.5) and ``ID_prob.png`` (its road probability,
0-255, unseen 0). Masks are found in ``masks`` as ``ID_prob.png``, ``ID_mask.png`` (0 / nonzero =
road, as ``vctrain predict`` writes them) or ``ID.png``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from ..dataset import Job
from ..errors import InputError
from ..io.images import read_image, write_png
from ..labels import LabelFormat, decode_label
from .border import camera_ego_rows, frame_hidden, label_border_rows
from .frames import frame_views
from .grid import KITTI_GRID, BevGrid
from .maps import bev_maps, to_bev
from .metres import CORRIDOR, road_in_metres
from .view import BevSource

__all__ = ["BevSettings", "bev_folder", "find_masks"]


@dataclass(frozen=True)
class BevSettings:
    """What ``vcprep bev`` does to every frame."""

    grid: BevGrid = KITTI_GRID              # the road grid (metres)
    within: str = "estimate"                # each frame's pose: 'estimate' (its road VP), 'none', or a VP CSV
    corridor: float = CORRIDOR              # the vehicle's corridor for free_m (metres)
    label_format: LabelFormat | None = None  # how the jobs' labels encode road
    images: bool = True                     # write ID_image.png
    roll: float = 0.0                       # the camera's roll about its optical axis (degrees, clockwise > 0)


def find_masks(folder: Path, jobs: list[Job]) -> dict[str, tuple[Path, str]]:
    """job id -> (file, 'prob' | 'mask') in ``folder``; a frame with none is an :class:`InputError`."""
    found = {}
    for job in jobs:
        for name, kind in ((f"{job.id}_prob.png", "prob"), (f"{job.id}_mask.png", "mask"), (f"{job.id}.png", "mask")):
            if (folder / name).is_file():
                found[job.id] = (folder / name, kind)
                break
        else:
            raise InputError(f"no {job.id}_prob.png, {job.id}_mask.png or {job.id}.png in {folder}", job.image,
                             "give the --out folder of 'vctrain predict' for these frames")
    return found


def _mask_bev(path: Path, kind: str, maps, size: tuple[int, int], out: Path, jid: str) -> np.ndarray:
    arr = read_image(path, label=True).array
    if arr.ndim != 2 or (arr.shape[1], arr.shape[0]) != tuple(size):
        raise InputError(f"is not a single-channel {size[0]}x{size[1]} road mask of its frame", path,
                         "give 0/255 masks or 0-255 probability maps at the frame's size")
    if kind == "prob":
        prob = to_bev(arr, maps, "prob")
        write_png(out / f"{jid}_prob.png", prob, "mask")
        mask = np.where(maps.valid.astype(bool), (prob >= 128).astype(np.uint8), 255).astype(np.uint8)
    else:
        mask = to_bev((arr != 0).astype(np.uint8), maps, "label")
    write_png(out / f"{jid}_mask.png", mask, "mask")
    return mask


def bev_folder(jobs: list[Job], source: BevSource, out: Path, settings: BevSettings,
               masks: dict[str, tuple[Path, str]] | None = None,
               on_image: Callable[[int], None] | None = None) -> Iterator[dict[str, Any]]:
    """Every frame of ``jobs`` onto ``settings.grid``, its PNGs written to ``out`` (module docstring);
    yields, for each frame with a label or a mask, ``{"id", "from": "mask"|"label", "free_m",
    "width_m", "area_m2", "pose", ...}`` (:func:`road_in_metres`; the mask's where both are given;
    the own vehicle's rows of the camera and a label's border rows, :mod:`.border`, hidden)."""
    views = frame_views(jobs, source, settings.within, on_image=on_image, roll=settings.roll)
    grid = settings.grid
    for job in jobs:
        view = views[job.id]
        maps = bev_maps(view, grid, job.image)
        Path(out / job.id).parent.mkdir(parents=True, exist_ok=True)
        if settings.images:
            write_png(out / f"{job.id}_image.png", to_bev(read_image(job.image).array, maps, "image"))
        road, what, border = None, None, 0
        if job.label is not None and settings.label_format is not None:
            label = decode_label(read_image(job.label, label=True).array, settings.label_format, job.label)
            if (label.shape[1], label.shape[0]) != tuple(view.size):
                raise InputError(f"label is {label.shape[1]}x{label.shape[0]} but its frame is {view.size[0]}x"
                                 f"{view.size[1]}", job.label, "give each frame's own label, at the frame's size")
            road, what, border = to_bev(label, maps, "label"), "label", label_border_rows(label)
            write_png(out / f"{job.id}_label.png", road, "mask")
        if masks is not None and job.id in masks:
            road, what, border = _mask_bev(*masks[job.id], maps, view.size, out, job.id), "mask", 0
        if road is not None:
            hidden, why = frame_hidden(maps, view.size, camera_ego_rows(source.camera, view.size), border)
            yield {"id": job.id, "from": what, **road_in_metres(road, grid, view, settings.corridor, hidden=hidden,
                                                                hidden_why=why)}
