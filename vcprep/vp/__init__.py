"""Road vanishing points (paper section 4.2): one image's VP, and the rules over a dataset.

Modules: :mod:`.segments` (LSD segments, sub-pixel re-fit), :mod:`.estimate` (:class:`VPConfig`,
:class:`VPResult`, the vote: :func:`estimate_vp`), :mod:`.reliability` (the reliability rule,
per-sequence smoothing, VP files), :mod:`.cache` (the detector's VPs kept on disk for a rerun),
:mod:`.poses` (each frame's pose from its VP or calibration:
:func:`frame_poses`, the one rule of the store, prediction and studies).
"""
from __future__ import annotations

from .cache import VP_CACHE, VPCache
from .estimate import VPConfig, VPResult, estimate_vp, is_reliable, score_vps
from .reliability import (VPRule, apply_reliability, estimate_arrays, estimate_files, format_vp_csv, read_vp_csv, sequence_key, smooth_sequences,
                          vps_for_items, write_vp_csv)
from .poses import ItemPose, array_poses, frame_poses
from .segments import detect_segments, prior_window, refine_segments, to_gray

__all__ = ["VPCache", "VP_CACHE", "ItemPose", "frame_poses", "array_poses", "estimate_arrays", "VPRule", "VPConfig", "VPResult", "estimate_vp", "is_reliable", "score_vps", "apply_reliability", "estimate_files",
           "format_vp_csv", "read_vp_csv", "sequence_key", "smooth_sequences", "vps_for_items", "write_vp_csv",
           "detect_segments", "prior_window", "refine_segments", "to_gray"]
