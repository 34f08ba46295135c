"""The warp between a camera and the virtual camera: the ground-plane homography, the remap,
projective completion around the vanishing point, and the way back.

Modules, in the order the data flows: :mod:`.homography` (``virt_H_src``, poses and VPs),
:mod:`.completion_rays` (where rays leave the source) + :mod:`.completion_tables` (the fill table)
+ :mod:`.completion` (:class:`CompletionMaps`, :func:`completion_maps`), :mod:`.remap` (one
``cv2.remap`` per image), :mod:`.backproject` (virtual-domain masks back to the source camera),
:mod:`.frame` (one frame into the virtual camera and back, in memory: :func:`warp_frame`).
"""
from __future__ import annotations

from .backproject import backproject_array, backproject_folder, backproject_rays, ray_clamped
from .completion import (COMPLETION_VERSION, CompletionMaps, METHODS, border_ignore, check_method, complete_maps,
                         completion_maps, store_vp)
from .completion_rays import LABEL_RIM, exit_points_rectangle, label_exit_points
from .completion_tables import TABLE_ARC, TABLE_COLS
from .frame import WarpedFrame, frame_pose, warp_at_pose, warp_frame
from .homography import (apply_homography, check_not_folded, ground_to_image, pose_axes, pose_from_vp,
                         road_magnification, virt_H_src, virtual_at_scale, vp_from_pose)
from .remap import (OUTSIDE, RemapMaps, build_maps, maps_for, maps_from_coordinates, source_coordinates, warp_image,
                    warp_label)

__all__ = ["backproject_array", "backproject_rays", "ray_clamped", "backproject_folder", "COMPLETION_VERSION", "CompletionMaps", "METHODS",
           "border_ignore", "check_method", "complete_maps", "completion_maps", "store_vp", "LABEL_RIM",
           "exit_points_rectangle", "label_exit_points", "TABLE_ARC", "TABLE_COLS", "apply_homography",
           "check_not_folded", "ground_to_image", "pose_axes", "pose_from_vp", "road_magnification", "virt_H_src", "virtual_at_scale",
           "vp_from_pose", "OUTSIDE", "RemapMaps", "build_maps", "maps_for", "maps_from_coordinates", "source_coordinates", "warp_image", "warp_label",
           "WarpedFrame", "warp_frame", "frame_pose", "warp_at_pose"]
