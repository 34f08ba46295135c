"""Prediction: original images in, road mask and probability map of the original camera out.

The preprocessing is the checkpoint's own (no repeated flags):

- ``virtual`` models: the images are warped into the checkpoint's virtual camera at its scale with
  the training store's completion method (:func:`vcprep.build.warp_dataset` into a temporary store,
  so the input is bit-for-bit what training saw), resized to the working size if it differs,
  inferred, and the road probability is back-projected to every source pixel
  (:func:`vcprep.backproject.backproject_array`, bilinear; pixels outside the virtual image get 0).
- ``resize`` baseline models: the image is resized to the working size, inferred, and the
  probability resized back (bilinear).

Outputs per image ``<stem>_prob.png`` (uint8, round(255 * P(road))) and ``<stem>_mask.png``
(255 where P(road) >= 0.5, else 0), both at the source image size.
"""
from __future__ import annotations

import json
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterable

import cv2
import numpy as np
import torch
from tqdm import tqdm

from vcprep.backproject import backproject_array
from vcprep.build import Job, WarpSettings, warp_dataset
from vcprep.camera import Camera, FrameCameras, camera_from_dict, camera_of_image, scale_matrix
from vcprep.dataset import collect_images  # re-exported: the one image collection of vcprep and vctrain
from vcprep.errors import InputError
from vcprep.homography import vp_from_pose
from vcprep.imageio import read_image, write_png
from vcprep.store import Store

from .checkpoint import load_checkpoint, model_from_checkpoint
from .data import resize_pair, to_input, vp_in_store, vp_proximity
from .train import resolve_device

__all__ = ["Predictor", "collect_images", "predict_images", "predict_store", "write_prediction", "warp_like_training",
           "frames_canvas", "within_mode", "model_vp_rule", "warp_geometry", "geometry_line"]


class Predictor:
    """A checkpoint's model plus its input conventions."""

    fixed_rectangle = False  # a model runs on any rectangle of its virtual camera (a prior: True, one image)

    def __init__(self, checkpoint: str | Path, device: str = "auto"):
        self.path = Path(checkpoint)
        self.ckpt = load_checkpoint(self.path)
        self.data: dict[str, Any] = self.ckpt["data"]
        self.device = resolve_device(device)
        self.model = model_from_checkpoint(self.ckpt, self.path).to(self.device).eval()
        self.size = tuple(self.data["input_size"])
        self.greyscale = float(self.data.get("greyscale", 0.0)) >= 1.0
        self.vp_channel = bool(self.data.get("vp_channel", False))

    @property
    def mode(self) -> str:
        return self.data["mode"]

    @torch.no_grad()
    def road_probability(self, image: np.ndarray, vp: tuple[float, float] | None = None,
                         size: tuple[int, int] | None = None) -> np.ndarray:
        """P(road) float32 at the size of ``image`` (any size; resized to the working size, or to
        ``size`` (w, h), and back). ``vp`` (image pixels) is needed for models with the VP channel."""
        h0, w0 = image.shape[:2]
        size = tuple(size) if size is not None else self.size
        img, _ = resize_pair(image, None, size)
        x = to_input(img, greyscale=self.greyscale)
        if self.vp_channel:
            if vp is None:
                raise InputError("this model needs the road vanishing point of each image (VP channel)", self.path,
                                 "give --camera so the VP follows from its pose, or predict a store")
            S = scale_matrix(size[0] / w0, size[1] / h0)
            v = S @ np.array([vp[0], vp[1], 1.0])
            x = np.concatenate([x, vp_proximity(size, (v[0], v[1]))[None]], axis=0)
        logits = self.model(torch.from_numpy(x)[None].to(self.device))
        prob = torch.softmax(logits.float(), dim=1)[0, 1].cpu().numpy().astype(np.float32)
        if (w0, h0) != size:
            prob = cv2.resize(prob, (w0, h0), interpolation=cv2.INTER_LINEAR)
        return prob

    def working_size(self, store_size: tuple[int, int]) -> tuple[int, int]:
        """The working size for a store image of ``store_size``: the training store's own size
        gives the model's input size; a larger canvas of the same virtual camera (a test camera's
        footprint, :func:`vcprep.virtual_camera.same_camera_other_canvas`) keeps the training's
        pixels per degree, so the network runs on the whole canvas unresized (fully convolutional)."""
        trained = (self.data.get("store_params") or {}).get("store_size")
        if not trained or tuple(trained) == tuple(store_size):
            return self.size
        return (max(1, int(round(store_size[0] * self.size[0] / trained[0]))),
                max(1, int(round(store_size[1] * self.size[1] / trained[1]))))

    def store_item(self, store: Store, rec: dict[str, Any]) -> np.ndarray:
        """P(road) in the item's ORIGINAL camera (source size), for either model mode."""
        if self.mode == "resize":
            img = read_image(rec["source"]).array
            return self.road_probability(img, tuple(rec["vp"]) if rec.get("vp") else None)
        img = read_image(store.path(rec["image"])).array
        prob = self.road_probability(img, vp_in_store(rec, store), self.working_size((img.shape[1], img.shape[0])))
        return np.clip(backproject_array(prob, rec, kind="prob"), 0.0, 1.0)


