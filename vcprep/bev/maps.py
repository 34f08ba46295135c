"""A frame onto the bird's-eye-view grid with one ``cv2.remap``: :func:`bev_maps` (the cached
inverse maps of a :class:`~vcprep.bev.view.GroundView` and a :class:`~vcprep.bev.grid.BevGrid`)
and :func:`to_bev`.

Convention (the warp's, :mod:`vcprep.warp.remap`): every grid cell's centre (x, z) on the road is
projected into the image; the cell is *seen* where that pixel lies inside the image's outer pixel
edges and in front of the camera (cells behind it, beyond the horizon or outside the frame are
unseen and never guessed). Labels and masks are sampled by nearest neighbour and keep the store's
values (0 not road, 1 road, 255 ignore), unseen cells 255; images and probabilities are sampled
bilinearly, unseen cells 0 (``maps.valid`` tells them apart).

A KITTI view (``devkit``) samples exactly as the devkit's ``BirdsEyeView.compute``: the cell centres
(``numpy.arange`` from the grid's edges, as float32) through ``image_H_ground``, a cell seen where
1 <= u <= w and 1 <= v <= h, and pixel (floor(v) - 1, floor(u) - 1) taken whatever the kind (integer
maps: nearest and bilinear sampling agree). One deviation: a cell behind the camera (never in the
benchmark's grid) is unseen here, where the devkit would sample its mirror image.
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np

from ..errors import InputError
from ..warp.remap import RemapMaps, build_maps, maps_from_coordinates
from .grid import BevGrid
from .view import GroundView

__all__ = ["bev_maps", "to_bev", "clear_cache", "image_H_bev", "KINDS"]

KINDS = ("image", "prob", "label")  # what to_bev samples: bilinear (image, prob) or nearest (label, mask)

_CACHE: "OrderedDict[tuple, RemapMaps]" = OrderedDict()
_CACHE_MAX = 16


def image_H_bev(view: GroundView, grid: BevGrid) -> np.ndarray:
    """3x3: BEV cell (col j, row i, 1) -> image pixel (u, v, 1): ``image_H_ground`` after the
    affine map of a cell index to its centre, x = x_min + (j + 1/2) res, z = z_max - (i + 1/2) res."""
    r = grid.res
    ground_A_bev = np.array([[r, 0.0, grid.x_min + r / 2], [0.0, -r, grid.z_max - r / 2], [0.0, 0.0, 1.0]])
    return view.image_H_ground @ ground_A_bev


def _devkit_maps(view: GroundView, grid: BevGrid) -> RemapMaps:
    """The devkit's lookup table as integer remap maps (module docstring)."""
    X, Z = np.meshgrid(grid.x_centres().astype(np.float32), grid.z_centres().astype(np.float32))
    pts = np.vstack([X.ravel(), Z.ravel(), np.ones(X.size, dtype=np.float32)])
    p = view.image_H_ground @ pts
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = p[0] / p[2], p[1] / p[2]
    w, h = view.size
    valid = (p[2] > 0) & (u >= 1) & (v >= 1) & (u <= w) & (v <= h)
    u = np.where(valid, np.floor(np.where(valid, u, 1.0)) - 1, 0.0).reshape(grid.shape)
    v = np.where(valid, np.floor(np.where(valid, v, 1.0)) - 1, 0.0).reshape(grid.shape)
    return maps_from_coordinates(u, v, valid.reshape(grid.shape), view.size)


def bev_maps(view: GroundView, grid: BevGrid, what: str | None = None) -> RemapMaps:
    """The remap maps from ``view``'s image onto ``grid`` (``valid``: the seen cells), cached by
    the exact view and grid (the last 16: one camera at its nominal pose builds them once). A
    grid the camera sees no cell of raises :class:`InputError` naming ``what`` (the frame)."""
    key = (view.H, view.size, view.devkit, grid)
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        return hit
    if view.devkit:
        maps = _devkit_maps(view, grid)
    else:
        rows, cols = grid.shape
        maps = build_maps(np.linalg.inv(image_H_bev(view, grid)), view.size, (cols, rows), oriented=True)
    if not maps.valid.any():
        raise InputError(f"the camera sees no cell of the grid x {grid.x_min:g}..{grid.x_max:g} m, z "
                         f"{grid.z_min:g}..{grid.z_max:g} m (behind it, beyond its horizon or outside its frame)",
                         what, "give a --range ahead of the camera and within its view (z forward, x right, metres)")
    _CACHE[key] = maps
    if len(_CACHE) > _CACHE_MAX:
        _CACHE.popitem(last=False)
    return maps


def clear_cache() -> None:
    """Forget the maps :func:`bev_maps` keeps (a benchmark's cold start)."""
    _CACHE.clear()


def to_bev(array: np.ndarray, maps: RemapMaps, kind: str = "image") -> np.ndarray:
    """``array`` (h, w[, c]) onto the grid of ``maps``, (rows, cols[, c]), far row first: 'label'
    (labels, masks; nearest, unseen 255), 'image' or 'prob' (bilinear, unseen 0)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    if kind == "label":
        return maps.remap_label(array, 255)
    return maps.remap_image(array)
