"""Running an exported road graph (:mod:`vctrain.export`) in onnxruntime: :class:`OnnxPredictor`
(frame [+ VP] -> P(road)) and :func:`predict_images_onnx` (``vctrain predict GRAPH.onnx``).
onnx / onnxruntime are optional (``pip install 'vcseg[deploy]'``) and imported only by
:func:`require`."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Iterable

import numpy as np

from vcprep.camera import Camera, camera_from_dict
from vcprep.errors import InputError

__all__ = ["GRAPH_FORMAT", "OnnxPredictor", "predict_images_onnx", "require", "vp_from_cam"]

GRAPH_FORMAT = "vcseg-road-graph"
DEPLOY_FIX = "pip install 'vcseg[deploy]'"


def require(module: str):
    """Import ``onnx`` or ``onnxruntime`` (the optional 'deploy' extra) or raise one clear error."""
    try:
        return __import__(module)
    except ImportError:
        raise InputError(f"{module} is not installed (needed to export or run ONNX graphs)", None, DEPLOY_FIX) from None


def vp_from_cam(camera: Camera) -> tuple[float, float]:
    from vcprep.homography import vp_from_pose

    return vp_from_pose(camera.for_image_size(camera.size))


def _session(ort, model, threads: int = 0):
    from .threads import threads_in_use

    so = ort.SessionOptions()
    so.intra_op_num_threads = threads or threads_in_use()  # what --threads set (vctrain.threads)
    so.log_severity_level = 3
    return ort.InferenceSession(model, so, providers=["CPUExecutionProvider"])


class OnnxPredictor:
    """An exported graph (``vctrain export``) run in onnxruntime: frame (+ VP) -> P(road)."""

    def __init__(self, path: str | Path, threads: int = 0):
        ort = require("onnxruntime")
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError("ONNX graph not found", self.path, "give the .onnx file written by 'vctrain export'")
        try:
            self.session = _session(ort, str(self.path), threads)
        except Exception as e:  # onnxruntime raises its own types for foreign/corrupt files
            raise InputError(f"cannot load ONNX graph ({str(e).splitlines()[0][:120]})", self.path,
                             "give the .onnx file written by 'vctrain export'") from None
        meta = self.session.get_modelmeta().custom_metadata_map.get("vcseg")
        info = json.loads(meta) if meta else {}
        if info.get("format") != GRAPH_FORMAT:
            raise InputError("not a graph written by 'vctrain export' (no vcseg metadata)", self.path,
                             "export the model with 'vctrain export'")
        self.info = info
        self.size = tuple(info["inputs"]["frame"][1][1::-1])  # (w, h)
        self.vp_input = "vp" in info["inputs"]
        self.camera = camera_from_dict(info["camera"], self.path)
        self.mode = info["mode"]
        self.beyond = 0  # frames of the last predict_images_onnx whose VP was beyond the pose range

    def beyond_range(self, vp: tuple[float, float] | None) -> bool:
        """Whether a ``--vp-input`` graph's pose range (``vctrain export --pose-range``) does not
        hold the pose of ``vp``: the graph's rectangle and back-projection box then cut P(road)."""
        pose_range = self.info.get("pose_range")
        if vp is None or not pose_range:
            return False
        from vcprep.homography import pose_from_vp

        cam = self.camera.for_image_size(self.camera.size)
        pan, tilt = pose_from_vp(cam, (float(vp[0]), float(vp[1])))
        return abs(pan - cam.pan) > pose_range[0] + 1e-6 or abs(tilt - cam.tilt) > pose_range[1] + 1e-6

    def road_probability(self, frame: np.ndarray, vp: tuple[float, float] | None = None,
                         name: str | Path | None = None) -> np.ndarray:
        """P(road) float32 (h, w) of one BGR uint8 frame of the graph's camera size."""
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            raise InputError(f"frame is {frame.dtype} with shape {frame.shape}, the graph takes uint8 BGR (h, w, 3)",
                             name, "give 8-bit colour frames")
        if (frame.shape[1], frame.shape[0]) != self.size:
            raise InputError(f"frame is {frame.shape[1]}x{frame.shape[0]} but the graph's camera is "
                             f"{self.size[0]}x{self.size[1]}", name, "export the model for this camera's image size")
        feeds = {"frame": np.ascontiguousarray(frame)}
        if self.vp_input:
            feeds["vp"] = np.asarray(vp if vp is not None else vp_from_cam(self.camera), dtype=np.float32)
        return self.session.run(None, feeds)[0]


def predict_images_onnx(predictor: OnnxPredictor, images: Iterable[str | Path], out: str | Path,
                        camera: Camera | None = None, progress: bool = True, overlay: bool = False,
                        within: str = "auto") -> list[Path]:
    """:func:`vctrain.predict.predict_images` for an exported graph: writes ``<stem>_prob.png`` and
    ``<stem>_mask.png``. A ``--vp-input`` graph gets each frame's VP: ``within`` 'auto'/'estimate'
    estimates it (with ``camera``, default the graph's), a CSV ``id,u,v`` gives it, 'none' takes
    the camera's mount pose; a fixed graph takes only 'auto' or 'none'. ``predictor.beyond``
    counts the frames whose VP lies beyond the graph's pose range (:meth:`OnnxPredictor.beyond_range`)."""
    from tqdm import tqdm

    from vcprep.imageio import read_image

    from .predict import _out_dir, collect_images, write_prediction

    jobs = collect_images(images)
    out = _out_dir(out)
    vps: dict[str, tuple[float, float]] = {}
    if not predictor.vp_input:
        if within not in ("auto", "none"):
            raise InputError("this graph has the camera's mount pose built in (exported without --vp-input)",
                             predictor.path, "drop --within, or export with --vp-input")
    elif within != "none":
        from vcprep.vanishing_point import vps_for_items

        cam = camera or predictor.camera
        res = vps_for_items([j.image for j in jobs], [j.id for j in jobs], cam,
                            "estimate" if within == "auto" else within)
        vps = {j.id: (float(r.vp[0]), float(r.vp[1])) for j, r in zip(jobs, res)}
    written = []
    predictor.beyond = sum(predictor.beyond_range(vp) for vp in vps.values())
    for job in tqdm(jobs, desc="predict", unit="img", disable=None if progress else True, leave=False):
        img = read_image(job.image).array
        prob = predictor.road_probability(img, vps.get(job.id), job.image)
        written.append(write_prediction(out, job.id, prob, job.image if overlay else None)[0])
    return written
