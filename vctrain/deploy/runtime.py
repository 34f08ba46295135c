"""Running an exported road graph (:mod:`vctrain.deploy.export`): :class:`OnnxPredictor` (frame [+ VP]
-> P(road)) in OpenVINO or onnxruntime (:data:`RUNTIMES`, :func:`compiled`); ``vctrain predict
GRAPH.onnx`` runs it on the one road for a frame (:mod:`vctrain.predict.road`).

OpenVINO is the default where it is installed (``--engine auto``; ``--engine onnx`` for onnxruntime):
on this project's 2-core CPU the shipped model's 1280x720 int8 graph ran the README's video command
(overlay included) at 39.3 frames/s against onnxruntime's 32.9, the float graph at 31.6 against 26.6
(benchmarks/speed/predict_e2e.py, a quiet machine; an earlier run 38.9 / 30.5 and 27.6 / 25.5). It runs every graph in float32
(``INFERENCE_PRECISION_HINT``: on a CPU with bf16 units it would otherwise compute in bf16, which
moves masks), so its P(road) is onnxruntime's to float rounding (tests/test_pipeline.py).
onnx / onnxruntime / openvino are optional (``pip install 'vcseg[deploy]'``) and imported only by
:func:`require`."""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Callable

import numpy as np

from vcprep.camera import Camera, camera_from_dict
from vcprep.errors import InputError

from ..training.checkpoint_data import CheckpointData

__all__ = ["GRAPH_FORMAT", "RUNTIMES", "OnnxPredictor", "compiled", "graph_output", "graph_runtime", "require",
           "runtime_name", "vp_from_cam"]

GRAPH_FORMAT = "vcseg-road-graph"
# OpenVINO's CPU settings (:func:`compiled`): one request at a time, in float32 (module docstring), its
# worker threads free to move between cores. OpenVINO pins them to cores by default, and a pinned worker
# waits while ``vctrain predict``'s decoding or writing thread holds its core instead of running on the
# other one: the shipped network at 480x360 on 2 cores beside a thread that computes half the time took
# 43.4 ms a call pinned and 32.9 ms unpinned (23.0 / 23.4 ms alone; issue 81, benchmarks/speed/predict_e2e.py
# gives the whole command). The numbers are the same either way.
OPENVINO_CONFIG = {"PERFORMANCE_HINT": "LATENCY", "INFERENCE_PRECISION_HINT": "f32", "ENABLE_CPU_PINNING": False}
DEPLOY_FIX = "pip install 'vcseg[deploy]'"
RUNTIMES = ("openvino", "onnxruntime")  # what runs an ONNX graph, the fastest first (module docstring)


def require(module: str):
    """Import ``onnx`` or ``onnxruntime`` (the optional 'deploy' extra) or raise one clear error."""
    try:
        return __import__(module)
    except ImportError:
        raise InputError(f"{module} is not installed (needed to export or run ONNX graphs)", None, DEPLOY_FIX) from None


def installed(module: str) -> bool:
    try:
        __import__(module)
    except ImportError:
        return False
    return True


def graph_runtime(engine: str | None) -> str:
    """The runtime a graph runs in for ``--engine`` ``engine``: 'openvino' or 'onnxruntime' (``onnx``);
    None or 'auto': the fastest installed (:data:`RUNTIMES`); 'torch' is refused (a graph is ONNX)."""
    if engine in ("onnx", "onnxruntime"):
        return "onnxruntime"
    if engine == "openvino":
        return "openvino"
    if engine not in (None, "auto"):
        raise InputError(f"an exported graph runs in OpenVINO or onnxruntime, not {engine}", None,
                         "give --engine openvino, onnx or auto, or the .pt model")
    return next((r for r in RUNTIMES if installed(r)), "onnxruntime")


def runtime_name(runtime: str) -> str:
    """'OpenVINO 2026.4.1' / 'onnxruntime 1.32.0': the runtime and its version, as stderr and
    predict.json say it."""
    if runtime == "openvino":
        return f"OpenVINO {require('openvino').__version__.split('-')[0]}"
    return f"onnxruntime {require('onnxruntime').__version__}"


