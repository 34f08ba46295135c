"""Which engine runs a checkpoint's network in ``vctrain predict`` (``--engine``): PyTorch, or the
same network exported in memory to ONNX and run in onnxruntime (``onnx``) or OpenVINO (``openvino``).

``auto``, the default of ``vctrain predict`` and :func:`vctrain.load`
(:data:`vctrain.predict.settings.DEFAULT_ENGINE`), takes OpenVINO, else onnxruntime, where installed
(the ``deploy`` extra) and the model runs on the CPU: the same network is faster there than
PyTorch's (the shipped lite0fpn at 480x360, two threads, a quiet machine: OpenVINO 13.5 ms,
onnxruntime 23.0, PyTorch 38.3; the README's video command on a 1280x720 video with overlay 36.3,
29.1 and 17.9 frames/s: benchmarks/speed/predict_e2e.py; on a loaded machine PyTorch's OpenMP
threads wait at every operator and the gap grows). On a GPU ``auto`` is PyTorch; on a CPU without
either runtime it is PyTorch too, and :func:`engine_note` says why (once, in predict's start-up
line, said with its summary). Its P(road) differs from PyTorch's by float rounding only (max |dP| ~3e-6): the masks are
identical on the examples (tests/test_pipeline.py), but a pixel at P = 0.5 can flip. Studies score
with PyTorch (:data:`vctrain.predict.settings.STUDY_ENGINE`): ``--engine torch`` gives a study's
masks bit for bit, the default a study's road IoU within
:data:`~vctrain.predict.settings.STUDY_IOU_TOLERANCE` (tests/test_study_predict.py).

:class:`OnnxNetwork` exports the network (BN folded, what :class:`vctrain.predict.Predictor` holds)
once per input shape (the EfficientNet encoders pad by the input size, so a graph is traced for
one size) and runs it with the threads ``vctrain predict --threads`` set. The traced graph is kept
for the process per checkpoint file content and input shape (:func:`traced_network`): a second
:func:`vctrain.load` or ``vctrain predict`` in one process compiles it again (the threads may
differ) but does not trace it again.
"""
from __future__ import annotations

import contextlib
import io
import time
import warnings
from collections import OrderedDict
from typing import Callable

import numpy as np
import torch
from torch import nn

from vcprep.errors import InputError

from ..predict.settings import ENGINES  # noqa: F401 (declared once there; importable from here)
from .runtime import DEPLOY_FIX, compiled, installed, require, runtime_name

__all__ = ["ENGINES", "OPSET", "OnnxNetwork", "choose_engine", "engine_name", "engine_note", "trace_onnx",
           "traced_network"]

RUNTIME = {"onnx": "onnxruntime", "openvino": "openvino"}  # an exported engine -> the runtime it runs in
OPSET = 17  # the ONNX opset of every graph vcseg writes
TRACED_KEPT = 4  # traced networks kept for the process (traced_network), the least recently used dropped
_TRACED: OrderedDict[tuple, bytes] = OrderedDict()


@contextlib.contextmanager
def _float64_scalars():
    """The TorchScript exporter types arithmetic among 0-d tensors (``H[0, 0] * vp[0]``) as the
    default dtype: float32 would cast the graph's float64 homography and completion centre to
    float32 (~3e-8 relative: a centre one float32 step off, fixed-point maps rounding the other
    way). Exporting with float64 as the default keeps them float64; tensors of a stated dtype
    (the network's, the uint8 frame's) are unaffected."""
    old = torch.get_default_dtype()
    torch.set_default_dtype(torch.float64)
    try:
        yield
    finally:
        torch.set_default_dtype(old)


def trace_onnx(module: nn.Module, args: tuple, inputs: list[str], outputs: list[str], fold: bool = True) -> bytes:
    """``module`` traced to ONNX (opset :data:`OPSET`, TorchScript exporter) with float64 scalars
    (:func:`_float64_scalars`); ``fold``: constant folding."""
    buf = io.BytesIO()
    with warnings.catch_warnings(), _float64_scalars():
        warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation and tracer notes
        torch.onnx.export(module, args, buf, dynamo=False, opset_version=OPSET, input_names=inputs,
                          output_names=outputs, do_constant_folding=fold)
    return buf.getvalue()


