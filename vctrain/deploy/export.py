"""Deployment: one ONNX graph with the camera inside (``vctrain export``), and running it.

The graph takes a camera's raw frame and returns road probability in that camera's pixels; it
holds everything ``vctrain predict`` does for that camera (:mod:`vctrain.predict`):

- ``virtual`` models: the warp into the checkpoint's virtual camera at its scale, the rectangle
  extended for this camera as ``predict`` does (:func:`vctrain.predict.road.rectangle_views`), with the
  training store's completion; the resize to the working size; :func:`vctrain.training.data.to_input`
  (and the VP channel); the network; softmax; the resize back and the back-projection
  (bilinear; a frame pixel beyond the training rectangle takes the value where the ray from the
  road VP leaves it, :func:`vcprep.warp.backproject.ray_clamped`: ``vctrain predict``'s default
  ``--beyond hybrid``).
  The camera's ``ego_rows`` are cut off before the warp and back-projected like any row.
- ``resize`` baseline models: resize in, network, softmax, resize back.

Fixed mount (default): the warp is a constant sampling grid -- the store maps of
:func:`vcprep.warp.completion.completion_maps` for the camera's own pose, completion included -- and
the back-projection another. ``vp_input=True``: the graph takes the frame's road vanishing point
(u, v, source pixels) and builds ``virt_H_src`` (:func:`vcprep.warp.homography.virt_H_src` via
:func:`~vcprep.warp.homography.pose_from_vp`, in float64) and the projective completion in the graph:
every uncovered store pixel takes the source point where the ray from the VP, at the fill
table's quantised angle, leaves the source rectangle (:func:`vcprep.warp.completion.exit_points_rectangle`
-- once per angle of the table), and a VP outside the image starts the rays from the nearest
covered pixel moved 10 % toward the centroid, as the library does. Its rectangle is fixed: the
training's, extended to hold the camera at every pose within ``pose_range`` (pan, tilt degrees)
of its mount; every frame pixel is back-projected (beyond the training rectangle by the rays). A
frame whose VP lies beyond the range sees less context around the training rectangle than
``vctrain predict`` would give it (which extends the rectangle for it).

Sampling convention and the layout of the taps: :mod:`vctrain.deploy.graph_ops`. P(road) of a
two-class network is ``sigmoid(l1 - l0)`` (softmax's value; onnxruntime's channel softmax is
slow). A two-output network (three classes, :mod:`vctrain.training.outputs`) gives the output the graph is
exported for (``output``; its metadata's ``prob_of``, which :class:`~vctrain.deploy.runtime.OnnxPredictor`
holds to): road ``sigmoid(l2 - logsumexp(l0, l1))`` (softmax's class 2), drivable
``sigmoid(logsumexp(l1, l2) - l0)`` (classes 1 and 2). Running a graph: :mod:`vctrain.deploy.runtime`. Graph I/O: ``frame`` uint8 (H, W, 3) BGR as ``cv2.imread`` gives it
at the camera's image size, ``vp`` float32 (2,) with ``vp_input``; output ``road_prob`` float32
(H, W). onnx / onnxruntime are optional (``pip install 'vcseg[deploy]'``) and imported only by :func:`require`.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from vcprep.camera import Camera, camera_from_dict, scale_matrix
from vcprep.errors import InputError
from vcprep.warp import ray_clamped

from .graph_ops import (FALLBACK_TOWARD, TABLE_ARC, _backproject_coords, _backproject_grid, _fixed_point,
                        _load_fraction, _padded, _pair_rows, _resize_u8, _sample_f, _sample_u8, _seen_box, _store_fraction,
                        _store_maps_from_vp, _taps, _vp_map)
from .engine import OPSET, trace_onnx
from .runtime import (GRAPH_FORMAT, OnnxPredictor, _session,  # noqa: F401
                           require, vp_from_cam)

__all__ = ["OPSET", "POSE_RANGE", "RoadGraph", "export_onnx", "OnnxPredictor", "require"]

# (pan, tilt) degrees of its mount a --vp-input graph holds the camera at by default (vctrain export --pose-range)
POSE_RANGE = (5.0, 5.0)


def _sees_store(idx: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """Which samples of :func:`~vctrain.deploy.graph_ops._taps` read any store pixel (not the corner's zeros)."""
    return (idx > 0) | (ax > 0) | (ay > 0)


def _logaddexp(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """log(exp(a) + exp(b)) without overflow, in operators every runtime has (ONNX's ReduceLogSumExp, which
    torch.logsumexp exports to, sums the exponentials unshifted: a trained network's logits overflow it)."""
    return torch.maximum(a, b) + torch.log1p(torch.exp(-(a - b).abs()))


# -- the graph -----------------------------------------------------------------------------------------

class RoadGraph(nn.Module):
    """Frame (H, W, 3) uint8 BGR [, VP (2,) float32] -> P(road) (H, W) float32; see the module doc.

    ``geom``: what :func:`_geometry` computed (sizes, maps, VP map, camera); ``model``: the
    network in eval mode."""

    def __init__(self, model: nn.Module, geom: dict[str, Any]):
        super().__init__()
        self.model, self.g = model, geom
        if geom.get("vp_map") is not None:
            self.register_buffer("vp_map", torch.from_numpy(np.ascontiguousarray(geom["vp_map"])), persistent=False)
        if geom.get("angle_index") is not None:
            self.register_buffer("angle_index", torch.from_numpy(geom["angle_index"]), persistent=False)
        if geom.get("warp_qx") is None:
            return
        # fixed mount: every tap index and weight is a constant (computed once, here)
        wv, hv = geom["visible"]
        Ws, Hs = geom["store_size"]
        w, h = geom["size"]
        x, y = (torch.from_numpy(np.ascontiguousarray(geom[k])).reshape(-1) for k in ("warp_qx", "warp_qy"))
        idx, ax, ay = _taps(x, y, wv, hv)
        self._constants("warp", _pair_rows(idx, wv, hv), ax, ay)
        # the back-projection only where a frame pixel reads the store: its bounding box (0 around it)
        idx, ax, ay = _taps(torch.from_numpy(geom["back_qx"]).reshape(-1), torch.from_numpy(geom["back_qy"]).reshape(-1),
                            Ws, Hs)
        self.back_box = r0, r1, c0, c1 = _seen_box(_sees_store(idx, ax, ay).reshape(h, w).numpy())
        self._constants("back", *(t.reshape(h, w)[r0:r1, c0:c1].reshape(-1) for t in (idx, ax, ay)))

    def _constants(self, name: str, idx: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> None:
        """Fixed-mount taps as buffers: int32 indices, fractions as int16 (the file stays small;
        onnxruntime converts them once when it loads the graph)."""
        self.register_buffer(f"{name}_idx", idx.contiguous())
        self.register_buffer(f"{name}_ax", _store_fraction(ax))
        self.register_buffer(f"{name}_ay", _store_fraction(ay))

    def _taps_of(self, name: str) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        return (getattr(self, f"{name}_idx"), _load_fraction(getattr(self, f"{name}_ax")),
                _load_fraction(getattr(self, f"{name}_ay")))

    def _net(self, x: torch.Tensor, vp_map: torch.Tensor | None, ws: int, hs: int, hwc: bool = False) -> torch.Tensor:
        """(3, hs, ws) float 0-255 BGR image (``hwc``: the uint8 frame (hs, ws, 3) itself) -> P(road)
        (hs, ws) at that size (working size inside)."""
        g = self.g
        if tuple(g["work"]) != (ws, hs):  # resize_pair: cv2.resize bilinear on the uint8 image
            x = _resize_u8(x if hwc else x[None], (ws, hs), tuple(g["work"]), hwc=hwc)
        else:
            x = x.to(torch.float32).permute(2, 0, 1)[None] if hwc else x[None]
        x = x * (2 / 255) - 1 if not g["greyscale"] else x
        if g["greyscale"]:  # to_input: cvtColor BGR2GRAY on [0, 1] floats, replicated
            grey = (x[:, 0:1] * 0.114 + x[:, 1:2] * 0.587 + x[:, 2:3] * 0.299) / 255
            x = (grey * 2 - 1).expand(-1, 3, -1, -1)
        if vp_map is not None:
            x = torch.cat([x, vp_map[None, None]], 1)
        logits = self.model(x).float()
        if logits.shape[1] == 2:  # softmax's P(road) of two classes, without onnxruntime's slow channel softmax
            prob = torch.sigmoid(logits[:, 1:2] - logits[:, 0:1])
        elif g.get("prob_of", "road") == "drivable":  # two outputs (module docstring): classes 1 and 2 against 0
            prob = torch.sigmoid(_logaddexp(logits[:, 1:2], logits[:, 2:3]) - logits[:, 0:1])
        else:  # class 2 against 0 and 1
            prob = torch.sigmoid(logits[:, 2:3] - _logaddexp(logits[:, 0:1], logits[:, 1:2]))
        if tuple(g["work"]) != (ws, hs):
            prob = F.interpolate(prob, size=(hs, ws), mode="bilinear", align_corners=False)
        return prob[0, 0]

    def store_maps(self, vp: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``--vp-input``: (virt_H_src, qx, qy) of the frame whose road VP is ``vp`` (float32 (2,)):
        :func:`~vctrain.deploy.graph_ops._store_maps_from_vp` with this graph's camera and rectangle."""
        g = self.g
        known = getattr(self, "angle_index", None)
        if known is not None:
            known = (torch.tensor(g["angle_centre"][0], dtype=torch.float32),
                     torch.tensor(g["angle_centre"][1], dtype=torch.float32),
                     torch.tensor(float(g["angle_n"]), dtype=torch.float64), known)
        return _store_maps_from_vp(vp.double(), g["camera"], torch.tensor(g["Gv"], dtype=torch.float64),
                                   tuple(g["store_size"]), tuple(g["visible"]), g["completion"], known)

    def forward(self, frame: torch.Tensor, vp: torch.Tensor | None = None) -> torch.Tensor:
        g = self.g
        w, h = g["size"]
        if g["mode"] == "resize":
            vp_map = None
            if g["vp_channel"]:
                vp_map = self.vp_map if vp is None else _vp_map(vp.double(), g["work"], (w, h)).float()
            return self._net(frame, vp_map, w, h, hwc=True).clamp(0, 1)
        wv, hv = g["visible"]
        src = _padded(frame[:hv])  # (P, 3) uint8; the own vehicle's rows are never warped
        Ws, Hs = g["store_size"]
        vp_map = getattr(self, "vp_map", None)
        if vp is None:
            taps = self._taps_of("warp")
        else:
            H, qx, qy = self.store_maps(vp)
            idx, ax, ay = _taps(qx.reshape(-1), qy.reshape(-1), wv, hv, inside=g["completion"] == "projective")
            taps = _pair_rows(idx, wv, hv), ax, ay
        store = _sample_u8(src, wv, *taps)  # (3, Hs*Ws) 0-255, exactly the store image
        prob = self._net(store.reshape(3, Hs, Ws), vp_map, Ws, Hs)
        if vp is None:
            r0, r1, c0, c1 = self.back_box
            out = _sample_f(_padded(prob), Ws, *self._taps_of("back")).reshape(r1 - r0, c1 - c0)
        else:  # only the frame pixels that can see the store at some pose in the range
            r0, r1, c0, c1 = g["back_box"]
            out = _backproject_grid(prob, H, (r0, r1, c0, c1), tuple(g["centre"]), tuple(g["rect"]))
        out = F.pad(out, (c0, w - c1, r0, h - r1))
        return out.clamp(0, 1)


def _geometry(predictor, camera: Camera, vp_input: bool, pose_range: tuple[float, float]) -> dict[str, Any]:
    """Everything the graph holds for ``camera`` (at its own image size)."""
    from vcprep.warp import completion as C
    from vcprep.store import item_geometry, item_magnification, item_maps, store_params
    from vcprep.warp import apply_homography, vp_from_pose
    from vcprep.camera import extend_canvas

    from ..training.data import vp_proximity

    assert (C.TABLE_ARC, C.FALLBACK_TOWARD) == (TABLE_ARC, FALLBACK_TOWARD)  # the in-graph completion's constants
    from ..predict.frames import refuse_mixed

    refuse_mixed(predictor)
    data = predictor.data
    cam = camera.for_image_size(camera.size)
    w, h = cam.size
    g: dict[str, Any] = {"mode": predictor.mode, "size": [w, h], "greyscale": predictor.greyscale,
                         "vp_channel": predictor.vp_channel, "vp_input": vp_input}
    vp_src = vp_from_pose(cam)
    if predictor.mode == "resize":
        if vp_input and not predictor.vp_channel:
            raise InputError("a resize model without the VP channel takes no VP (the frame is only resized)",
                             predictor.path, "export without --vp-input")
        g["work"] = list(predictor.frame_working_size((w, h)))  # (a keep_aspect model: the frame's aspect)
        if predictor.vp_channel:
            S = scale_matrix(g["work"][0] / w, g["work"][1] / h)
            p = S @ np.array([vp_src[0], vp_src[1], 1.0])
            g["vp_map"] = vp_proximity(tuple(g["work"]), (p[0], p[1])).astype(np.float32)
        return g
    sp = data.store_params
    if not sp:
        raise InputError("model was not trained in a virtual camera and is no resize baseline", predictor.path,
                         "use a model written by 'vctrain fit'")
    completion = data.completion
    if vp_input and completion == "replicate":
        raise InputError("'replicate' completion (a distance transform) cannot follow a VP given at run time",
                         predictor.path, "export without --vp-input (the camera's mount pose)")
    virtual = camera_from_dict(sp["virtual"], predictor.path)
    views = [(cam, cam.pan, cam.tilt)]
    if vp_input:  # one fixed rectangle for every pose in the range (vctrain predict extends per frame set)
        views += [(cam, cam.pan + a * pose_range[0], cam.tilt + b * pose_range[1])
                  for a in (-1, 0, 1) for b in (-1, 0, 1)]
    canvas = extend_canvas(virtual, views)
    params = store_params(canvas, float(sp["scale"]))
    vs = camera_from_dict(params["virtual_scaled"])
    store_size = tuple(params["store_size"])
    _, H = item_geometry(cam, (w, h), vs, None, cam.pan, cam.tilt)
    vis = cam.visible_size
    vp_store = tuple(apply_homography(H, [vp_src])[0])
    work = predictor.working_size(store_size, item_magnification(cam, (w, h), vs))
    trained = store_params(virtual, float(sp["scale"]))  # the training rectangle inside the grown one: rays beyond it
    ox = float(vs.cx) - float(trained["virtual_scaled"]["cx"])
    rect = (ox, 0.0, ox + trained["store_size"][0] - 1.0, trained["store_size"][1] - 1.0)
    g.update(work=list(work), store_size=list(store_size), visible=list(vis), completion=completion,
             virtual=canvas.to_dict(), scale=float(sp["scale"]), ego_rows=int(cam.ego_rows),
             centre=[float(vs.cx), float(vs.cy)], rect=list(rect))  # every road VP lands on the principal point
    if predictor.vp_channel:
        S = scale_matrix(work[0] / store_size[0], work[1] / store_size[1])
        p = S @ np.array([vp_store[0], vp_store[1], 1.0])
        g["vp_map"] = vp_proximity(work, (p[0], p[1])).astype(np.float32)
    if vp_input:
        return _vp_geometry(g, cam, vs, H, vp_store)
    maps = item_maps(H, vis, store_size, completion, vp_store)
    covered = torch.from_numpy(maps.valid.astype(bool))
    mx, my = torch.from_numpy(maps.exact_maps.map_x), torch.from_numpy(maps.exact_maps.map_y)
    # covered pixels are remapped with fixed-point maps, the completion's fill table with float ones
    g["warp_qx"] = torch.where(covered, _fixed_point(mx), mx).numpy()
    g["warp_qy"] = torch.where(covered, _fixed_point(my), my).numpy()
    bx, by = _backproject_coords(torch.tensor(np.asarray(H, dtype=np.float64)), w, h)
    bx, by = ray_clamped(bx.double().numpy(), by.double().numpy(), vp_store, rect)
    g["back_qx"], g["back_qy"] = bx.astype(np.float32), by.astype(np.float32)
    return g


def _vp_geometry(g: dict[str, Any], cam: Camera, vs: Camera, H: np.ndarray,
                 vp_store: tuple[float, float]) -> dict[str, Any]:
    """What a ``--vp-input`` graph holds besides :func:`_geometry`'s sizes: the camera and the
    virtual camera's ground homography, the back-projection's box (the whole frame: beyond the
    training rectangle every pixel takes the rays' value) and (projective completion) the fill
    table's angle index seen from the mount pose's ray centre."""
    from vcprep.warp import completion as C
    from vcprep.warp import ground_to_image

    w, h = g["size"]
    vis, store_size, completion = tuple(g["visible"]), tuple(g["store_size"]), g["completion"]
    g["camera"] = cam
    g["Gv"] = ground_to_image(vs)
    g["back_box"] = [0, h, 0, w]
    if completion == "projective":  # the fill table's angles seen from the mount pose's centre (module doc)
        from vcprep.warp import TABLE_COLS
        from vcprep.warp.completion_tables import _all_angles

        mount = C.completion_maps(H, vis, store_size, completion, vp_store)
        n, cu, cv = mount.angles.n, np.float32(mount.centre[0]), np.float32(mount.centre[1])
        pair = _all_angles((store_size[1], store_size[0]), cu, cv, n).astype(np.int32)
        g["angle_index"] = (pair[..., 0] + pair[..., 1] * TABLE_COLS).astype(np.int16)
        g["angle_centre"], g["angle_n"] = [float(cu), float(cv)], n
    return g


def frames_camera(size: tuple[int, int]) -> Camera:
    """The camera of a graph for a model that reads frames as they are (a resize model without the
    VP channel): only its image size matters (nothing is warped and no VP is taken)."""
    w, h = int(size[0]), int(size[1])
    return Camera("frames as they are", (w, h), float(w), float(w), (w - 1) / 2.0, (h - 1) / 2.0, 1.5)


def export_onnx(checkpoint: str | Path, camera: Camera | None, out: str | Path, vp_input: bool = False,
                pose_range: tuple[float, float] = POSE_RANGE, check: bool = True, size: tuple[int, int] | None = None,
                camera_spec: str | None = None, int8: bool = False, calib: str | Path | None = None,
                output: str = "road") -> dict[str, Any]:
    """Write the ONNX graph of ``checkpoint`` for ``camera`` to ``out`` (module docstring); with
    ``check`` runs it once in onnxruntime against the torch module. Returns its description (also
    stored in the graph's metadata ``vcseg``): inputs, output, sizes, opset, max_abs_diff.
    ``camera`` None: a model that reads frames as they are, for frames of ``size`` (w, h);
    ``camera_spec``: how the camera was named (``--camera``), for the graph's own advice. ``int8``:
    the network quantized to 8 bits, calibrated on the frames of ``calib`` (None: the examples;
    :mod:`vctrain.deploy.quantize`); the description's ``int8`` gives the calibration and the share of
    pixels whose mask is the float graph's. ``output``: which output of a two-output model the graph
    computes (road or drivable; the description's ``prob_of``)."""
    onnx = require("onnx")
    from ..predict.predictor import Predictor

    predictor = Predictor(checkpoint, "cpu", output=output)  # (an output the model lacks: refused here)
    if camera is None:
        if predictor.mode != "resize" or predictor.vp_channel:
            raise InputError(f"a {'VP-channel ' if predictor.mode == 'resize' else 'virtual-camera '}model needs the "
                             "camera of its frames", checkpoint, "add --camera: a preset, a calibration file, or for an uncalibrated camera "
                             "the one 'vcprep camera estimate FRAMES -o cam.yaml' writes")
        if size is None:
            raise InputError("the graph's frame size is not known", None, "give --frame A_FRAME or --size WxH")
        camera = frames_camera(size)
    if not isinstance(camera, Camera):
        raise InputError("export needs one camera (the graph holds one mount)", None,
                         "give a preset or one calibration file, not a folder")
    geom = {**_geometry(predictor, camera, vp_input, pose_range), "prob_of": predictor.output}
    graph = RoadGraph(predictor.model.eval(), geom).eval()
    w, h = geom["size"]
    frame = torch.zeros(h, w, 3, dtype=torch.uint8)
    vp = torch.tensor(vp_from_cam(camera), dtype=torch.float32)
    args = (frame, vp) if vp_input else (frame,)
    names = ["frame", "vp"] if vp_input else ["frame"]
    graph_bytes = trace_onnx(graph, args, names, ["road_prob"],
                             fold=vp_input)  # fixed mount: int16 taps stay small in the file
    model = onnx.load_from_string(graph_bytes)
    info = {"format": GRAPH_FORMAT, "checkpoint": str(checkpoint), "mode": geom["mode"],
            "camera": camera.to_dict(), "camera_name": camera.name, "opset": OPSET,
            "camera_given": camera_spec is not None or camera.name != "frames as they are",
            **({"camera_file": camera_spec} if camera_spec else {}),
            "inputs": {"frame": ["uint8", [h, w, 3], "BGR"], **({"vp": ["float32", [2], "u, v source px"]}
                                                                 if vp_input else {})},
            "output": {"road_prob": ["float32", [h, w]]}, "prob_of": predictor.output,
            **{k: geom[k] for k in ("work", "store_size", "completion", "ego_rows", "vp_input") if k in geom},
            **({"beyond": "hybrid"} if geom["mode"] == "virtual" else {})}  # vctrain predict's default rule
    if vp_input and geom["mode"] == "virtual":
        info["pose_range"] = list(pose_range)
    if check:
        ort = require("onnxruntime")
        rng = np.random.default_rng(0)
        test = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        feeds = {"frame": test, **({"vp": vp.numpy()} if vp_input else {})}
        got = _session(ort, graph_bytes).run(None, feeds)[0]
        with torch.no_grad():
            ref = graph(torch.from_numpy(test), *((vp,) if vp_input else ())).numpy()
        info["max_abs_diff_vs_torch"] = float(np.abs(got - ref).max())
    if int8:
        model, info["int8"] = _int8(model, (w, h), vp if vp_input else None, calib)
    entry = model.metadata_props.add()
    entry.key, entry.value = "vcseg", json.dumps(info)
    out = Path(out)
    try:
        onnx.save(model, str(out))
    except OSError as e:
        raise InputError(f"cannot write: {e.strerror or e}", out, "check the folder exists and is writable") from None
    return info


def _int8(model, size: tuple[int, int], vp: torch.Tensor | None, calib: str | Path | None):
    """(the int8 graph, its description) of the float graph ``model`` (:mod:`vctrain.deploy.quantize`)."""
    from .quantize import calibration_frames, quantize_graph

    frames, source = calibration_frames(calib, size)
    feeds = [{"frame": f, **({"vp": vp.numpy()} if vp is not None else {})} for f in frames]
    del model.metadata_props[:]  # (the description is added to the int8 graph)
    q, agreement = quantize_graph(model, feeds)
    return q, {"calibration": source, "frames": len(frames), "mask_agreement": agreement}
