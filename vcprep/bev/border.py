"""Frame rows that show no road scene, on the bird's-eye-view grid: :func:`label_border_rows` (a
label whose bottom pixel rows are marked not road across the whole frame, as KITTI road's
``gt_image_2``: its bottom 4 rows) and :func:`hidden_cells` (a frame's bottom rows - that border, or
the own vehicle's ``ego_rows`` - as the BEV cells they cover). :func:`vcprep.bev.road_in_metres`
counts those cells as unseen and names them in ``start_why``, so a label's border does not stop
``free_m`` at the grid's first row."""
from __future__ import annotations

import numpy as np

from ..warp.remap import RemapMaps
from .maps import to_bev

__all__ = ["label_border_rows", "hidden_cells", "bottom_rows_why", "frame_hidden", "camera_ego_rows", "MAX_BORDER"]

MAX_BORDER = 0.05  # a border is at most this share of the frame's height


def label_border_rows(label: np.ndarray) -> int:
    """How many of ``label``'s (0 not road, 1 road, 255 ignore) bottom pixel rows hold no road
    across the whole frame while the row above them does: a labelling border (KITTI road's
    ``gt_image_2``: 4), 0 where there is none or it is taller than :data:`MAX_BORDER` of the frame."""
    has_road = (label == 1).any(axis=1)
    if not has_road.any() or has_road[-1]:
        return 0
    k = int(label.shape[0] - 1 - np.flatnonzero(has_road)[-1])
    return k if k <= MAX_BORDER * label.shape[0] else 0


def hidden_cells(maps: RemapMaps, size: tuple[int, int], rows: int) -> np.ndarray | None:
    """The BEV cells (bool, the grid's shape) that sample the bottom ``rows`` pixel rows of a frame of
    ``size`` (w, h) through ``maps``; None for 0 rows."""
    if rows <= 0:
        return None
    w, h = size
    band = np.zeros((h, w), np.uint8)
    band[h - min(rows, h):] = 1
    return to_bev(band, maps, "label") == 1


def bottom_rows_why(ego_rows: int, border: int) -> tuple[int, str | None]:
    """(rows, reason) of a frame's bottom rows that show no road scene: the own vehicle's
    ``ego_rows`` (a camera's) or a label's ``border`` (:func:`label_border_rows`), the larger."""
    if ego_rows <= 0 and border <= 0:
        return 0, None
    if ego_rows >= border:
        return ego_rows, f"own vehicle (the camera's ego_rows: its bottom {ego_rows} pixel rows)"
    return border, f"label border (its bottom {border} pixel rows hold no road across the frame)"


def frame_hidden(maps: RemapMaps, size: tuple[int, int], ego_rows: int = 0,
                 border: int = 0) -> tuple[np.ndarray | None, str | None]:
    """(:func:`hidden_cells`, its reason) of a frame's bottom rows by :func:`bottom_rows_why`."""
    rows, why = bottom_rows_why(int(ego_rows), int(border))
    return hidden_cells(maps, size, rows), why


def camera_ego_rows(camera, size: tuple[int, int]) -> int:
    """``camera``'s own-vehicle rows (``ego_rows``, 0 where it has none or is no single camera) at a
    frame ``size`` (w, h) tall (rounded up)."""
    rows = int(getattr(camera, "ego_rows", 0) or 0)
    cam_size = getattr(camera, "size", None)
    if rows <= 0 or not cam_size:
        return 0
    return min(size[1], int(np.ceil(rows * size[1] / cam_size[1] - 1e-9)))
