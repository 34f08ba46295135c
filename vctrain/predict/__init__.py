"""Prediction: a trained network on new frames, in the source camera's pixels.

Modules: :mod:`.frames` (:class:`FramePredictor`: one frame in memory - warp, network,
back-projection), :mod:`.road` (the one road for a frame: image files and folders through a model,
the prior or a graph, with one set of rules for VPs, the rectangle and bad frames; writing masks),
:mod:`.video` (a video's frames on the same road, streamed), :mod:`.predictor` (:class:`Predictor`:
a checkpoint on one image; the store path for stores that exist), :mod:`.inputs` (what ``vctrain
predict`` was given, routed), :mod:`.model` (:func:`load`, :class:`RoadModel`: the Python face,
docs/api.md).
"""
from __future__ import annotations

from .frames import FramePredictor, StageTimes, StreamingVPs
from .inputs import predict_inputs
from .model import RoadModel, Segmentation, check_frame, load
from .predictor import Predictor, predict_frames, predict_images, warp_like_training
from .road import run_road
from .video import ego_camera, predict_video
from .written import write_prediction

__all__ = ["FramePredictor", "StageTimes", "StreamingVPs", "predict_inputs", "Predictor", "predict_images",
           "predict_frames", "run_road", "warp_like_training", "write_prediction", "ego_camera", "predict_video",
           "load", "RoadModel", "Segmentation", "check_frame"]
