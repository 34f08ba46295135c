"""The road in metres from a bird's-eye-view road mask: :func:`road_in_metres`.

Input: a BEV label or mask on a :class:`~vcprep.bev.grid.BevGrid` (0 not road, 1 road, 255 unseen
or ignore; far row first). Distances are along the road plane from the camera's foot (the grid's
z minus the view's ``origin_z``: 0 for a camera, the road frame's offset for a KITTI calibration).
``hidden`` (given: a bool BEV array, :func:`vcprep.bev.border.hidden_cells`) marks cells that show
no road scene (the own vehicle, a label's border rows): they count as unseen, and say why the
corridor starts where it does.

- ``free_m``: how far ahead the corridor of the vehicle (``corridor`` metres wide, centred on
  x = 0: the cells whose centre lies within it, at least the one column nearest 0; along z, the
  road's direction under a VP pose, the camera's heading under a nominal or calibrated one) is
  road. From the nearest row the camera sees in full (a row partly unseen or hidden is not yet the
  corridor's start: the old rule, 'or the first with a not-road cell', let a hidden border's last
  row stop it), the corridor's not-road and unseen cells are grouped into 8-connected blobs (their extent inside the
  corridor); a blob smaller than ``MIN_BLOCK`` (0.5 m) both across and along the road (a lane arrow,
  noise) is passed over, any other (a barrier, the road's end, the view's end) stops the corridor,
  as does any blob at the grid's far row. With a view, a blob of not-road cells must reach
  ``MIN_BLOCK`` plus the road one pixel of the frame covers at its far end (:func:`pixel_footprint`,
  at most ``MAX_FOOTPRINT``): far ahead a hole of one pixel row spans more than 0.5 m of road on the
  grid whatever its size in the scene. ``free_m`` is the near edge of the nearest stopping blob;
  the grid's far edge when none stops it (``free_to_edge`` true); None where the camera sees no
  corridor cell. ``free_stop``: 'not road', 'unseen' or 'edge'.
- ``start_m``: where the corridor starts (the near edge of that first row); ``start_why``: None
  where it starts at the grid's first row and that row is road, else why not: the ``hidden`` reason
  (own vehicle, label border) where hidden cells lie before the start, else 'not road' (the first
  row holds not-road cells) or 'unseen' (the camera sees the corridor from ``start_m`` on).
- ``width_m``: {"10": w, "20": w, "30": w}: the width of the road the vehicle drives on, in the
  row that holds that distance. Holes in the road smaller than ``MIN_BLOCK`` both ways (a lane
  arrow or a speck left out: ``free_m``'s rule) count as road; of the row's runs of road this
  gives, those with a cell in the corridor (one, or two beside a car in it: the car is not
  counted), else, where the road has left the corridor, the nearest run on each side of the 2-D
  road region (4-connected) that holds the corridor's nearest road; 0.0 where that region has no
  road in the row. A kerb, a strip of grass or a lane line left out by the model (long gaps, however
  narrow) separates. None where the row lies outside the grid, is unseen, or a run taken reaches
  the grid's side or an unseen cell (not all in view). ``edges_m``: the left and right edge of the
  runs taken (x, metres); ``others_m``: the widths of the row's other runs of at least
  ``MIN_BLOCK`` (a pavement, the opposite carriageway beyond a gap), left to right.
- ``area_m2``: road cells times the cell area.
"""
from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from ..errors import InputError
from .grid import BevGrid
from .view import GroundView

__all__ = ["road_in_metres", "free_distance", "road_widths", "fill_small_holes", "pixel_footprint", "CORRIDOR",
           "DISTANCES", "MIN_BLOCK"]

CORRIDOR = 1.8               # metres: the vehicle's corridor (a car's width)
DISTANCES = (10, 20, 30)     # metres ahead where width_m is measured
MIN_BLOCK = 0.5              # metres: a blob or gap smaller than this both ways does not end the road
MAX_FOOTPRINT = 1.0          # metres: the most a frame's pixel may widen a blob's tolerance (pixel_footprint)
UNSEEN = 255
_EPS = 1e-9


