"""The road in metres from a bird's-eye-view road mask: :func:`road_in_metres`.

Input: a BEV label or mask on a :class:`~vcprep.bev.grid.BevGrid` (0 not road, 1 road, 255 unseen
or ignore; far row first). Distances are along the road plane from the camera's foot (the grid's
z minus the view's ``origin_z``: 0 for a camera, the road frame's offset for a KITTI calibration).

- ``free_m``: how far ahead the corridor of the vehicle (``corridor`` metres wide, centred on
  x = 0: the cells whose centre lies within it, at least the one column nearest 0; along z, the
  road's direction under a VP pose, the camera's heading under a nominal or calibrated one) is road. From
  the nearest row the camera sees in full (or the first with a not-road cell), rows are taken
  outwards until one holds a not-road (0) or unknown (255) cell; ``free_m`` is that row's near
  edge: where the road stops being free, or where the view stops vouching for it. Every row road:
  the grid's far edge. None where the camera sees no corridor cell.
- ``width_m``: {"10": w, "20": w, "30": w}: the road cells of the row that holds that distance
  (the drivable width: a car on the road is not counted) times the cell size; None where the row
  lies outside the grid, is unseen, or its road reaches the grid's side or an unseen cell (the
  width is not all in view).
- ``area_m2``: road cells times the cell area.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from .grid import BevGrid
from .view import GroundView

__all__ = ["road_in_metres", "CORRIDOR", "DISTANCES"]

CORRIDOR = 1.8               # metres: the vehicle's corridor (a car's width)
DISTANCES = (10, 20, 30)     # metres ahead where width_m is measured
UNSEEN = 255


def _corridor_cols(grid: BevGrid, corridor: float) -> np.ndarray:
    x = grid.x_min + (np.arange(grid.shape[1]) + 0.5) * grid.res
    cols = np.flatnonzero(np.abs(x) <= corridor / 2 + 1e-9)
    if cols.size == 0:
        cols = np.array([int(np.argmin(np.abs(x)))])
    return cols


def free_distance(bev: np.ndarray, grid: BevGrid, corridor: float = CORRIDOR, origin_z: float = 0.0) -> float | None:
    """``free_m`` (module docstring)."""
    c = bev[:, _corridor_cols(grid, corridor)][::-1]  # near row first
    blocked = (c == 0).any(axis=1)
    unknown = (c == UNSEEN).any(axis=1)
    start = np.flatnonzero(blocked | ~unknown)
    if start.size == 0:
        return None
    stops = np.flatnonzero((blocked | unknown)[start[0]:])
    rows = grid.shape[0]
    if stops.size == 0:
        return round(float(grid.z_max - origin_z), 6)
    near_first = start[0] + stops[0]
    return round(float(grid.z_max - rows * grid.res + near_first * grid.res - origin_z), 6)


def road_width(bev: np.ndarray, grid: BevGrid, distance: float, origin_z: float = 0.0) -> float | None:
    """The road's width ``distance`` metres ahead (``width_m``, module docstring)."""
    row = grid.row_at(origin_z + distance)
    if row is None:
        return None
    r = bev[row]
    if not (r != UNSEEN).any():
        return None
    road = np.flatnonzero(r == 1)
    if road.size == 0:
        return 0.0
    last = r.size - 1
    left, right = road - 1, road + 1
    clipped = (road == 0).any() or (road == last).any()
    clipped = clipped or (r[left[left >= 0]] == UNSEEN).any() or (r[right[right <= last]] == UNSEEN).any()
    return None if clipped else round(float(road.size * grid.res), 6)


def road_in_metres(bev: np.ndarray, grid: BevGrid, view: GroundView | None = None, corridor: float = CORRIDOR,
                   distances: tuple[float, ...] = DISTANCES) -> dict[str, Any]:
    """``{"free_m", "width_m": {"10", "20", "30"}, "area_m2", "pose"}`` of a BEV road mask
    (module docstring); ``pose`` is ``view``'s :meth:`~GroundView.pose_dict` (None without a view)."""
    if bev.shape != grid.shape:
        raise InputError(f"BEV mask is {bev.shape[1]}x{bev.shape[0]} cells but the grid is "
                         f"{grid.shape[1]}x{grid.shape[0]}", None, "map the mask onto the same grid")
    if not corridor > 0:
        raise InputError(f"corridor width {corridor:g} m", None, "give a corridor width > 0 m (a car's: 1.8)")
    oz = view.origin_z if view is not None else 0.0
    return {
        "free_m": free_distance(bev, grid, corridor, oz),
        "width_m": {f"{d:g}": road_width(bev, grid, d, oz) for d in distances},
        "area_m2": round(float(np.count_nonzero(bev == 1)) * grid.res ** 2, 4),
        "pose": view.pose_dict() if view is not None else None,
    }
