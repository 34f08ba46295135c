"""The settings of prediction, each declared once (no torch here: the commands' help texts take
their defaults from these names)."""
from __future__ import annotations

__all__ = ["BEYOND", "DEFAULT_BEYOND", "ENGINES", "DEFAULT_ENGINE", "GRAPH_ENGINE", "STUDY_ENGINE",
           "STUDY_IOU_TOLERANCE"]

# what a virtual-camera model predicts for frame pixels outside its training rectangle
# (vctrain.predict.frames' docstring; vctrain predict --beyond)
BEYOND = ("extend", "rays", "hybrid")
DEFAULT_BEYOND = "hybrid"

# what runs a .pt model's network (vctrain.deploy.engine.choose_engine; vctrain predict --engine)
ENGINES = ("auto", "torch", "onnx", "openvino")
# a .pt model's in vctrain predict and vctrain.load: the fastest installed (OpenVINO, else onnxruntime,
# on the CPU; PyTorch on a GPU or where neither is installed)
DEFAULT_ENGINE = "auto"
GRAPH_ENGINE = "auto"     # an exported graph's: OpenVINO, else onnxruntime, where installed
# what studies (vctrain crossval, fit's held-out scores) score with: PyTorch on every install and
# device, so a study's number does not depend on which runtime is installed; vctrain predict
# --engine torch gives its masks bit for bit, the default engine its road IoU within this much on
# every split (tests/test_study_predict.py)
STUDY_ENGINE = "torch"
STUDY_IOU_TOLERANCE = 0.002
