"""A checkpoint's network on one image (:class:`Predictor`), and the store path.

The preprocessing is the checkpoint's own (no repeated flags):

- ``virtual`` models run on images of their virtual camera, resized to the working size if it
  differs; the road probability is back-projected to every source pixel
  (bilinear; pixels outside the training rectangle by the model's ``beyond`` rule, rays from the
  road VP by default: :func:`vctrain.predict.frames.back_to_frame`).
- ``resize`` baseline models: the image is resized to the working size, inferred, and the
  probability resized back (bilinear).
- ``mixed`` models (trained on both views, :class:`vctrain.training.trainset.MixedViews`): on a store item, the
  mean of the two, each in the item's original camera (the resize view at the checkpoint's
  ``resize_size``). Scored by studies on stores; frames, video and export take the other two modes.

New frames take one road (:mod:`vctrain.predict.road`, in memory). The store path is for stores:
:func:`predict_store` predicts the items of a store that exists (``vctrain predict --store``), and
:func:`warp_like_training` warps frames into a store exactly as the checkpoint's training store was
built (``--keep-store``; :mod:`vctrain.adapt`'s target stores), with the same rules as the road.
Outputs per image ``<stem>_prob.png`` (uint8, round(255 * P(road))) and ``<stem>_mask.png``
(255 where P(road) >= 0.5, else 0), both at the source image size. A model with two outputs
(:mod:`vctrain.training.outputs`) gives the one chosen (``output``: P(road) or P(drivable)) in their place.
"""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any, Callable, Iterable

import cv2
import numpy as np
import torch
from tqdm import tqdm

from vcprep.dataset import Job, collect_images
from vcprep.store import WarpSettings, record_magnification, warp_dataset
from vcprep.camera import Camera, FrameCameras, camera_from_dict, scale_matrix
from vcprep.errors import InputError
from vcprep.io import read_image
from vcprep.store import Store
from vcprep.vp import frame_poses

from ..training.checkpoint import load_checkpoint, model_from_checkpoint
from ..training.checkpoint_data import CheckpointData
from ..training.data import ray_angles, resize_pair, source_focal, to_input, vp_in_store, vp_proximity
from ..training.outputs import check_output, output_probability, output_probability_np
from ..networks.build import fold_batchnorm
from ..training.loop import resolve_device
from ..training.trainset import MIN_SIDE
from .bev import BevRun
from .frames import DEFAULT_BEYOND, NEEDS_CAMERA, back_to_frame, extends, refuse_mixed, warps_frames
from .road import RoadRun, frames_canvas, geometry_line, model_vp_rule, out_dir, run_road, virtual_within
from .written import write_prediction