def write_prediction(out: Path, stem: str, prob: np.ndarray, overlay_on: str | Path | None = None) -> tuple[Path, Path]:
    """Write ``<stem>_prob.png`` (0-255) and ``<stem>_mask.png`` (0/255); with ``overlay_on``
    (the original image) also ``<stem>_overlay.png``: predicted road in green over the image."""
    p8 = np.clip(np.rint(prob * 255.0), 0, 255).astype(np.uint8)
    mask = np.where(prob >= 0.5, 255, 0).astype(np.uint8)
    pp, mp = out / f"{stem}_prob.png", out / f"{stem}_mask.png"
    write_png(pp, p8)
    write_png(mp, mask, kind="mask")
    if overlay_on is not None:
        from vcprep.figures import overlay_label

        write_png(out / f"{stem}_overlay.png", overlay_label(read_image(overlay_on).array, (mask > 0).astype(np.uint8)),
                  level=3)
    return mp, pp


def _out_dir(out: str | Path) -> Path:
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a directory", out, "choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    return out


def predict_store(predictor: Predictor, store: Store, out: str | Path, progress: bool = True,
                  ids: Iterable[str] | None = None, overlay: bool = False) -> list[Path]:
    """Predict every item of ``store`` (or those in ``ids``); writes ``<id>_mask.png`` and
    ``<id>_prob.png`` at the source image size. Returns the mask paths."""
    out = _out_dir(out)
    if predictor.mode == "virtual":
        from vcprep.virtual_camera import same_camera_other_canvas

        sp = predictor.data.get("store_params") or {}
        if store.params.get("scale") != sp.get("scale"):
            raise InputError("store has another scale than the model's training store", store.root,
                             "predict from the images with --camera (they are warped as the model expects)")
        other_rectangle = (not predictor.fixed_rectangle
                           and same_camera_other_canvas(store.params.get("virtual"), sp.get("virtual")))
        if store.params.get("virtual") != sp.get("virtual") and not other_rectangle:
            raise InputError("store has another virtual camera than the model's training store", store.root,
                             "predict from the images with --camera (they are warped as the model expects)")
    written = []
    recs = list(store) if ids is None else [store.get(i) for i in ids]
    for rec in tqdm(recs, desc="predict", unit="img", disable=None if progress else True, leave=False):
        written.append(write_prediction(out, rec["id"], predictor.store_item(store, rec),
                                        rec["source"] if overlay else None)[0])
    return written


