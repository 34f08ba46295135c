"""Deployment: the ONNX graph with the camera inside, and running it.

Modules: :mod:`.graph_ops` (the torch ops of the graph: OpenCV's sampling, the in-graph warp),
:mod:`.export` (:func:`export_onnx`), :mod:`.runtime` (:class:`OnnxPredictor`).
"""
from __future__ import annotations

from .export import POSE_RANGE, RoadGraph, export_onnx, trace_onnx
from .runtime import OnnxPredictor

__all__ = ["POSE_RANGE", "RoadGraph", "export_onnx", "trace_onnx", "OnnxPredictor"]