def choose_engine(engine: str, device: str) -> str:
    """'torch', 'onnx' or 'openvino' for ``--engine`` ``engine`` on ``device`` (a torch device string):
    ``auto`` is openvino on the CPU where it is installed, else onnx where onnxruntime is, else torch."""
    if engine not in ENGINES:
        raise InputError(f"unknown --engine '{engine}'", None, f"use one of {', '.join(ENGINES)}")
    if engine in RUNTIME:
        require(RUNTIME[engine])
        if device != "cpu":
            raise InputError(f"--engine {engine} runs on the CPU, not {device}", None,
                             "drop --device, or use --engine torch")
        return engine
    if engine == "torch" or device != "cpu":
        return "torch"
    return next((e for e in ("openvino", "onnx") if installed(RUNTIME[e])), "torch")


def engine_note(engine: str, device: str) -> str:
    """Why ``--engine`` ``engine`` runs PyTorch on ``device`` (a torch device string) where a faster
    engine was asked for and none is installed ('auto' on the CPU without OpenVINO or onnxruntime);
    '' otherwise (a GPU's auto is PyTorch by design)."""
    if engine != "auto" or device != "cpu" or choose_engine(engine, device) != "torch":
        return ""
    return f"neither OpenVINO nor onnxruntime is installed: PyTorch runs the network ({DEPLOY_FIX}: ~2x faster on a CPU)"


def traced_network(model: nn.Module, shape: tuple[int, ...], key: str | None = None) -> bytes:
    """The ONNX graph (bytes) of ``model`` (eval mode, on the CPU) on float32 inputs of ``shape``:
    logits out. ``key`` (given: what identifies the network's weights and code, e.g. its checkpoint
    file's SHA-256): the graph is kept for the process under (key, shape), the
    :data:`TRACED_KEPT` last used, and a later call with the same key and shape is given it without
    tracing (~1 s for the shipped model, a load's or a test's repeated cost)."""
    if key is not None and (key, shape) in _TRACED:
        _TRACED.move_to_end((key, shape))
        return _TRACED[(key, shape)]
    x = torch.zeros(shape, dtype=torch.float32)
    with torch.no_grad():
        graph = trace_onnx(model, (x,), ["x"], ["logits"])
    if key is not None:
        _TRACED[(key, shape)] = graph
        while len(_TRACED) > TRACED_KEPT:
            _TRACED.popitem(last=False)
    return graph


def engine_name(engine: str) -> str:
    """'PyTorch 2.13.0' / 'onnxruntime 1.32.0' / 'OpenVINO 2026.4.1': the engine and its version, as
    stderr and predict.json say it."""
    if engine in RUNTIME:
        return runtime_name(RUNTIME[engine])
    return f"PyTorch {torch.__version__.split('+')[0]}"


class OnnxNetwork:
    """``model`` (eval mode) exported to ONNX per input shape and run in ``engine``'s runtime ('onnx':
    onnxruntime, 'openvino'): (1, C, h, w) float32 in, logits (1, K, h, w) float32 out, as
    ``model(x)``. ``key``: the network's identity for :func:`traced_network` (None: traced every
    time). ``say`` (given) hears each export: (the input shape, its seconds). ``export_seconds``: the
    time spent exporting and compiling so far, all shapes together (a start-up cost, not a frame's)."""

    def __init__(self, model: nn.Module, say: Callable[[tuple[int, ...], float], None] | None = None,
                 engine: str = "onnx", key: str | None = None):
        self.model = model
        self.say = say
        self.key = key
        self.runtime = RUNTIME[engine]
        self._sessions: dict[tuple[int, ...], object] = {}
        self.export_seconds = 0.0

    def session(self, shape: tuple[int, ...]):
        """The compiled network for inputs of ``shape`` (exported on first use): feeds -> outputs."""
        s = self._sessions.get(shape)
        if s is None:
            t0 = time.perf_counter()
            s = self._sessions[shape] = compiled(traced_network(self.model, shape, self.key), self.runtime)
            secs = time.perf_counter() - t0
            self.export_seconds += secs
            if self.say is not None:
                self.say(shape, secs)
        return s

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.ascontiguousarray(x, dtype=np.float32)
        return self.session(tuple(x.shape))({"x": x})[0]
