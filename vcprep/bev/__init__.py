"""The road in metres: a bird's-eye view (BEV) of the road plane from any camera.

Modules, in the order the data flows: :mod:`.grid` (:class:`BevGrid`: the metric grid, far row
first), :mod:`.view` (:class:`GroundView`: one frame's road plane -> image mapping, from a camera
at its nominal pose or a frame's road-VP pose, or a KITTI ``Tr_cam_to_road`` exactly as the devkit;
:class:`BevSource`: a ``--camera``), :mod:`.maps` (:func:`bev_maps`, cached, and :func:`to_bev`:
one ``cv2.remap`` a frame), :mod:`.metres` (:func:`road_in_metres`: free distance, widths, area),
:mod:`.frames` (:func:`frame_views`: every frame's view by the warp's ``--within`` rule),
:mod:`.folder` (:func:`bev_folder`, :class:`BevSettings`: ``vcprep bev``'s file layer).

Numpy in, numpy out. A BEV label/mask keeps the store's values: 0 not road, 1 road, 255 unseen or
ignore. Use from another command (e.g. ``vctrain predict --bev``)::

    from vcprep.bev import BevGrid, BevSource, bev_maps, frame_views, road_in_metres, to_bev
    grid = BevGrid()                                   # KITTI's: x -10..10, z 6..46 m, 0.05 m
    source = BevSource.from_spec("camvid", jobs[0].image)
    views = frame_views(jobs, source, "estimate")      # id -> GroundView (each frame's VP pose)
    maps = bev_maps(views[job.id], grid, job.image)    # cached
    bev_mask = to_bev(mask01, maps, "label")           # (800, 400) uint8, far row first
    road = road_in_metres(bev_mask, grid, views[job.id])  # free_m, width_m, area_m2, pose
"""
from __future__ import annotations

from .folder import BevSettings, bev_folder, find_masks
from .frames import frame_views, within_rule
from .grid import KITTI_GRID, MAX_CELLS, BevGrid, parse_range
from .maps import KINDS, bev_maps, clear_cache, image_H_bev, to_bev
from .metres import CORRIDOR, DISTANCES, road_in_metres
from .view import BevSource, GroundView, camera_view, kitti_view

__all__ = ["BevSettings", "bev_folder", "find_masks", "frame_views", "within_rule", "KITTI_GRID", "MAX_CELLS",
           "BevGrid", "parse_range", "KINDS", "bev_maps",
           "clear_cache", "image_H_bev", "to_bev", "CORRIDOR", "DISTANCES", "road_in_metres", "BevSource",
           "GroundView", "camera_view", "kitti_view"]