class Predictor:
    """A checkpoint's model plus its input conventions."""

    beyond_rule = DEFAULT_BEYOND  # frame pixels outside the training rectangle (vctrain.predict.frames: BEYOND)
    takes_frames = False          # (vctrain.predict.kinds.RoadPredictor: a network on warped or resized frames)
    camera = None                 # (the frames' camera is given)

    def check_frame_size(self, size: tuple[int, int], name: str | Path | None = None) -> None:
        """Frames of any size are taken (warped or resized to the working size)."""

    def __init__(self, checkpoint: str | Path, device: str = "auto", engine: str = "torch", output: str = "road"):
        t0 = time.perf_counter()
        self.path = Path(checkpoint)
        self.ckpt = load_checkpoint(self.path)
        self.data = CheckpointData.from_dict(self.ckpt["data"])  # (read here, once)
        self.outputs = self.data.outputs  # the model's outputs; ``output`` the one it gives (use_output)
        self.output = check_output(output, self.outputs, self.path)
        self.device = resolve_device(device)
        # BN folded into the convs and the channels last: the same function, faster on a CPU (the
        # depthwise convs of lite0fpn most: benchmarks/speed/networks.py)
        self.model = fold_batchnorm(model_from_checkpoint(self.ckpt, self.path).to(self.device).eval())
        self.model = self.model.to(memory_format=torch.channels_last)
        self.size = self.data.input_size
        self.greyscale = self.data.greyscale >= 1.0
        self.vp_channel = self.data.vp_channel
        self.ray_channels = self.data.ray_channels
        self.engine, self.engine_note = "torch", ""
        self._onnx = None
        self.load_seconds = time.perf_counter() - t0  # the checkpoint read and the network built
        self.use_engine(engine)

    def use_engine(self, engine: str) -> str:
        """Run the network through ``engine`` (:data:`vctrain.deploy.engine.ENGINES`: 'torch', 'onnx' /
        'openvino' (the same network exported in memory, run in onnxruntime / OpenVINO) or 'auto':
        OpenVINO, else onnxruntime, on the CPU where installed); returns the one chosen, and
        :attr:`engine_note` says why auto chose torch on a CPU ('' otherwise). This class's default,
        torch, is what studies score (:data:`vctrain.predict.settings.STUDY_ENGINE`); ``vctrain
        predict`` and :func:`vctrain.load` take :data:`~vctrain.predict.settings.DEFAULT_ENGINE`."""
        from ..deploy.engine import OnnxNetwork, choose_engine, engine_note
        from ..study.hashing import file_sha256

        self.engine = choose_engine(engine, str(self.device))
        self.engine_note = engine_note(engine, str(self.device))
        self._onnx = None if self.engine == "torch" else \
            OnnxNetwork(self.model, engine=self.engine, key=file_sha256(self.path))
        return self.engine

    @property
    def compile_seconds(self) -> float:
        """Seconds spent exporting and compiling the network so far (an exported engine's: once per
        input size, on its first frame; 0 for torch)."""
        return self._onnx.export_seconds if self._onnx is not None else 0.0

    def logits(self, x: np.ndarray) -> torch.Tensor | np.ndarray:
        """The network's logits (1, K, h, w) float32 of one input array (C, h, w), through
        :attr:`engine`: a tensor on the device (torch), an array (onnx)."""
        if self._onnx is not None:
            return self._onnx(x[None])
        return self.model(self.network_input(x)).float()

    def use_output(self, output: str) -> str:
        """Give P(``output``) from now on ('road' or 'drivable'; a model without it: one line naming the fix)."""
        self.output = check_output(output, self.outputs, self.path)
        return self.output

    def road_softmax(self, x: np.ndarray) -> np.ndarray:
        """P(road) float32 (h, w): the softmax's class 1 of the logits of ``x`` (C, h, w); a two-output model's
        :attr:`output` (road: class 2, drivable: classes 1 and 2; :mod:`vctrain.training.outputs`). The onnx
        engine takes it in numpy: a torch operator between two onnxruntime calls wakes torch's
        OpenMP threads, which then spin on the cores onnxruntime needs (4x slower on 2 cores)."""
        logits = self.logits(x)
        if isinstance(logits, np.ndarray):
            return output_probability_np(logits[0], self.output)
        return output_probability(logits, self.output)[0].cpu().numpy().astype(np.float32)

    @property
    def mode(self) -> str:
        return self.data.mode

    def network_input(self, x: np.ndarray) -> torch.Tensor:
        """One input array (C, H, W; :func:`vctrain.training.data.to_input` and any extra channels) as the
        network takes it: a batch of one on the device, channels-last like the model."""
        return torch.from_numpy(x)[None].to(self.device).contiguous(memory_format=torch.channels_last)

    @torch.no_grad()
    def road_probability(self, image: np.ndarray, vp: tuple[float, float] | None = None,
                         size: tuple[int, int] | None = None, focal: tuple[float, float] | None = None) -> np.ndarray:
        """P(road) float32 at the size of ``image`` (any size; resized to the working size, or to
        ``size`` (w, h), and back). ``vp`` (image pixels) is needed for models with the VP channel,
        and with ``focal`` (the camera's f_x, f_y in image pixels) for models with ray channels."""
        h0, w0 = image.shape[:2]
        size = tuple(size) if size is not None else self.frame_working_size((w0, h0))
        img, _ = resize_pair(image, None, size)
        x = to_input(img, greyscale=self.greyscale)
        if self.vp_channel:
            if vp is None:
                raise InputError("this model needs the road vanishing point of each image (VP channel)", self.path,
                                 "give --camera so the VP follows from its pose, or predict a store")
            S = scale_matrix(size[0] / w0, size[1] / h0)
            v = S @ np.array([vp[0], vp[1], 1.0])
            x = np.concatenate([x, vp_proximity(size, (v[0], v[1]))[None]], axis=0)
        if self.ray_channels:
            if vp is None or focal is None:
                raise InputError("this model needs each image's road VP and focal length (ray channels)", self.path,
                                 "predict a store built with 'vcprep warp'")
            sx, sy = size[0] / w0, size[1] / h0
            v = scale_matrix(sx, sy) @ np.array([vp[0], vp[1], 1.0])  # (pixel centres, as the training's)
            x = np.concatenate([x, ray_angles(size, (v[0], v[1]), (focal[0] * sx, focal[1] * sy))], axis=0)
        prob = self.road_softmax(x)
        if (w0, h0) != size:
            prob = cv2.resize(prob, (w0, h0), interpolation=cv2.INTER_LINEAR)
        return prob

    def frame_working_size(self, frame_size: tuple[int, int]) -> tuple[int, int]:
        """The size (w, h) a frame of ``frame_size`` is resized to: the model's input size, or for a
        model trained with ``keep_aspect`` its pixel count at the frame's own aspect (as in training,
        :func:`vctrain.training.parts.resize_working_size`)."""
        if not self.data.keep_aspect:
            return self.size
        from ..training.parts import resize_working_size

        return resize_working_size(self.size, frame_size)

    def working_size(self, store_size: tuple[int, int], magnification: float | None = None) -> tuple[int, int]:
        """The working size for a store image of ``store_size``: the training store's own size
        gives the model's input size; a larger canvas of the same virtual camera (a test camera's
        footprint, :func:`vcprep.camera.virtual.same_camera_other_canvas`) keeps the training's
        pixels per degree, so the network runs on the whole canvas unresized (fully convolutional).
        ``magnification``: store pixels per source pixel of the frames' camera
        (:func:`vcprep.store.item_magnification`); where the warp enlarges the frames more than
        it did any training camera's, the size shrinks by :meth:`density_scale`."""
        trained = self.data.store_size
        if not trained or trained == tuple(store_size):
            w, h = self.size
        else:
            w, h = store_size[0] * self.size[0] / trained[0], store_size[1] * self.size[1] / trained[1]
        s = self.density_scale(magnification)
        return max(MIN_SIDE, int(round(w * s))), max(MIN_SIDE, int(round(h * s)))

    def density_scale(self, magnification: float | None) -> float:
        """The share of the working size a camera whose frames the warp enlarges ``magnification``
        times is run at: ``min(1, ref / magnification)``, ``ref`` the most any training camera was
        enlarged (``data['source_magnification']``, at least 1: the virtual camera's own density).
        A frame of fewer pixels than the canvas is then seen at the sharpness the network learned
        (issue 73: IDD-Lite's 320x227 frames, enlarged 2.2x, 49-68 % road IoU at full size, 79-80 %
        at this scale). 1 for models trained before the figure was recorded, and for None."""
        ref = self.data.source_magnification
        if not ref or not magnification:
            return 1.0
        return min(1.0, max(1.0, float(ref)) / float(magnification))

    def store_item(self, store: Store, rec: dict[str, Any]) -> np.ndarray:
        """P(road) in the item's ORIGINAL camera (source size), for every model mode."""
        if self.mode == "mixed":
            return 0.5 * (self._virtual_item(store, rec) + self._resized_item(rec, self.data.resize_size))
        if self.mode == "resize":
            return self._resized_item(rec, None)
        return self._virtual_item(store, rec)

    def _resized_item(self, rec: dict[str, Any], size: tuple[int, int] | None) -> np.ndarray:
        img = read_image(rec["source"]).array
        return self.road_probability(img, tuple(rec["vp"]) if rec.get("vp") else None, size, source_focal(rec))

    def _virtual_item(self, store: Store, rec: dict[str, Any]) -> np.ndarray:
        img = read_image(store.path(rec["image"])).array
        vs = store.params.get("virtual_scaled") or {}
        focal = (vs["fx"], vs["fy"]) if vs.get("fx") else None
        vp = vp_in_store(rec, store)
        m = record_magnification(rec, store.virtual) if vs else None  # (the frames' pixel density)
        size = self.working_size((img.shape[1], img.shape[0]), m)
        prob = self.road_probability(img, vp, size, focal)
        return back_to_frame(prob, rec, self.beyond_rule, vp, self._training_rect(store))

    def _training_rect(self, store: Store) -> tuple[float, float, float, float] | None:
        """The ``hybrid`` rule's training rectangle inside ``store``'s (grown) image, in store pixel
        centres (:meth:`vctrain.predict.frames.FramePredictor._training_rect`); None otherwise."""
        trained = self.data.virtual_scaled
        if self.beyond_rule != "hybrid" or not trained:
            return None
        ox = float(store.params["virtual_scaled"]["cx"]) - float(trained["cx"])
        w, h = self.data.store_size
        return (ox, 0.0, ox + w - 1.0, h - 1.0)