def compiled(model: str | bytes, runtime: str, threads: int = 0) -> Callable[[dict], list[np.ndarray]]:
    """``model`` (an ONNX file's path or its bytes) compiled for the CPU in ``runtime`` at ``threads``
    (0: what --threads set): a call feeds -> the outputs (arrays owned by the caller, in order)."""
    from ..threads import threads_in_use

    threads = threads or threads_in_use()
    if runtime == "onnxruntime":
        session = _session(require("onnxruntime"), model, threads)
        return lambda feeds: session.run(None, feeds)
    ov = require("openvino")
    core = ov.Core()
    net = core.compile_model(core.read_model(model), "CPU", {**OPENVINO_CONFIG, "INFERENCE_NUM_THREADS": threads})
    request, outputs = net.create_infer_request(), list(net.outputs)

    def run(feeds: dict) -> list[np.ndarray]:
        res = request.infer(feeds)  # (copies: the request's buffers are reused by the next call)
        return [res[o] for o in outputs]
    return run


def vp_from_cam(camera: Camera) -> tuple[float, float]:
    from vcprep.warp import vp_from_pose

    return vp_from_pose(camera.for_image_size(camera.size))


def _session(ort, model, threads: int = 0):
    """An onnxruntime CPU session of ``model`` (a path or the graph's bytes) at ``threads`` (0: what
    --threads set, :mod:`vctrain.threads`). Its worker threads sleep between runs instead of spinning:
    a spinning worker holds a core that ``vctrain predict``'s decoding and writing threads need (on 2
    cores, a 1280x720 video with overlay through the int8 graph: 29 frames/s against 24 spinning,
    benchmarks/speed/predict_e2e.py); the numbers are the same either way."""
    from ..threads import threads_in_use

    so = ort.SessionOptions()
    so.intra_op_num_threads = threads or threads_in_use()  # what --threads set (vctrain.threads)
    so.log_severity_level = 3
    so.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return ort.InferenceSession(model, so, providers=["CPUExecutionProvider"])


def _graph_info(path: Path) -> dict:
    """The ``vcseg`` metadata of an ONNX file ({} when it has none); a file that is not ONNX is refused."""
    onnx = require("onnx")
    try:
        model = onnx.load(str(path), load_external_data=False)
    except Exception as e:  # protobuf's DecodeError and friends for a foreign or corrupt file
        raise InputError(f"cannot load ONNX graph ({str(e).splitlines()[0][:120] if str(e) else type(e).__name__})",
                         path, "give the .onnx file written by 'vctrain export'") from None
    meta = {p.key: p.value for p in model.metadata_props}.get("vcseg")
    return json.loads(meta) if meta else {}


def graph_output(info: dict, output: str, path: Path) -> str:
    """``output`` if the graph of metadata ``info`` computes it (``info['prob_of']``; a graph of an older
    vctrain: road); else one line naming the output it computes and the fix: a graph is exported for one
    output and never gives another's probability."""
    from vcprep.labels import DEFINITIONS

    own = info.get("prob_of", "road")
    if output not in DEFINITIONS:
        raise InputError(f"unknown output '{output}'", path, f"use --output {' or '.join(DEFINITIONS)}")
    if output != own:
        raise InputError(f"graph computes P({own}), not P({output})", path,
                         f"use --output {own}, or export the model again with --output {output}")
    return output


