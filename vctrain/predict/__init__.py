"""Prediction: a trained network on new frames, in the source camera's pixels.

Modules: :mod:`.frames` (:class:`FramePredictor`: one frame in memory - warp, network,
back-projection), :mod:`.road` (the one road for a frame: image files and folders through a model,
the prior or a graph, with one set of rules for VPs, the rectangle and bad frames; writing masks),
:mod:`.video` (a video's frames on the same road, streamed), :mod:`.predictor` (:class:`Predictor`:
a checkpoint on one image; the store path for stores that exist), :mod:`.inputs` (what ``vctrain
predict`` was given, routed), :mod:`.model` (:func:`load`, :class:`RoadModel`: the Python face,
docs/api.md), :mod:`.settings` (the settings declared once: ``--beyond``, ``--engine``), :mod:`.kinds`
(:class:`RoadPredictor`: what a predictor offers the road).
"""
from __future__ import annotations

from ..lazy import lazy_face

# Each name's module. The face loads a module on first use of one of its names (PEP 562), as
# vctrain.training's does: the commands take their help texts' defaults from settings.py (no torch).
_HOME = {
    "settings": ("BEYOND", "DEFAULT_BEYOND", "ENGINES", "DEFAULT_ENGINE", "GRAPH_ENGINE", "STUDY_ENGINE",
                 "STUDY_IOU_TOLERANCE"),
    "kinds": ("RoadPredictor",),
    "frames": ("FramePredictor", "StageTimes", "StreamingVPs"),
    "inputs": ("PredictOptions", "predict_inputs"),
    "model": ("load", "RoadModel", "Segmentation", "check_frame"),
    "predictor": ("Predictor", "predict_frames", "predict_images", "warp_like_training"),
    "road": ("run_road",),
    "video": ("ego_camera", "predict_video"),
    "written": ("write_prediction",),
}
__all__, __getattr__, __dir__ = lazy_face(__name__, _HOME, globals())
