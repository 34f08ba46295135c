"""Cross-camera study (``vctrain crossval``): leave one dataset out (paper Tables 4 and 7), and
test-only datasets ("will my model work on camera X?").

A study names datasets, each taken with its own camera, and the conditions to compare; for every
condition each dataset of role ``both`` is held out in turn, and with datasets of role ``test`` one
more model is trained on all trainable datasets and tested on each of them. One module per job:

=============  =====================================================================================
spec           the study file: its schema, checked as it is read (:func:`load_study`), the conditions
resolve        what its files resolve to: items, cameras (given, per-frame, estimated), own vehicle,
               the virtual camera of each store and the scale (:class:`Resolution`)
stores         the stores each run needs, each built once, and their VPs (:class:`Stores`)
keys           what finished work depends on, as short hashes (one helper: :func:`settings_sha`)
runs           the run plan (:func:`plan_runs`) and the result files of finished work
conditions     how each kind of condition comes by its predictor: trained, the prior, adapted
execute        one executor over the condition kinds, the scoring, and :func:`run_study`
=============  =====================================================================================

The tables are written by :mod:`vctrain.report`.
"""
from __future__ import annotations

from .conditions import training_settings
from .execute import evaluate_heldout, run_study, score_store, scored_items
from .hashing import settings_sha
from .resolve import Resolution
from .runs import plan_runs
from .spec import (ADAPT_COMBINE, CANVASES, CONDITIONS, DEFAULT_ABOVE, DEFAULT_CANVAS, DEFAULT_CONDITIONS,
                   DEFAULT_STORE_PIXELS, DEFAULT_TRAIN, GEOMETRIES, ROLES, RUN_KEYS, TRAIN_KEYS, Dataset, Split, Study,
                   camera_spec, check_conditions, evaluated_datasets, load_study)

__all__ = ["CONDITIONS", "DEFAULT_CONDITIONS", "DEFAULT_STORE_PIXELS", "DEFAULT_ABOVE", "DEFAULT_TRAIN", "CANVASES",
           "DEFAULT_CANVAS", "GEOMETRIES", "ROLES", "ADAPT_COMBINE", "RUN_KEYS", "TRAIN_KEYS", "Split", "Dataset",
           "Study", "load_study", "camera_spec", "check_conditions", "evaluated_datasets", "Resolution", "plan_runs",
           "training_settings", "run_study", "evaluate_heldout", "score_store", "scored_items", "settings_sha"]
