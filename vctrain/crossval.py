"""``vctrain crossval``'s library, kept under its old name for importers: the study now lives in
the package :mod:`vctrain.study` (spec, resolution, stores, keys, runs, conditions, execution)."""
from __future__ import annotations

from .study import evaluate_heldout, plan_runs, run_study, score_store, training_settings

__all__ = ["plan_runs", "training_settings", "run_study", "evaluate_heldout", "score_store"]
