"""Per-frame prediction in memory: one BGR frame in, P(road) of the original camera out.

:class:`FramePredictor` does for one decoded frame (a video frame) what ``vctrain predict`` does
for an image file through a store (:func:`vctrain.predict.predictor.warp_like_training`), with the
same code and the same numbers: the frame's pose (the camera's average pose, or its own road VP),
``virt_H_src`` and its fold check (:func:`vcprep.store.build.item_geometry`), the warp + the checkpoint's
completion in one remap (:func:`vcprep.store.build.warp_arrays`, the body of the store build; maps are
cached, so a fixed pose builds them once), the network on the warped uint8 image (what the store's
PNG holds, bit for bit) and the back-projection (:func:`back_to_frame`).

What a frame pixel that lands outside the training rectangle gets is the model's ``beyond`` rule
(:data:`BEYOND`; ``vctrain predict --beyond``; measured by benchmarks/archive/other_cameras/low_camera.py):

* ``extend``: the rectangle grown
  to hold the frame's lower half at its pose (:func:`vcprep.camera.virtual.extend_canvas`; a
  folder's frames share the rectangle of :func:`vctrain.predict.road.rectangle_views`; a later
  video frame whose pose does not fit grows it), the network run on rows no training image filled;
* ``rays``: the network runs on the training rectangle only; such a pixel takes P(road) where the
  ray from the road VP through it leaves the rectangle (:func:`vcprep.warp.backproject.backproject_rays`:
  the projective completion's rule run backwards; road edges are lines through the VP);
* ``hybrid`` (the default, :data:`vctrain.predict.settings.DEFAULT_BEYOND`; what a study scores): the
  network on the grown rectangle (its context), such a pixel by the rays from the training
  rectangle's edge within it.

The geometric prior (an image of the training rectangle) gives such pixels 0.

:class:`StreamingVPs` gives a video's frames their road VPs with the sequence rules of
:mod:`vcprep.vp` (:func:`~vcprep.vp.estimate_vp`,
:func:`~vcprep.vp.apply_reliability`, :func:`~vcprep.vp.smooth_sequences`)
run over a sliding window instead of the whole sequence: a frame's VP is final once ``window``
later frames are seen.

:class:`StageTimes` adds up the seconds spent per stage (VP, warp, network, back-projection).
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np

from vcprep.warp import backproject_array, backproject_rays
from vcprep.store import item_magnification, store_params
from vcprep.camera import Camera, camera_from_dict
from vcprep.errors import InputError
from vcprep.warp import frame_pose, vp_from_pose, warp_at_pose
from vcprep.vp import VPConfig, VPResult, apply_reliability, estimate_vp, smooth_sequences
from vcprep.camera import extend_canvas

from ..training.data import vp_in_store
from .kinds import RoadPredictor
from .settings import BEYOND, DEFAULT_BEYOND

__all__ = ["StageTimes", "FramePredictor", "StreamingVPs", "warps_frames", "reads_road_vps", "BEYOND",
           "DEFAULT_BEYOND", "extends", "back_to_frame",
           "reads_frames_as_they_are"]


# the fix of every "this model needs the camera of the frames" error: an uncalibrated camera is estimated
NEEDS_CAMERA = "add --camera: a preset, a calibration file, or 'estimate' (from these frames, no calibration needed)"


@dataclass
class StageTimes:
    """Seconds spent per stage, summed over ``frames`` frames (a benchmark reads them)."""

    vp: float = 0.0           # road VP estimation (per-frame VPs only)
    warp: float = 0.0         # pose, homography, warp + completion into the virtual camera
    network: float = 0.0      # resize to the working size, the network, softmax
    backproject: float = 0.0  # virtual -> original camera
    frames: int = 0

    def per_frame_ms(self) -> dict[str, float]:
        """Milliseconds per frame of each stage."""
        n = max(1, self.frames)
        return {k: 1000.0 * getattr(self, k) / n for k in ("vp", "warp", "network", "backproject")}


class FramePredictor:
    """P(road) of single frames of one camera, in memory (module docstring).

    ``predictor``: a :class:`vctrain.predict.Predictor` (virtual or resize model), a
    :class:`vctrain.adapt.PriorPredictor` or a graph that takes whole frames
    (:class:`vctrain.deploy.OnnxPredictor`: ``takes_frames``); ``camera``: the frames' camera (any
    size; rescaled to ``frame_size`` (w, h)); ``poses``: (pan, tilt) of frames to come, which the
    virtual rectangle is extended for in advance (the camera's average pose always is); ``views``
    instead: exactly the (camera, pan, tilt) views the rectangle is extended for (a folder's, of
    every camera in it, so that all its frames share one rectangle). ``ego_rows``: a model that
    reads frames as they are (resize) predicts 'not road' on these bottom rows of the frame, the own
    vehicle (a virtual-camera model never warps the camera's ``ego_rows``)."""

    def __init__(self, predictor: RoadPredictor, camera: Camera | None, frame_size: tuple[int, int],
                 poses: Iterable[tuple[float, float]] = (),
                 views: list[tuple[Camera, float, float]] | None = None, ego_rows: int = 0):
        refuse_mixed(predictor)
        self.predictor = predictor
        self.size = (int(frame_size[0]), int(frame_size[1]))
        self.ego_rows = int(ego_rows)
        self.camera = camera.for_image_size(self.size) if camera is not None else None
        self.times = StageTimes()
        self.virtual: Camera | None = None
        if not warps_frames(predictor):
            return  # a resize model needs no camera (only its VP channel does); a graph warps inside
        if self.camera is None:
            raise InputError("a virtual-camera model needs the camera of the frames", predictor.path,
                             NEEDS_CAMERA)
        sp = predictor.data.store_params
        if not sp:
            raise InputError("model has no training store parameters", predictor.path,
                             "use a model trained on a store built by 'vcprep warp'")
        self._trained = camera_from_dict(sp["virtual"], predictor.path)
        self._scale = float(sp["scale"])
        self._completion = predictor.data.completion
        self._beyond = predictor.beyond_rule  # None: the prior (0 outside its rectangle)
        self._extend = self._beyond in ("extend", "hybrid")
        if views is not None:
            self._views = list(views)
        else:
            self._views = [(self.camera, self.camera.pan, self.camera.tilt)]
            self._views += [(self.camera, float(p), float(t)) for p, t in poses]
        self._set_virtual(extend_canvas(self._trained, self._views) if self._extend else self._trained)

    def _set_virtual(self, virtual: Camera) -> None:
        self.virtual = virtual
        params = store_params(virtual, self._scale)
        # the scaled camera exactly as a store holds it (Store.virtual reads this dict)
        self._virtual_scaled = camera_from_dict(params["virtual_scaled"])
        self.store_size = (int(params["store_size"][0]), int(params["store_size"][1]))
        # store pixels per frame pixel: the network's working size shrinks where the frames are enlarged
        self.magnification = item_magnification(self.camera, self.size, self._virtual_scaled)

    def _training_rect(self) -> tuple[float, float, float, float] | None:
        """The training rectangle inside the (grown) store image, in store pixel centres: where the
        ``hybrid`` rule's rays stop (None for the other rules: the store image's own edge)."""
        if self._beyond != "hybrid":
            return None
        trained = store_params(self._trained, self._scale)
        ox = self._virtual_scaled.cx - float(trained["virtual_scaled"]["cx"])  # the rectangle grows left, right, down
        return (ox, 0.0, ox + trained["store_size"][0] - 1.0, trained["store_size"][1] - 1.0)

    def _fit_canvas(self, pan: float, tilt: float) -> None:
        """Grow the rectangle when the frame at (pan, tilt) does not fit: the training's rectangle
        extended for every view that ever grew it (a view that fits changes no extension)."""
        view = (self.camera, pan, tilt)
        if extend_canvas(self.virtual, [view]) is not self.virtual:
            self._views.append(view)
            self._set_virtual(extend_canvas(self._trained, self._views))

    def _check(self, frame: np.ndarray) -> None:
        """A frame as an image file decodes (:func:`vcprep.io.read_image`): grey or BGR, 8 or 16 bit."""
        if frame.ndim not in (2, 3) or (frame.ndim == 3 and frame.shape[2] != 3) or frame.dtype not in (np.uint8,
                                                                                                       np.uint16):
            raise InputError(f"frame is {frame.dtype} {frame.shape}, expected BGR or grey uint8/uint16", None,
                             "give decoded frames")
        if (frame.shape[1], frame.shape[0]) != self.size:
            raise InputError(f"frame is {frame.shape[1]}x{frame.shape[0]} but the predictor is for "
                             f"{self.size[0]}x{self.size[1]}", None, "make one FramePredictor per frame size")

    def warp(self, frame: np.ndarray, vp: tuple[float, float] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """The frame in the virtual camera (uint8, what a store would hold) and the store record
        fields that describe it (``H``, ``size``, ``store_size``, ``vp``, ``pan_deg``, ``tilt_deg``),
        as :func:`vcprep.store.build.build_item` computes them. ``vp``: the frame's own road VP (source
        pixels); None: the camera's average pose."""
        self._check(frame)
        vp, pan, tilt = frame_pose(self.camera, vp)
        if self._extend:
            self._fit_canvas(pan, tilt)
        item, _, rec = warp_at_pose(frame, self.camera, self._virtual_scaled, self.store_size, self._completion, vp,
                                    pan, tilt)
        return item.image, rec

    def predict(self, frame: np.ndarray, vp: tuple[float, float] | None = None) -> np.ndarray:
        """P(road) float32 (h, w) at the frame's size; ``vp`` as in :meth:`warp` (a resize model
        with the VP channel takes it, else the camera's average-pose VP)."""
        p = self.predictor
        t0 = time.perf_counter()
        if not warps_frames(p):
            self._check(frame)
            if vp is None and p.vp_channel and self.camera is not None:
                vp = vp_from_pose(self.camera)
            prob = p.road_probability(frame, vp)
            if self.ego_rows:
                prob[prob.shape[0] - self.ego_rows:] = 0.0
            self.times.network += time.perf_counter() - t0
            self.times.frames += 1
            return prob
        img, rec = self.warp(frame, vp)
        t1 = time.perf_counter()
        if hasattr(p, "road_probability"):
            prob = p.road_probability(img, vp_in_store(rec), p.working_size(self.store_size, self.magnification))
        else:  # the geometric prior: P(road) is p_g itself
            prob = p.prior
        t2 = time.perf_counter()
        out = back_to_frame(prob, rec, self._beyond, rect=self._training_rect())
        t3 = time.perf_counter()
        self.times.warp += t1 - t0
        self.times.network += t2 - t1
        self.times.backproject += t3 - t2
        self.times.frames += 1
        return out


def extends(predictor: RoadPredictor) -> bool:
    """Whether frames are warped into a rectangle grown to hold them (``extend``, ``hybrid``) rather
    than the training's (``rays``; the prior's one image)."""
    return warps_frames(predictor) and predictor.beyond_rule in ("extend", "hybrid")


def back_to_frame(prob: np.ndarray, rec: dict[str, Any], beyond: str | None,
                  vp_store: tuple[float, float] | None = None,
                  rect: tuple[float, float, float, float] | None = None) -> np.ndarray:
    """P(road) of a store-sized map in the frame of the store record ``rec`` (float32 in [0, 1]):
    bilinear, and outside the store by the ``beyond`` rule (module docstring: ``rays``/``hybrid``
    from the road VP in store pixels, ``vp_store``, else the record's, to the store's edge or
    ``rect``'s; otherwise 0)."""
    if beyond in ("rays", "hybrid"):
        out = backproject_rays(prob, rec, vp_in_store(rec) if vp_store is None else vp_store, rect=rect)
    else:
        out = backproject_array(prob, rec, kind="prob")
    return np.clip(out, 0.0, 1.0)


def refuse_mixed(predictor: RoadPredictor) -> None:
    """A mixed-view or ray-channel model (issue 53's study candidates) predicts store items only (the
    two views averaged per store record; the record's camera gives the rays): one clear error for
    frames, video and export."""
    if predictor.mode == "mixed":
        raise InputError("a mixed-view model (trained on both views) predicts store items only", predictor.path,
                         "predict a store with --store, or use a virtual-camera or resize model")
    if predictor.ray_channels:
        raise InputError("a ray-channel model predicts store items only (their records give each camera)",
                         predictor.path, "predict a store with --store, or use a model without ray channels")


def warps_frames(predictor: RoadPredictor) -> bool:
    """Whether frames are warped into a virtual camera before ``predictor`` sees them: a virtual-camera
    model or the prior, not a resize model nor a graph that holds its warp inside."""
    return predictor.mode == "virtual" and not predictor.takes_frames


def reads_frames_as_they_are(predictor: RoadPredictor) -> bool:
    """A model (not a graph) that neither warps frames nor reads their road VPs: a resize model."""
    return not predictor.takes_frames and not warps_frames(predictor) and not reads_road_vps(predictor)


def reads_road_vps(predictor: RoadPredictor) -> bool:
    """Whether ``predictor`` sees each frame's road VP: it warps frames (:func:`warps_frames`), or it is a
    resize model with the VP channel (crossval's ``resize-vp``). Its own vehicle then counts as for the
    study's stores: the bonnet's rows are left out of the VP estimate."""
    return warps_frames(predictor) or bool(predictor.vp_channel or predictor.ray_channels)


@dataclass
class StreamingVPs:
    """Road VPs of a video's frames, in order, with the sequence rules over a sliding window.

    :meth:`push` estimates a frame's VP (:func:`~vcprep.vp.estimate_vp`) and returns
    the frames whose VP is now final: those with ``window`` later frames seen. A final VP is what
    :func:`~vcprep.vp.apply_reliability` and
    :func:`~vcprep.vp.smooth_sequences` (``window`` frames either side) give over the
    frames held: the last ``memory`` frames before it and the ``window`` after it. So a frame's
    smoothed VP equals the whole-video rule's whenever a neighbour's VP is accepted (smoothing
    takes the median of the accepted ones); a rejected frame without one falls back to the mean
    of the accepted VPs of the last ``memory`` frames (the whole-video rule: of the whole video).
    Frames that could not be decoded are simply not pushed. :meth:`flush` ends the video."""

    camera: Camera              # the camera at the frames' size
    window: int = 2             # frames either side that a VP is smoothed over (smooth_sequences' default)
    memory: int = 150           # earlier frames whose accepted VPs a rejected one may fall back to
    cfg: VPConfig = field(default_factory=VPConfig)
    times: StageTimes | None = None  # adds the estimation time to .vp when given

    def __post_init__(self):
        self._held: deque[tuple[int, VPResult]] = deque()  # (frame index, raw estimate), in order
        self._waiting = 0  # how many of the last held frames have no final VP yet

    def estimate(self, frame: np.ndarray) -> VPResult:
        """The frame's raw estimate (:func:`~vcprep.vp.estimate_vp`; pure, so it may
        run in another thread, ahead of :meth:`push`)."""
        t0 = time.perf_counter()
        res = estimate_vp(frame, self.camera, self.cfg)
        if self.times is not None:
            self.times.vp += time.perf_counter() - t0
        return res

    def push(self, index: int, frame: np.ndarray | None = None,
             estimate: VPResult | None = None) -> list[tuple[int, VPResult]]:
        """Add the next frame (or its ``estimate``, computed by :meth:`estimate`); returns the frames
        whose VP is now final, in order."""
        self._held.append((int(index), self.estimate(frame) if estimate is None else estimate))
        self._waiting += 1
        out = []
        while self._waiting > self.window:
            out.append(self._final(len(self._held) - self._waiting))
            self._waiting -= 1
        return out

    def flush(self) -> list[tuple[int, VPResult]]:
        out = [self._final(len(self._held) - k) for k in range(self._waiting, 0, -1)]
        self._waiting = 0
        return out

    def _final(self, pos: int) -> tuple[int, VPResult]:
        held = list(self._held)
        ids = [f"video_{i:09d}" for i, _ in held]  # one sequence; the ids sort in frame order
        cams = [self.camera] * len(held)
        rel = apply_reliability([r for _, r in held], cams, ids)
        lo, hi = max(0, pos - self.window), min(len(held), pos + self.window + 1)
        res = smooth_sequences(ids[lo:hi], rel[lo:hi], cams[lo:hi], self.window)[pos - lo]
        while len(self._held) > self.memory + self._waiting:  # drop what no later frame needs
            self._held.popleft()
        return held[pos][0], res