class OnnxPredictor:
    """An exported graph (``vctrain export``) run in ``runtime`` (:data:`RUNTIMES`; None: the fastest
    installed): frame (+ VP) -> P(road). It takes whole frames (``takes_frames``: the warp and
    back-projection are inside the graph)."""

    takes_frames = True
    beyond_rule = None                    # (rays, inside the graph; vctrain.predict.kinds.RoadPredictor)
    vp_channel = ray_channels = False

    def __init__(self, path: str | Path, threads: int = 0, runtime: str | None = None, output: str = "road"):
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError("ONNX graph not found", self.path, "give the .onnx file written by 'vctrain export'")
        self.runtime = graph_runtime(runtime)  # (None: the fastest installed)
        info = _graph_info(self.path)
        if info.get("format") != GRAPH_FORMAT:
            raise InputError("not a graph written by 'vctrain export' (no vcseg metadata)", self.path,
                             "export the model with 'vctrain export'")
        self.output = graph_output(info, output, self.path)
        t0 = time.perf_counter()
        try:
            self._call = compiled(str(self.path), self.runtime, threads)
        except Exception as e:  # each runtime raises its own types for a graph it cannot run
            raise InputError(f"cannot load ONNX graph in {self.runtime} ({str(e).splitlines()[0][:120]})", self.path,
                             "give the .onnx file written by 'vctrain export'") from None
        self.compile_seconds = time.perf_counter() - t0  # (the graph read and compiled: part of its load)
        self.info = info
        self.size = tuple(info["inputs"]["frame"][1][1::-1])  # (w, h)
        self.vp_input = "vp" in info["inputs"]
        self.camera = camera_from_dict(info["camera"], self.path)
        self.mode = info["mode"]
        self.data = CheckpointData()  # (no checkpoint: the VP rule is the detector's)
        self.beyond = 0  # frames predicted with a VP beyond the graph's pose range (beyond_range)

    def use_output(self, output: str) -> str:
        """``output`` if this graph computes it (:func:`graph_output`); refused otherwise."""
        return graph_output(self.info, output, self.path)

    def beyond_range(self, vp: tuple[float, float] | None) -> bool:
        """Whether a ``--vp-input`` graph's pose range (``vctrain export --pose-range``) does not
        hold the pose of ``vp``: the graph's rectangle then holds less of the frame than ``vctrain
        predict``'s (the network sees less context; the rays give every pixel a value)."""
        pose_range = self.info.get("pose_range")
        if vp is None or not pose_range:
            return False
        from vcprep.warp import pose_from_vp

        cam = self.camera.for_image_size(self.camera.size)
        pan, tilt = pose_from_vp(cam, (float(vp[0]), float(vp[1])))
        return abs(pan - cam.pan) > pose_range[0] + 1e-6 or abs(tilt - cam.tilt) > pose_range[1] + 1e-6

    def check_frame_size(self, size: tuple[int, int], name: str | Path | None = None) -> None:
        """Raise :meth:`size_error` unless frames of ``size`` (w, h) are the graph's own size: a graph
        is traced for one frame size and never resizes a frame silently (issue 69: a 480x360 frame
        through a 960x720 graph scored 92.72 against 92.81, up to 4.7 % of a frame's pixels different)."""
        if tuple(size) != tuple(self.size):
            raise self.size_error(size, name)

    def size_error(self, size: tuple[int, int], name: str | Path | None) -> InputError:
        """One line naming both sizes and the fix: a graph exported for frames of this size."""
        w, h = size
        gw, gh = self.size
        what = f"frame is {w}x{h} but the graph was exported for {gw}x{gh} frames"
        ckpt = self.info.get("checkpoint", "MODEL.pt")
        cam = f" --camera {self.info['camera_file']}" if self.info.get("camera_file") else \
            (" --camera CAMERA" if self.info.get("camera_given", True) else "")
        if self.info.get("camera_given", True):
            try:  # the same camera at another resolution: the same export at that size
                self.camera.for_image_size((w, h), name)
            except InputError:
                what += f" (and {w}x{h} is not a uniform rescale of its camera: another camera, or a crop)"
        return InputError(what, name, f"export a graph for {w}x{h}: vctrain export {ckpt}{cam} "
                          f"--frame {name or 'FRAME'} -o road_{w}x{h}.onnx")

    def road_probability(self, frame: np.ndarray, vp: tuple[float, float] | None = None,
                         name: str | Path | None = None) -> np.ndarray:
        """P(road) float32 (h, w) of one BGR uint8 frame at the graph's own size (another size raises
        :meth:`size_error`); ``vp`` (a ``--vp-input`` graph) in the frame's pixels."""
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            raise InputError(f"frame is {frame.dtype} with shape {frame.shape}, the graph takes uint8 BGR (h, w, 3)",
                             name, "give 8-bit colour frames")
        self.check_frame_size((frame.shape[1], frame.shape[0]), name)
        return self._run(frame, vp)

    def _run(self, frame: np.ndarray, vp: tuple[float, float] | None) -> np.ndarray:
        """The graph on one frame of its own size (``vp`` in its pixels)."""
        feeds = {"frame": np.ascontiguousarray(frame)}
        self.beyond += self.beyond_range(vp)
        if self.vp_input:
            feeds["vp"] = np.asarray(vp if vp is not None else vp_from_cam(self.camera), dtype=np.float32)
        return self._call(feeds)[0]
