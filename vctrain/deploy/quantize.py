"""``vctrain export --int8``: the road graph with its network in 8 bits (onnxruntime static quantization).

Only the network's nodes are quantized (their names start with ``/model/``, the traced
:class:`~vctrain.deploy.export.RoadGraph`'s network): weights int8 per output channel, activations
uint8 with ranges calibrated (min-max) on real frames, in QDQ form, which onnxruntime runs as
integer convolutions. The warp, the resizes, the sigmoid and the back-projection stay in float, so a
pixel's P(road) moves only by what the network's rounding moves it.

Two of the network's nodes stay in float (:func:`float_nodes`): its first convolution (it reads the
normalised frame) and the decoder's finest lateral projection (``lateral.0``, the encoder's 1/4-scale
features into the pyramid). Measured on road-street (issue 82; int8 - float road IoU points, masks the
float graph's, on held-out frames): every node quantized, Cityscapes -2.64 (97.3 %), kitti_semantics
-3.06 (97.4 %), CamVid val -0.73 (98.7 %); ``lateral.0`` in float, Cityscapes +0.11 (99.3 %), CamVid
+0.12 (99.8 %), kitti_semantics -0.87; with the first convolution too, kitti_semantics +0.11 (99.3 %).
Other calibration (percentile, entropy, 37 frames of four training cameras) moved the loss by at most a
point; the head, the context branch or the last blocks in float, not at all.

Calibration frames: the user's (``--calib DIR``, up to :data:`CALIB_FRAMES` spread over the folder),
else the repository's examples (``examples/camvid/images``, ``examples/kitti/image_2``); a frame of
another size is resized to the graph's (calibration sees ranges of values, not geometry). The
agreement reported is the share of pixels whose mask (P >= 0.5) is the float graph's, over the
calibration frames; benchmarks/speed/predict_e2e.py measures it and the IoU on held-out frames.
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from vcprep.errors import InputError

from .runtime import _session, require

__all__ = ["CALIB_FRAMES", "calibration_frames", "float_nodes", "quantize_graph", "mask_agreement"]

CALIB_FRAMES = 32  # at most this many calibration frames (spread evenly over those given)
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
EXAMPLE_FOLDERS = ("camvid/images", "kitti/image_2")
NETWORK_PREFIX = "/model/"  # the traced network's node names (RoadGraph.model)
FINEST_LATERAL = NETWORK_PREFIX + "lateral.0/"  # the FPN decoder's 1/4-scale lateral (vctrain.networks.fpn)


def calibration_frames(calib: str | Path | None, size: tuple[int, int]) -> tuple[list[np.ndarray], str]:
    """(BGR uint8 frames at ``size`` (w, h), where they came from): up to :data:`CALIB_FRAMES` of
    ``calib`` (a folder or image files), else of the shipped examples."""
    import cv2

    from vcprep.dataset import collect_images
    from vcprep.io import read_image

    if calib is not None:
        files, source = [j.image for j in collect_images([Path(calib)], trees=True)], str(calib)
    else:
        folders = [EXAMPLES / f for f in EXAMPLE_FOLDERS if (EXAMPLES / f).is_dir()]
        if not folders:
            raise InputError("no calibration frames: the repository's examples are not here", None,
                             "give --calib DIR (frames of the camera)")
        files = [j.image for j in collect_images(folders)]
        source = "the examples (" + ", ".join(EXAMPLE_FOLDERS) + ")"
    picks = sorted({int(round(k)) for k in np.linspace(0, len(files) - 1, min(CALIB_FRAMES, len(files)))})
    frames = []
    for k in picks:
        img = read_image(files[k]).array
        if img.dtype != np.uint8 or img.ndim != 3:
            from vcprep.figures import to_bgr8

            img = to_bgr8(img)
        if (img.shape[1], img.shape[0]) != tuple(size):
            img = cv2.resize(img, tuple(size), interpolation=cv2.INTER_AREA)
        frames.append(img)
    return frames, source


def mask_agreement(float_graph, int8_graph, feeds: list[dict[str, np.ndarray]]) -> float:
    """The share of pixels whose mask (P >= 0.5) the two graphs (bytes or paths) agree on, over ``feeds``."""
    ort = require("onnxruntime")
    a, b = _session(ort, float_graph), _session(ort, int8_graph)
    same = total = 0
    for f in feeds:
        pa, pb = a.run(None, f)[0], b.run(None, f)[0]
        same += int(((pa >= 0.5) == (pb >= 0.5)).sum())
        total += pa.size
    return same / max(1, total)


def float_nodes(graph: Any) -> list[str]:
    """The network's nodes of ``graph`` (an ``onnx.GraphProto``) that int8 leaves in float: the first
    convolution and the finest lateral projection (the module docstring says why, with numbers)."""
    convs = [n.name for n in graph.node if n.name.startswith(NETWORK_PREFIX) and n.op_type == "Conv"]
    return convs[:1] + [n.name for n in graph.node if n.name.startswith(FINEST_LATERAL)]


def quantize_graph(model: Any, feeds: list[dict[str, np.ndarray]]) -> tuple[Any, float]:
    """(the int8 graph, its mask agreement with ``model``) of the float graph ``model`` (an
    ``onnx.ModelProto``), calibrated on ``feeds`` (the graph's inputs, one dict per frame)."""
    onnx = require("onnx")
    require("onnxruntime")
    from onnxruntime.quantization import (CalibrationDataReader, CalibrationMethod, QuantFormat, QuantType,
                                          quantize_static)
    from onnxruntime.quantization.shape_inference import quant_pre_process

    class Frames(CalibrationDataReader):
        def __init__(self):
            self.it = iter(feeds)

        def get_next(self):
            return next(self.it, None)

    with tempfile.TemporaryDirectory(prefix="vcseg-int8-") as tmp:
        src, pre, out = (str(Path(tmp) / n) for n in ("float.onnx", "pre.onnx", "int8.onnx"))
        onnx.save(model, src)
        quant_pre_process(src, pre, skip_symbolic_shape=True)  # shapes inferred, graph optimised for the quantizer
        graph = onnx.load(pre).graph
        keep = set(float_nodes(graph))
        nodes = [n.name for n in graph.node if n.name.startswith(NETWORK_PREFIX) and n.name not in keep]
        quantize_static(pre, out, Frames(), quant_format=QuantFormat.QDQ, per_channel=True,
                        activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8,
                        calibrate_method=CalibrationMethod.MinMax, nodes_to_quantize=nodes)
        agreement = mask_agreement(src, out, feeds)
        return onnx.load(out), agreement