def predict_store(predictor: Predictor, store: Store, out: str | Path, progress: bool = True,
                  ids: Iterable[str] | None = None, overlay: bool = False, bev: Any = None) -> list[Path]:
    """Predict every item of ``store`` (or those in ``ids``); writes ``<id>_mask.png`` and
    ``<id>_prob.png`` at the source image size. Returns the mask paths. ``bev`` (given: a
    :class:`vctrain.predict.bev.BevRun`): each item's BEV and road in metres too, at the pose of the
    VP its record holds."""
    out = out_dir(out)
    if predictor.mode in ("virtual", "mixed"):
        from vcprep.camera import same_camera_other_canvas

        sp = predictor.data.store_params or {}
        if store.params.get("scale") != sp.get("scale"):
            raise InputError("store has another scale than the model's training store", store.root,
                             "predict from the images with --camera (they are warped as the model expects)")
        other_rectangle = (getattr(predictor, "beyond_rule", None) is not None
                           and same_camera_other_canvas(store.params.get("virtual"), sp.get("virtual")))
        if store.params.get("virtual") != sp.get("virtual") and not other_rectangle:
            raise InputError("store has another virtual camera than the model's training store", store.root,
                             "predict from the images with --camera (they are warped as the model expects)")
    written = []
    recs = list(store) if ids is None else [store.get(i) for i in ids]
    for rec in tqdm(recs, desc="predict", unit="img", disable=None if progress else True, leave=False):
        prob = predictor.store_item(store, rec)
        inset = bev.write(out, rec["id"], prob, rec["source"], rec.get("vp"), rec.get("vp_status")) \
            if bev is not None else None
        written.append(write_prediction(out, rec["id"], prob, rec["source"] if overlay else None, inset)[0])
    return written


