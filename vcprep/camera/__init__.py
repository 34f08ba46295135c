"""Cameras: the pinhole model, where a ``--camera`` comes from, cameras estimated from their own
frames, the virtual camera's design and the own vehicle.

Modules, in the order the data flows: :mod:`.pinhole` (:class:`Camera`, the presets,
:func:`scale_matrix`), :mod:`.files` (camera YAML, KITTI and Cityscapes calibration files),
:mod:`.sources` (preset, file or per-frame folder: :func:`load_cameras`), :mod:`.estimate` (a camera
from its own frames), :mod:`.ego` (the own vehicle's rows), :mod:`.virtual` (designing the virtual
camera and its rectangle).
"""
from __future__ import annotations

from .ego import (EgoEstimate, GROUP_MIN_DISTINCT, MIN_DISTINCT, SourceEgo, ego_rows_from_frame_files,
                  ego_rows_from_frames, ego_rows_from_label_files, ego_rows_from_labels, ego_rows_per_source,
                  rows_at_height, source_groups, spread)
from .estimate import (ASSUMED_HEIGHT, ASSUMED_HFOV, ROAD_WIDTH, estimate_camera, estimate_to_yaml, estimated_line, exif_focal_35mm,
                       road_widths, whole_frame_vp_config)
from .files import (camera_from_dict, camera_to_yaml, read_camera_yaml, read_cityscapes_camera, read_kitti_calib,
                    read_kitti_entries)
from .pinhole import Camera, PRESETS, scale_matrix
from .sources import FrameCameras, PRESET_PREFIX, camera_of_image, load_camera, load_cameras, preset_name
from .spec import camera_from_spec
from .virtual import (DESIGN_ABOVE, DESIGN_PAN_RANGE, DESIGN_TILT_RANGE, EXTENTS, STORE_PIXELS, design_virtual_camera,
                      extend_canvas, same_camera_other_canvas, scale_for_pixels)

__all__ = ["EgoEstimate", "GROUP_MIN_DISTINCT", "MIN_DISTINCT", "SourceEgo", "ego_rows_from_frame_files",
           "ego_rows_from_frames", "ego_rows_from_label_files", "ego_rows_from_labels", "ego_rows_per_source",
           "rows_at_height", "source_groups", "spread", "ASSUMED_HEIGHT", "ASSUMED_HFOV",
           "ROAD_WIDTH", "estimate_camera", "estimate_to_yaml", "estimated_line", "exif_focal_35mm", "road_widths",
           "whole_frame_vp_config", "camera_from_dict", "camera_to_yaml", "read_camera_yaml", "read_cityscapes_camera",
           "read_kitti_calib", "read_kitti_entries", "Camera", "PRESETS", "scale_matrix", "FrameCameras", "PRESET_PREFIX", "camera_from_spec", "camera_of_image",
           "load_camera", "load_cameras", "preset_name", "EXTENTS", "design_virtual_camera", "extend_canvas",
           "same_camera_other_canvas", "DESIGN_ABOVE", "DESIGN_PAN_RANGE", "DESIGN_TILT_RANGE", "STORE_PIXELS",
           "scale_for_pixels"]
