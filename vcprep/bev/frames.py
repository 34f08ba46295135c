"""Every frame's :class:`~vcprep.bev.view.GroundView` by the warp's rule (:func:`vcprep.vp.frame_poses`):
``within`` 'estimate' (each frame's pose from its road vanishing point, the default for one camera),
'none' (the camera's nominal pose; each frame's calibrated pose for per-frame calibration and
KITTI files, which refuse any other) or a CSV 'id,u,v' of known VPs."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..dataset import Job
from ..errors import InputError, VCError
from ..io.images import image_size
from ..vp.poses import frame_poses
from ..vp.reliability import VPRule
from .view import BevSource, GroundView

__all__ = ["frame_views", "within_rule"]


def within_rule(within: str | None, source: BevSource, spec: str | Path | None = None) -> str:
    """``--within`` or its default: 'estimate' for one camera, 'none' for calibrated frames (per-frame
    folders, KITTI files), which refuse any other (their pose is exact)."""
    if within is None:
        return "none" if source.calibrated else "estimate"
    if source.calibrated and within != "none":
        raise InputError("--within needs one camera; this calibration already gives every frame its exact pose",
                         spec, "drop --within, or give one camera file or preset")
    return within


def frame_views(jobs: list[Job], source: BevSource, within: str, rule: VPRule | None = None,
                on_image: Callable[[int], None] | None = None,
                on_error: Callable[[int, VCError], None] | None = None, roll: float = 0.0) -> dict[str, GroundView]:
    """job id -> its frame's view (:meth:`BevSource.view` at the pose ``within`` gives it, turned by
    ``roll`` degrees). A frame the VP detector cannot read is told to ``on_error`` (given) and has no view."""
    camera = source.camera if not source.calibrated else None
    poses = None
    if camera is not None and within != "none":
        poses, _ = frame_poses(jobs, camera, within, rule, on_image=on_image, on_error=on_error)
    views = {}
    for i, job in enumerate(jobs):
        if poses is not None and job.id not in poses:
            continue
        pose = poses.get(job.id) if poses is not None else None
        size = image_size(job.image)
        views[job.id] = source.view(job.image, size, pose.vp if pose else None, pose.status if pose else None, roll)
    return views
