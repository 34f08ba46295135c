"""Simulating another camera exactly (a re-mounted, re-zoomed, re-cropped camera at the same place).

Modules: :mod:`.geometry` (rotation, zoom, coverage), :mod:`.plan` (:func:`plan_simulation`: every
image's H, VP and pose, nothing written), :mod:`.writer` (:func:`simulate_dataset`: reads, warps,
writes atomically).
"""
from __future__ import annotations

from .geometry import covered, draw_offsets, relative_rotation
from .plan import SimulateParams, plan_simulation
from .writer import recorded_homographies, simulate_arrays, simulate_dataset

__all__ = ["covered", "draw_offsets", "relative_rotation", "SimulateParams", "plan_simulation",
           "recorded_homographies", "simulate_arrays", "simulate_dataset"]