def predict_frames(predictor: Any, images: Iterable[str | Path], out: str | Path,
                   camera: Camera | FrameCameras | None, progress: bool = True, keep_store: str | Path | None = None,
                   overlay: bool = False, within: str = "auto", vp_rule: Any = None,
                   say: Callable[[str], None] | None = None, ego_source: str = "",
                   vehicle: tuple[int, int] | dict | None = None, bev: Any = None) -> RoadRun:
    """Image files/folders through the one road for a frame (:func:`vctrain.predict.road.run_road`:
    a frame that fails is named and skipped); with ``keep_store`` (a model that warps frames) the
    warped frames are also kept as a store there, and predicted from it (the same masks). ``vp_rule``,
    ``say``, ``ego_source``, ``vehicle`` and ``bev`` as :func:`~vctrain.predict.road.run_road` takes them."""
    refuse_mixed(predictor)
    if keep_store is None or not warps_frames(predictor):
        return run_road(predictor, images, out, camera, progress=progress, overlay=overlay, within=within,
                        vp_rule=vp_rule, say=say, ego_source=ego_source, vehicle=vehicle, bev=bev)
    if camera is None:
        raise InputError("a virtual-camera model needs the camera of the images", None,
                         NEEDS_CAMERA)
    jobs = collect_images(images)
    store = warp_like_training(predictor.data, predictor.path, jobs, camera, keep_store, within, progress,
                               extend=extends(predictor), vp_rule=vp_rule)
    if say is not None:
        say(geometry_line(warp_geometry(store), model_vp_rule(predictor.data, vp_rule)[1], ego_source))
    bev_run = BevRun(bev, camera, within) if bev is not None else None
    return RoadRun(predict_store(predictor, store, out, progress, ids=[j.id for j in jobs], overlay=overlay,
                                 bev=bev_run))