def predict_images(predictor: Predictor, images: Iterable[str | Path], out: str | Path,
                   camera: Camera | FrameCameras | None,
                   progress: bool = True, keep_store: str | Path | None = None, overlay: bool = False,
                   within: str = "auto", vp_rule: Any = None, say: Callable[[str], None] | None = None,
                   ego_source: str = "") -> list[Path]:
    """Predict image files/folders taken with ``camera`` (needed for virtual-camera models; a
    :class:`~vcprep.camera.FrameCameras` gives every image its own calibrated camera and pose).

    ``within``: per-image pan/tilt from the road VP, as for ``vcprep warp --within``
    ('estimate', a CSV ``id,u,v``, 'none'); 'auto' estimates VPs when the model's training store
    used per-image VPs and uses the camera's average pose otherwise; estimated VPs follow
    ``vp_rule`` or the model's (:func:`model_vp_rule`). ``say`` (given) gets one line saying the
    VPs, own vehicle (``ego_source``: where its rows come from) and rectangle used (:func:`geometry_line`)."""
    jobs = collect_images(images)
    out = _out_dir(out)
    if predictor.mode == "resize":
        written = []
        for job in tqdm(jobs, desc="predict", unit="img", disable=None if progress else True, leave=False):
            img = read_image(job.image).array
            vp = None
            if camera is not None and predictor.vp_channel:
                vp = vp_from_pose(camera_of_image(camera, job.image, (img.shape[1], img.shape[0])))
            written.append(write_prediction(out, job.id, predictor.road_probability(img, vp),
                                            job.image if overlay else None)[0])
        return written
    if camera is None:
        raise InputError("a virtual-camera model needs the camera of the images", None,
                         "add --camera (preset or calibration file)")
    with tempfile.TemporaryDirectory(prefix="vctrain-predict-") as tmp:
        root = Path(keep_store) if keep_store else Path(tmp) / "store"
        # a prior is an image of the training rectangle: its frames are warped into that rectangle as it is
        store = warp_like_training(predictor.data, predictor.path, jobs, camera, root, within, progress,
                                   extend=not predictor.fixed_rectangle, vp_rule=vp_rule)
        if say is not None:
            say(geometry_line(warp_geometry(store), model_vp_rule(predictor.data, vp_rule)[1], ego_source))
        return predict_store(predictor, store, out, progress, ids=[j.id for j in jobs], overlay=overlay)


def frames_canvas(virtual: Camera, jobs: list[Job], camera: Camera | FrameCameras,
                  poses: dict | None) -> Camera:
    """The training's virtual camera, its rectangle extended to hold every frame of ``jobs`` at its
    camera's average pose and at the pose it is warped with (``poses``: :func:`vcprep.build.frame_poses`;
    :func:`vcprep.virtual_camera.extend_canvas`): a camera wider or steeper than the training
    cameras is predicted whole, at the training's pixels per degree. The one rectangle rule of
    ``vctrain predict``, a video (:class:`vctrain.frames.FramePredictor`) and a study's test stores."""
    from vcprep.homography import pose_from_vp
    from vcprep.imageio import image_size
    from vcprep.virtual_camera import extend_canvas

    views, seen = [], set()
    for j in jobs:
        cam = camera_of_image(camera, j.image, image_size(j.image))
        for pan, tilt in ((cam.pan, cam.tilt), pose_from_vp(cam, poses[j.id].vp) if poses else (cam.pan, cam.tilt)):
            key = (cam, round(pan, 3), round(tilt, 3))
            if key not in seen:
                seen.add(key)
                views.append((cam, pan, tilt))
    return extend_canvas(virtual, views)


def within_mode(data: dict[str, Any], camera: Any, within: str = "auto") -> str:
    """'estimate', 'none' or a CSV path: ``within`` as given, 'auto' as the model (its ``data``) was
    trained -- per-frame VPs estimated when its training stores had estimated or given ones, for one
    camera (a per-frame calibration folder's poses are its own), else the camera's average pose."""
    if within != "auto":
        return within
    trained = set(data.get("vp_status", [])) - {"camera", "calibrated"}
    return "estimate" if data.get("mode") == "virtual" and trained and isinstance(camera, Camera) else "none"


