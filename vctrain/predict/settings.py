"""The settings of prediction, each declared once (no torch here: the commands' help texts take
their defaults from these names)."""
from __future__ import annotations

__all__ = ["BEYOND", "DEFAULT_BEYOND", "ENGINES", "DEFAULT_ENGINE", "GRAPH_ENGINE"]

# what a virtual-camera model predicts for frame pixels outside its training rectangle
# (vctrain.predict.frames' docstring; vctrain predict --beyond)
BEYOND = ("extend", "rays", "hybrid")
DEFAULT_BEYOND = "hybrid"

# what runs a .pt model's network (vctrain.deploy.engine.choose_engine; vctrain predict --engine)
ENGINES = ("auto", "torch", "onnx", "openvino")
DEFAULT_ENGINE = "torch"  # a .pt model's: the engine studies score, their masks bit for bit
GRAPH_ENGINE = "auto"     # an exported graph's: OpenVINO, else onnxruntime, where installed