def predict_images(predictor: Any, images: Iterable[str | Path], out: str | Path,
                   camera: Camera | FrameCameras | None, progress: bool = True, keep_store: str | Path | None = None,
                   overlay: bool = False, within: str = "auto", vp_rule: Any = None) -> list[Path]:
    """:func:`predict_frames`, returning the mask paths; a frame that failed raises its error (after
    the other frames are predicted)."""
    run = predict_frames(predictor, images, out, camera, progress, keep_store, overlay, within, vp_rule)
    if run.failed:
        raise run.failed[0][1]
    return run.written


def warp_like_training(data: CheckpointData, path: str | Path, jobs: list[Job], camera: Camera | FrameCameras,
                       root: str | Path, within: str = "auto", progress: bool = True, extend: bool = True,
                       vp_rule: Any = None) -> Store:
    """Warp image ``jobs`` of ``camera`` into the store ``root`` exactly as the training store of
    a checkpoint (its ``data``; ``path`` names it in errors) was built: same code, virtual
    camera, scale and completion. ``within``: per-image pan/tilt from the road VP ('estimate',
    a CSV ``id,u,v``, 'none'; 'auto': :func:`vctrain.predict.road.virtual_within`), estimated
    together (:func:`vcprep.vp.frame_poses`) with ``vp_rule`` or the model's
    (:func:`vctrain.predict.road.model_vp_rule`). ``extend``: the virtual camera's rectangle extended
    to hold every frame (:func:`vctrain.predict.road.frames_canvas`); False keeps the training's
    rectangle (what a prior, an image of that rectangle, needs)."""
    sp = data.store_params
    if not data.virtual:
        raise InputError("model was not trained in a virtual camera (a resize baseline)", path,
                         "use a model trained on a store built by 'vcprep warp'")
    virtual = camera_from_dict(sp["virtual"], path)
    within = virtual_within(data, within, camera)
    if isinstance(camera, FrameCameras):
        for j in jobs:  # every frame's calibration file exists: an error before anything is written
            camera.file_for(j.image)
    poses, _ = frame_poses(jobs, camera, within, model_vp_rule(data, vp_rule)[0])
    if extend:
        virtual = frames_canvas(virtual, jobs, camera, poses)
    settings = WarpSettings(camera=camera, virtual=virtual, scale=float(sp["scale"]),
                            completion=data.completion, poses=poses, progress=progress)
    store, _ = warp_dataset(jobs, root, settings)
    return store


def warp_geometry(store: Store) -> dict[str, Any]:
    """What the frames of ``store`` were warped with, read from its records: the VPs (statuses and
    the rule of the estimated ones), the own vehicle's rows and the virtual rectangle. What a
    study's result records and ``vctrain predict`` says."""
    from collections import Counter

    recs = list(store)
    rules = {json.dumps(r["vp_rule"], sort_keys=True) for r in recs if r.get("vp_rule")}
    return {"vp_status": dict(sorted(Counter(r.get("vp_status", "camera") for r in recs).items())),
            "vp_rule": json.loads(rules.pop()) if len(rules) == 1 else sorted(map(json.loads, rules)) or None,
            "ego_rows": sorted({int(r.get("ego_rows", 0)) for r in recs}),
            "rectangle": list(store.params["virtual"]["image_size"])}