def model_vp_rule(data: dict[str, Any], override: Any = None) -> tuple[Any, str]:
    """(the :class:`~vcprep.vanishing_point.VPRule` frames are estimated with, where it comes from):
    ``override`` (given), else the rule the model's training VPs were found with, else the
    detector's defaults (a model whose stores record none)."""
    from vcprep.vanishing_point import VPRule

    if override is not None:
        return override, "the given"
    recorded = VPRule.from_dict(data.get("vp_rule"))
    return (recorded, "the model's") if recorded is not None else (VPRule(), "the detector's defaults")


def warp_like_training(data: dict[str, Any], path: str | Path, jobs: list[Job], camera: Camera | FrameCameras,
                       root: str | Path, within: str = "auto", progress: bool = True, extend: bool = True,
                       vp_rule: Any = None) -> Store:
    """Warp image ``jobs`` of ``camera`` into the store ``root`` exactly as the training store of
    a checkpoint (its ``data``; ``path`` names it in errors) was built: same code, virtual
    camera, scale and completion. ``within``: per-image pan/tilt from the road VP ('estimate',
    a CSV ``id,u,v``, 'none'; 'auto': :func:`within_mode`), estimated together
    (:func:`vcprep.build.frame_poses`) with ``vp_rule`` or the model's (:func:`model_vp_rule`).
    ``extend``: the virtual camera's rectangle extended to hold every frame (:func:`frames_canvas`);
    False keeps the training's rectangle (what a prior, an image of that rectangle, needs)."""
    from vcprep.build import frame_poses

    sp = data.get("store_params")
    if data.get("mode") != "virtual" or not sp:
        raise InputError("model was not trained in a virtual camera (a resize baseline)", path,
                         "use a model trained on a store built by 'vcprep warp'")
    virtual = camera_from_dict(sp["virtual"], path)
    within = within_mode(data, camera, within)
    if within != "none" and not isinstance(camera, Camera):
        raise InputError("--within needs one camera; a per-frame calibration folder already gives every frame its "
                         "exact pose", camera.folder, "drop --within, or give one camera file or preset")
    if isinstance(camera, FrameCameras):
        for j in jobs:  # every frame's calibration file exists: an error before anything is written
            camera.file_for(j.image)
    poses, _ = frame_poses(jobs, camera, within, model_vp_rule(data, vp_rule)[0])
    if extend:
        virtual = frames_canvas(virtual, jobs, camera, poses)
    settings = WarpSettings(camera=camera, virtual=virtual, scale=float(sp["scale"]),
                            completion=data.get("completion", "none"), poses=poses, progress=progress)
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


def geometry_line(geo: dict[str, Any], rule_source: str = "", ego_source: str = "") -> str:
    """One line for stderr from :func:`warp_geometry`: 'VPs: 2 accepted, 1 fallback (the model's rule:
    ...); own vehicle: 3 bottom rows (the camera's ego_rows); virtual rectangle 554x240'."""
    from vcprep.vanishing_point import VPRule

    counts = ", ".join(f"{n} {k}" for k, n in geo["vp_status"].items())
    rule = VPRule.from_dict(geo["vp_rule"]) if isinstance(geo["vp_rule"], dict) else None
    vps = f"VPs: {counts}" + (f" ({rule_source + ' rule: ' if rule_source else ''}{rule.describe()})" if rule else "")
    rows = "/".join(map(str, geo["ego_rows"]))
    ego = (f"own vehicle: {rows} bottom rows never warped" if geo["ego_rows"] != [0] else "own vehicle: none")
    ego += f" ({ego_source})" if ego_source else ""
    return f"{vps}; {ego}; virtual rectangle {geo['rectangle'][0]}x{geo['rectangle'][1]}"
