"""Each frame's pose from its road vanishing point or its calibration: :class:`ItemPose` and
:func:`frame_poses`, the one rule of ``vcprep warp`` (the store), ``vctrain predict`` (frames, videos,
graphs) and a study's stores.

Convention: a pose's ``vp`` is [u, v] in source pixels of the image as stored on disk (pixel-centre
origin); the pan and tilt it implies are :func:`vcprep.warp.homography.pose_from_vp`'s.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping

from ..camera.pinhole import Camera
from ..camera.sources import FrameCameras
from ..dataset import Job
from ..errors import InputError, VCError
from .reliability import VPRule, estimate_arrays, vps_for_items

__all__ = ["ItemPose", "frame_poses", "array_poses"]


@dataclass(frozen=True)
class ItemPose:
    """A per-image pose from its road vanishing point (within-camera correction).

    ``vp`` is [u, v] in source pixels of the image as stored on disk; ``status`` is
    'accepted', 'fallback' or 'given' (see the vanishing-point module); ``rule``: the
    :class:`~vcprep.vp.VPRule` an estimated VP was found with (its ``to_dict``,
    recorded as the item's ``vp_rule``), None for a given one."""

    vp: tuple[float, float]
    status: str
    rule: Mapping[str, Any] | None = None


def frame_poses(jobs: list[Job], camera: Camera | FrameCameras, within: str, rule: Any = None,
                id_prefix: str = "", on_image: Callable[[int], None] | None = None,
                on_error: Callable[[int, VCError], None] | None = None, cache: Any = None
                ) -> tuple[dict[str, ItemPose] | None, list[Any]]:
    """(``poses`` of :class:`vcprep.store.WarpSettings`, the VP results) of ``jobs`` taken together: ``within``
    'none' (None: the camera's average pose, or each frame's calibrated one), 'estimate' (each
    frame's road VP found by ``rule``, a :class:`~vcprep.vp.VPRule`: None, the
    detector's defaults; frames grouped into sequences by its ``frame_ids``, not by item ids;
    recorded with each pose) or a CSV ``id,u,v`` of given VPs (looked up by item id). The one rule
    of ``vcprep warp``, ``vctrain predict`` and a study's stores. ``on_error(i, error)`` (given): a
    frame that cannot be read is told to it and has no pose (estimation only). ``cache`` (a
    :class:`vcprep.vp.cache.VPCache`, given): the detector's results found there are not computed
    again, and those computed are kept there."""
    if within == "none":
        return None, []
    rule = rule or VPRule()
    images = [j.image for j in jobs]
    # estimated VPs: grouped into sequences by the rule (the same frames, the same groups, whatever their ids)
    ids = rule.frame_ids(images) if within == "estimate" else [j.id for j in jobs]
    results = vps_for_items(images, ids, camera, within, rule.smooth, rule.config(), id_prefix, on_image, on_error,
                            cache)
    tag = rule.to_dict() if within == "estimate" else None
    return {j.id: ItemPose((r.vp[0], r.vp[1]), r.status, tag) for j, r in zip(jobs, results) if r is not None}, results


def array_poses(frames: list[Any], camera: Camera, within: str, rule: Any = None,
                ids: list[str] | None = None) -> dict[str, ItemPose]:
    """:func:`frame_poses` of decoded frames (numpy arrays, one camera), keyed by ``ids`` (default
    ``frame_000000``, ...: one sequence, in order): {} for ``within`` 'none', each frame's road VP by
    ``rule`` for 'estimate' (:func:`vcprep.vp.reliability.estimate_arrays`: the numbers of the
    frames' files). Given VPs have no file here: the caller passes them itself."""
    if within == "none":
        return {}
    if within != "estimate":
        raise InputError(f"within '{within}' is a table of VPs by file id; frames in memory have no file", within,
                         "give within='estimate' or 'none', or each frame's VP (u, v) yourself")
    rule = rule or VPRule()
    ids = list(ids) if ids is not None else [f"frame_{i:06d}" for i in range(len(frames))]
    results = estimate_arrays(frames, camera, rule.config(), rule.smooth, ids)
    tag = rule.to_dict()
    return {i: ItemPose((r.vp[0], r.vp[1]), r.status, tag) for i, r in zip(ids, results)}