def _corridor_cols(grid: BevGrid, corridor: float) -> np.ndarray:
    x = grid.x_min + (np.arange(grid.shape[1]) + 0.5) * grid.res
    cols = np.flatnonzero(np.abs(x) <= corridor / 2 + _EPS)
    if cols.size == 0:
        cols = np.array([int(np.argmin(np.abs(x)))])
    return cols


def _cells(metres: float, res: float) -> int:
    """The fewest whole cells that span at least ``metres``."""
    return max(1, int(np.ceil(metres / res - 1e-6)))


def pixel_footprint(view: GroundView | None, grid: BevGrid) -> tuple[np.ndarray, np.ndarray] | None:
    """Per grid row (far row first): the road length (along z) and width (along x) that one pixel of
    ``view``'s image covers at x = 0, in metres (at most :data:`MAX_FOOTPRINT`): how far a blob's
    size on the grid may stray from the size of what the frame shows. None without a view."""
    if view is None:
        return None
    H, z, eps = view.image_H_ground, grid.z_centres(), 1e-3

    def pixel(dx: float, dz: float) -> np.ndarray:
        p = H @ np.stack([np.full_like(z, dx), z + dz, np.ones_like(z)])
        with np.errstate(divide="ignore", invalid="ignore"):
            return p[:2] / p[2]

    at, along, across = pixel(0.0, 0.0), pixel(0.0, eps), pixel(eps, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        foot_z = eps / np.hypot(*(along - at))
        foot_x = eps / np.hypot(*(across - at))
    clean = lambda a: np.clip(np.nan_to_num(a, nan=MAX_FOOTPRINT, posinf=MAX_FOOTPRINT), 0.0, MAX_FOOTPRINT)
    return clean(foot_z), clean(foot_x)


def _large(stats: np.ndarray, far_rows: np.ndarray, res: float, min_block: float,
           footprint: tuple[np.ndarray, np.ndarray] | None, exact: np.ndarray) -> np.ndarray:
    """Which blobs (``stats`` of :func:`cv2.connectedComponentsWithStats`, background dropped) reach
    ``min_block`` along or across the road; a blob of not-road cells alone (``exact`` False) may be a
    pixel's footprint larger on the grid than in the frame, so it must reach ``min_block`` plus the
    footprint at its far row (grid row ``far_rows``) to count."""
    along, across = stats[:, cv2.CC_STAT_HEIGHT] * res, stats[:, cv2.CC_STAT_WIDTH] * res
    slack_z = slack_x = np.zeros(len(stats))
    if footprint is not None:
        slack_z = np.where(exact, 0.0, footprint[0][far_rows])
        slack_x = np.where(exact, 0.0, footprint[1][far_rows])
    return (along >= min_block + slack_z - 1e-6) | (across >= min_block + slack_x - 1e-6)


def free_distance(bev: np.ndarray, grid: BevGrid, corridor: float = CORRIDOR, origin_z: float = 0.0,
                  hidden: np.ndarray | None = None, min_block: float = MIN_BLOCK,
                  footprint: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, Any]:
    """``{"free_m", "free_to_edge", "free_stop", "start_m", "start_why"}`` (module docstring)."""
    cols = _corridor_cols(grid, corridor)
    c = bev[:, cols][::-1].copy()  # near row first
    hid = hidden[:, cols][::-1] if hidden is not None else np.zeros(c.shape, bool)
    c[hid] = UNSEEN
    rows = grid.shape[0]
    near_edge = grid.z_max - rows * grid.res - origin_z  # the grid's first row's near edge, from the camera
    start = np.flatnonzero(~(c == UNSEEN).any(axis=1))
    s = int(start[0]) if start.size else rows
    before = slice(0, max(s, 1))  # the rows before the start (the first row where the corridor starts there)
    why = None
    if not (s == 0 and (c[0] == 1).all()):
        why = "hidden" if hid[before].any() else "not road" if (c[before] == 0).any() else "unseen"
    out = {"free_m": None, "free_to_edge": False, "free_stop": None, "start_m": None, "start_why": why}
    if start.size == 0:
        return out
    out["start_m"] = round(float(near_edge + s * grid.res), 6)
    sub = c[s:]
    n, lab, stats, _ = cv2.connectedComponentsWithStats((sub != 1).astype(np.uint8), connectivity=8)
    top, hgt = stats[1:, cv2.CC_STAT_TOP], stats[1:, cv2.CC_STAT_HEIGHT]
    unseen = np.zeros(n, bool)
    unseen[np.unique(lab[sub == UNSEEN])] = True
    far_rows = rows - 1 - (s + top + hgt - 1)
    stops = _large(stats[1:], far_rows, grid.res, min_block, footprint, unseen[1:]) | (top + hgt >= sub.shape[0])
    if not stops.any():
        out.update(free_m=round(float(grid.z_max - origin_z), 6), free_to_edge=True, free_stop="edge")
        return out
    row = int(top[stops].min())
    blobs = np.flatnonzero(stops) + 1
    in_row = np.isin(lab[row], blobs)
    out["free_m"] = round(float(near_edge + (s + row) * grid.res), 6)
    out["free_stop"] = "not road" if (sub[row][in_row] == 0).any() else "unseen"
    return out


def fill_small_holes(road: np.ndarray, res: float, min_block: float = MIN_BLOCK,
                     footprint: tuple[np.ndarray, np.ndarray] | None = None,
                     unseen: np.ndarray | None = None) -> np.ndarray:
    """``road`` (bool, a grid's rows far first, cells ``res`` metres) with every 8-connected blob of
    other cells smaller than ``min_block`` both across and along the road (a lane arrow or a speck
    left out) filled: ``free_m``'s rule for what does not count (``footprint``, ``unseen``: as
    :func:`free_distance` takes them). A long thin gap (a kerb, a lane line left out) stays."""
    n, lab, stats, _ = cv2.connectedComponentsWithStats((~road).astype(np.uint8), connectivity=8)
    exact = np.zeros(n, bool)
    if unseen is not None:
        exact[np.unique(lab[unseen])] = True
    small = np.flatnonzero(~_large(stats[1:], stats[1:, cv2.CC_STAT_TOP], res, min_block, footprint, exact[1:])) + 1
    return road | np.isin(lab, small) if small.size else road


def _runs(row: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) column of each run of True in ``row``, left to right."""
    d = np.diff(np.concatenate([[0], row.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), (np.flatnonzero(d == -1) - 1).tolist()))


def _vehicle_region(road: np.ndarray, cols: np.ndarray) -> np.ndarray | None:
    """The 4-connected region of ``road`` (far row first) that holds the corridor's nearest road."""
    near = np.flatnonzero(road[:, cols].any(axis=1))
    if near.size == 0:
        return None
    _, lab = cv2.connectedComponents(road.astype(np.uint8), connectivity=4)
    ids, counts = np.unique(lab[near[-1], cols][lab[near[-1], cols] > 0], return_counts=True)
    return lab == ids[np.argmax(counts)]


def _pick_runs(runs: list[tuple[int, int]], cols: np.ndarray, region_row: np.ndarray | None) -> list[int]:
    """The runs under the corridor (every run with a cell in it: a car in the corridor splits the
    road, the road beside it is still the vehicle's), else the region's nearest run on each side."""
    lo, hi = int(cols[0]), int(cols[-1])
    under = [i for i, (a, b) in enumerate(runs) if a <= hi and b >= lo]
    if under or region_row is None:
        return under
    mine = [i for i, (a, b) in enumerate(runs) if region_row[a:b + 1].any()]
    left = [i for i in mine if runs[i][1] < lo]
    right = [i for i in mine if runs[i][0] > hi]
    return ([left[-1]] if left else []) + ([right[0]] if right else [])


def road_widths(bev: np.ndarray, grid: BevGrid, distances: tuple[float, ...] = DISTANCES, origin_z: float = 0.0,
                corridor: float = CORRIDOR, hidden: np.ndarray | None = None, min_block: float = MIN_BLOCK,
                footprint: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, dict[str, Any]]:
    """``{"width_m", "edges_m", "others_m"}``, each keyed by distance (module docstring)."""
    b = bev if hidden is None else np.where(hidden, UNSEEN, bev)
    cols = _corridor_cols(grid, corridor)
    k = _cells(min_block, grid.res)
    filled = fill_small_holes(b == 1, grid.res, min_block, footprint, b == UNSEEN)
    region = _vehicle_region(filled, cols)
    width, edges, others = {}, {}, {}
    for d in distances:
        key, row = f"{d:g}", grid.row_at(origin_z + d)
        width[key], edges[key], others[key] = None, None, None
        if row is None or not (b[row] != UNSEEN).any():
            continue
        runs = _runs(filled[row])
        picked = _pick_runs(runs, cols, region[row] if region is not None else None)
        others[key] = [round((z - a + 1) * grid.res, 6) for i, (a, z) in enumerate(runs)
                       if i not in picked and z - a + 1 >= k]
        if not picked:
            width[key] = 0.0
            continue
        spans = [runs[i] for i in picked]
        last = b.shape[1] - 1
        if any(a == 0 or z == last or b[row, a - 1] == UNSEEN or b[row, z + 1] == UNSEEN for a, z in spans):
            continue  # not all of it in view
        width[key] = round(float(sum(z - a + 1 for a, z in spans) * grid.res), 6)
        edges[key] = [round(float(grid.x_min + spans[0][0] * grid.res), 6),
                      round(float(grid.x_min + (spans[-1][1] + 1) * grid.res), 6)]
    return {"width_m": width, "edges_m": edges, "others_m": others}


def road_in_metres(bev: np.ndarray, grid: BevGrid, view: GroundView | None = None, corridor: float = CORRIDOR,
                   distances: tuple[float, ...] = DISTANCES, hidden: np.ndarray | None = None,
                   hidden_why: str | None = None) -> dict[str, Any]:
    """``{"free_m", "free_to_edge", "free_stop", "start_m", "start_why", "width_m", "edges_m",
    "others_m", "area_m2", "pose"}`` of a BEV road mask (module docstring); ``pose`` is ``view``'s
    :meth:`~GroundView.pose_dict` (None without a view); ``hidden_why`` names the ``hidden`` cells."""
    if bev.shape != grid.shape:
        raise InputError(f"BEV mask is {bev.shape[1]}x{bev.shape[0]} cells but the grid is "
                         f"{grid.shape[1]}x{grid.shape[0]}", None, "map the mask onto the same grid")
    if not corridor > 0:
        raise InputError(f"corridor width {corridor:g} m", None, "give a corridor width > 0 m (a car's: 1.8)")
    if hidden is not None and not hidden.any():
        hidden = None
    oz = view.origin_z if view is not None else 0.0
    foot = pixel_footprint(view, grid)
    free = free_distance(bev, grid, corridor, oz, hidden, footprint=foot)
    if free["start_why"] == "hidden":
        free["start_why"] = hidden_why or "hidden"
    widths = road_widths(bev, grid, distances, oz, corridor, hidden, footprint=foot)
    return {
        "free_m": free["free_m"],
        "width_m": widths["width_m"],
        "area_m2": round(float(np.count_nonzero(bev == 1)) * grid.res ** 2, 4),
        "pose": view.pose_dict() if view is not None else None,
        **{k: free[k] for k in ("free_to_edge", "free_stop", "start_m", "start_why")},
        "edges_m": widths["edges_m"],
        "others_m": widths["others_m"],
    }
