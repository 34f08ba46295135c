"""A model you call from Python: :func:`load` then :meth:`RoadModel.segment` (one frame in memory),
:meth:`RoadModel.segment_frames` (several frames of one camera, as a folder of them), and
:meth:`RoadModel.segment_video` (a video, frame by frame). ``vctrain predict`` is one caller of the
same road (:mod:`vctrain.predict.road`, :mod:`vctrain.predict.video`): the masks are its masks, bit
for bit.

Conventions: a frame is a numpy array H x W x 3, uint8, in OpenCV's **BGR** channel order (what
``cv2.imread`` and ``cv2.VideoCapture`` give); anything else is refused (:func:`check_frame`). A
result (:class:`Segmentation`) is in the frame's own pixels: ``prob`` H x W float32 P(road),
``mask`` H x W bool (``prob >= 0.5``: the 255 of predict's ``_mask.png``). VPs are (u, v) in frame
pixels, origin at the centre of the top-left pixel; a pose is (pan, tilt) in degrees
(:func:`vcprep.warp.pose_from_vp`).

A ``camera`` is anything ``--camera`` takes (:func:`vcprep.camera.camera_from_spec`): a preset name
('kitti', 'camvid', ...), a camera YAML file, a KITTI ``.txt`` or Cityscapes ``.json`` calibration
file, a :class:`vcprep.camera.Camera`, or 'estimate' (from the frames given: at least five).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

from vcprep.camera import Camera, camera_of_image
from vcprep.errors import InputError

from ..shipped import resolve_model
from .bev import BevMeasure, BevOptions
from .kinds import RoadPredictor
from .frames import reads_road_vps, refuse_mixed, warps_frames
from .settings import DEFAULT_ENGINE, GRAPH_ENGINE
from .road import plan_arrays
from .written import road_mask

__all__ = ["load", "RoadModel", "Segmentation", "check_frame", "open_predictor", "engine_used"]

# the fix of the API's "needs the camera" errors (the commands say --camera)
GIVE_CAMERA = ("give camera=: a preset ('kitti', 'camvid', ...), a camera YAML or calibration file, a "
               "vcprep.camera.Camera, or 'estimate' (from several frames)")


@dataclass(frozen=True)
class Segmentation:
    """The road in one frame (module docstring: conventions). ``vp``: the road VP the frame was
    warped with (None: its camera's average pose, or a model that takes none); ``vp_status``:
    'accepted', 'fallback', 'given' or None; ``pose``: (pan, tilt) degrees of the camera at that VP
    (None without a camera); ``bev`` (``bev=True``): the bird's-eye view
    (:class:`vctrain.predict.bev.BevMeasure`: ``prob``, ``mask``, ``grid``); ``index``: the frame's
    place in its video or list; ``source``: its file (:meth:`RoadModel.segment_files`)."""

    prob: np.ndarray
    mask: np.ndarray
    vp: tuple[float, float] | None = None
    vp_status: str | None = None
    pose: tuple[float, float] | None = None
    camera: Camera | None = None
    bev: BevMeasure | None = None
    index: int = 0
    source: str | None = None  # the frame's file (segment_files)

    @property
    def metres(self) -> dict[str, Any]:
        """The road in metres, as ``vctrain predict --bev`` prints it: ``free_m`` (how far the corridor
        ahead is road), ``width_m`` at 10, 20 and 30 m (None where not all in view), ``area_m2``,
        ``pose`` (needs ``bev=True``)."""
        if self.bev is None:
            raise InputError("no bird's-eye view was asked for", None, "segment with bev=True (and a camera)")
        return self.bev.metres


def check_frame(frame: Any, what: str = "frame") -> np.ndarray:
    """``frame`` if it is an H x W x 3 uint8 array (BGR); else the project's error saying what was
    expected and what came."""
    if not isinstance(frame, np.ndarray):
        raise InputError(f"{what} is a {type(frame).__name__}, expected a numpy array H x W x 3 uint8 (BGR)", None,
                         "decode it first: cv2.imread(path)")
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        raise InputError(f"{what} is a {frame.dtype} array of shape {frame.shape}, expected H x W x 3 uint8 (BGR, "
                         "as cv2.imread gives it)", None,
                         "convert it: cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), "
                         "or (img16 // 257).astype(np.uint8)")
    if min(frame.shape[:2]) < 16:
        raise InputError(f"{what} is {frame.shape[1]}x{frame.shape[0]} pixels, too small to segment", None,
                         "give a camera frame (at least 16 pixels a side)")
    return frame


def open_predictor(model: str | Path, device: str = "auto", engine: str | None = None, prior: bool = False,
                   output: str = "road"):
    """The predictor of ``model``: an exported graph (``.onnx``: :class:`~vctrain.deploy.runtime.OnnxPredictor`),
    the geometric prior (``prior``: :class:`~vctrain.adapt.PriorPredictor`) or a checkpoint's network on
    ``device`` through ``engine`` (None: :data:`~vctrain.predict.settings.DEFAULT_ENGINE` for a checkpoint,
    the fastest engine installed; :data:`~vctrain.predict.settings.GRAPH_ENGINE` for a graph). ``output``:
    which output it gives, 'road' or 'drivable' (a model trained with two, :mod:`vctrain.training.outputs`;
    a graph exported for it); one it does not have is refused."""
    path = Path(model)
    if not prior and path.suffix.lower() == ".onnx":
        from ..deploy.runtime import OnnxPredictor

        if engine == "torch":
            raise InputError("an exported graph runs in OpenVINO or onnxruntime, not PyTorch", path,
                             "drop --engine torch, or give the .pt model")
        return OnnxPredictor(path, runtime=engine or GRAPH_ENGINE, output=output)
    if prior:
        from ..adapt import PriorPredictor
        from ..training.outputs import ONE_OUTPUT, check_output

        check_output(output, ONE_OUTPUT, path)  # (the prior is the road's)
        return PriorPredictor(path)
    from .predictor import Predictor

    return Predictor(path, device, engine or DEFAULT_ENGINE, output=output)


def engine_used(predictor) -> str:
    """What runs the network, as stderr and predict.json say it ('' for the prior: no network)."""
    from ..deploy.engine import engine_name
    from ..deploy.runtime import runtime_name

    if predictor.takes_frames:
        return f"{runtime_name(predictor.runtime)}, the graph{' (int8)' if predictor.info.get('int8') else ''}"
    kind = predictor.engine
    if kind is None:
        return ""
    device = str(predictor.device)
    return engine_name(kind) + (", the network exported in memory" if kind != "torch" else "") + \
        (f" on {device}" if device != "cpu" else "")


def load(name_or_path: str | Path, engine: str | None = None, device: str = "auto",
         beyond: str | None = None, output: str = "road") -> "RoadModel":
    """A road model ready to segment frames: ``name_or_path`` a checkpoint written by ``vctrain fit``
    (``.pt``, a virtual-camera or a resize model), a shipped model's name from any folder
    ('shipped'), or a graph written by ``vctrain export`` (``.onnx``). ``engine``: what runs a
    ``.pt``'s network (None or 'auto': OpenVINO, else onnxruntime, on the CPU where installed, else
    PyTorch, as ``vctrain predict`` by default; 'torch': a study's masks bit for bit; 'onnx',
    'openvino') or a graph's ('onnx', 'openvino'; None: the fastest installed); ``device``: 'auto',
    'cpu', 'cuda:N' (a GPU runs PyTorch);
    ``beyond``: a virtual-camera model's rule for frame pixels outside its training rectangle
    (:data:`vctrain.predict.frames.BEYOND`; None: the default); ``output``: 'road' (P(road), every model)
    or 'drivable' (P(drivable area): a model trained with ``--outputs road,drivable``, or a graph exported for
    it); ``Segmentation.prob`` and ``mask`` are then that output's."""
    path = resolve_model(name_or_path)
    predictor = open_predictor(path, device, engine, output=output)
    if beyond is not None:
        set_beyond(predictor, beyond, path)
    return RoadModel(predictor)


def set_beyond(predictor: RoadPredictor, beyond: str, path: Path) -> None:
    """``beyond`` checked, and given to a virtual-camera model (the only kind it concerns)."""
    from vcprep.errors import one_of

    from .frames import BEYOND

    if beyond not in BEYOND:
        raise InputError(f"unknown --beyond '{beyond}'", None, one_of(beyond, BEYOND))
    if predictor.beyond_rule is None or predictor.mode != "virtual" or predictor.takes_frames:
        raise InputError("--beyond is for a virtual-camera model (.pt); a resize model, the prior and an "
                         "exported graph (rays, inside it) have no choice to make", path, "drop --beyond")
    predictor.beyond_rule = beyond


class RoadModel:
    """A loaded model (:func:`load`): its ``predictor`` and what it needs. Thread-confined: one
    RoadModel per thread (its frame predictors keep caches)."""

    def __init__(self, predictor: RoadPredictor):
        refuse_mixed(predictor)
        self.predictor = predictor
        self.path = Path(predictor.path)

    def __repr__(self) -> str:
        return f"RoadModel({str(self.path)!r}, {self.kind}, needs_camera={self.needs_camera})"

    @property
    def kind(self) -> str:
        """'virtual' (warps frames into its virtual camera), 'resize' (reads frames as they are) or
        'graph (virtual)' / 'graph (resize)' (an exported graph, the camera inside)."""
        mode = self.predictor.mode
        return f"graph ({mode})" if self.predictor.takes_frames else mode

    @property
    def needs_camera(self) -> bool:
        """Whether ``segment`` needs ``camera``: a virtual-camera model, or one that reads each frame's VP."""
        return warps_frames(self.predictor) or (reads_road_vps(self.predictor)
                                                and not self.predictor.takes_frames)

    @property
    def engine(self) -> str:
        """What runs the network ('PyTorch 2.13.0', 'onnxruntime 1.x, the graph', ...)."""
        return engine_used(self.predictor)

    def segment(self, frame: np.ndarray, camera: Any = None, *, bev: bool = False, within: str = "auto",
                vp: tuple[float, float] | None = None, ego: str | int | None = None,
                grid: Any = None, corridor: float | None = None) -> Segmentation:
        """The road in one ``frame`` (H x W x 3 uint8 BGR) of ``camera`` (module docstring; needed by
        a virtual-camera model), as ``vctrain predict`` finds it in a folder holding that frame alone.
        ``within``: which road VP the frame is warped with ('auto': as the model was trained,
        'estimate', 'none': the camera's average pose); ``vp`` (u, v): a known one instead. ``ego``:
        the own vehicle (None: the model's default; 'none', 'auto', or a number of bottom rows).
        ``bev``: also the bird's-eye view and the road in metres (:attr:`Segmentation.metres`) on
        ``grid`` (a :class:`vcprep.bev.BevGrid`; default the KITTI benchmark's) along a
        ``corridor`` metres wide."""
        return self.segment_frames([check_frame(frame)], camera, bev=bev, within=within,
                                   vps=None if vp is None else [vp], ego=ego, grid=grid, corridor=corridor)[0]

    def segment_frames(self, frames: Sequence[np.ndarray], camera: Any = None, *, bev: bool = False,
                       within: str = "auto", vps: Sequence[tuple[float, float]] | None = None,
                       ego: str | int | None = None, grid: Any = None,
                       corridor: float | None = None) -> list[Segmentation]:
        """:meth:`segment` of several frames of one camera, in order, as ``vctrain predict`` does a
        folder of them: their VPs estimated together (one sequence), one virtual rectangle for all,
        their own vehicle found from them (as one source: predict searches a folder whose file names
        tell several sources apart source by source); ``camera`` 'estimate' is estimated from them."""
        frames = [check_frame(f, f"frame {i}") for i, f in enumerate(frames)]
        if not frames:
            raise InputError("no frames given", None, "give a list of H x W x 3 uint8 BGR arrays")
        if vps is not None and len(vps) != len(frames):
            raise InputError(f"{len(vps)} VPs for {len(frames)} frames", None, "give one (u, v) per frame")
        p = self.predictor
        cam = self._camera(camera, frames, bev)
        cam, vehicle = self._own_vehicle(cam, frames, ego)
        plan, ids = plan_arrays(p, frames, cam, within, None, vehicle, self._bev_options(bev, camera, grid, corridor),
                                vps)
        out = []
        for k, (key, frame) in enumerate(zip(ids, frames)):
            prob = plan.road.probability(frame, plan.vp(key), key)
            measure = plan.bev_run.measure(prob, key, *plan.bev_pose(key)) if plan.bev_run is not None else None
            out.append(self._result(prob, frame, plan.vp(key), plan.poses.get(key), cam, measure, k))
        return out

    def segment_files(self, images: Sequence[str | Path], camera: Any = None, *, bev: bool = False,
                      within: str = "auto", ego: str | int | None = None, grid: Any = None,
                      corridor: float | None = None) -> Iterator[Segmentation]:
        """:meth:`segment` of image files and folders (read as ``vctrain predict`` reads them, in its
        order), yielded one by one: the very road ``vctrain predict`` takes them on (its VP sequences
        by file name, its own vehicle per source, a folder of per-frame calibration files as
        ``camera``), the frame's file in :attr:`Segmentation.source`. A frame that cannot be read or
        predicted raises its error."""
        from vcprep.camera import camera_from_spec
        from vcprep.dataset import collect_images

        from .road import plan_files, road_files
        from .vehicle import files_vehicle

        jobs = collect_images(images, trees=True)
        files = [j.image for j in jobs]
        cam = None
        if camera is None:
            self._camera(None, files, bev)  # (the error where one is needed)
        else:
            cam = camera_from_spec(camera, files[0], per_frame=True, frames=files)
        cam, rows, _ = files_vehicle(self.predictor, cam, files, None if ego is None else str(ego))
        plan = plan_files(self.predictor, jobs, cam, within, None, rows, self._bev_options(bev, camera, grid, corridor))
        for k, (job, img, prob, error) in enumerate(road_files(plan, jobs, progress=False)):
            if error is not None:
                raise error
            measure = plan.bev_run.measure(prob, job.image, *plan.bev_pose(job.id)) if plan.bev_run else None
            at = camera_of_image(cam, job.image, (img.shape[1], img.shape[0])) if cam is not None else None
            yield replace(self._result(prob, img, plan.vp(job.id), plan.poses.get(job.id), at, measure, k),
                          source=str(job.image))

    def segment_video(self, source: str | Path, camera: Any = None, *, bev: bool = False, within: str = "auto",
                      ego: str | int | None = None, grid: Any = None, corridor: float | None = None,
                      vp_window: int = 2) -> Iterator[Segmentation]:
        """The road in every frame of the video file ``source``, yielded in order as the frames are
        read, with a video's rules (those of ``vctrain predict`` on the video): per-frame VPs smoothed
        over ``vp_window`` frames either side (a frame comes out once its VP is final), the own
        vehicle found from frames spread over the video. An undecodable frame is left out (its
        ``index`` is skipped)."""
        from .video import VideoStream

        cam = self._camera(camera, [Path(source)], bev)
        if cam is not None and not isinstance(cam, Camera):
            raise InputError("a video takes one camera, not a folder of per-frame calibration files", None,
                             GIVE_CAMERA)
        stream = VideoStream(self.predictor, source, cam, within, None if ego is None else str(ego), progress=False,
                             vp_window=vp_window, bev=self._bev_options(bev, camera, grid, corridor))
        try:
            road = stream.road
            for i, frame, prob, vp, status in stream:
                if frame is None:
                    continue
                measure = road.bev_run.measure(prob, stream.path, vp, status) if road.bev_run is not None else None
                pose = _Pose(vp, status) if vp is not None and road.model_vps else None
                yield self._result(prob, frame, vp if road.model_vps else None, pose, road.fp.camera, measure, i)
        finally:
            stream.close()

    def _camera(self, camera: Any, frames: list, bev: bool) -> Camera | None:
        """The frames' camera from ``camera`` (checked even where the model needs none: a typo is never
        silent); the model's error naming ``camera`` where it needs one and none was given."""
        from vcprep.camera import camera_from_spec

        if camera is None:
            own = self.predictor.camera  # (a graph's)
            if self.needs_camera or (bev and own is None):
                what = "a bird's-eye view" if not self.needs_camera else \
                    "a virtual-camera model" if warps_frames(self.predictor) else "a model that reads each frame's VP"
                raise InputError(f"{what} needs the frames' camera: camera is None", self.path, GIVE_CAMERA)
            return None
        size = (frames[0].shape[1], frames[0].shape[0]) if isinstance(frames[0], np.ndarray) else None
        return camera_from_spec(camera, None, per_frame=False, frames=frames, size=size)

    def _own_vehicle(self, cam: Camera | None, frames: list[np.ndarray], ego: Any) -> tuple[Camera | None, Any]:
        """(the camera with its own vehicle's rows, (rows, height) a resize model cuts) by ``vctrain
        predict``'s rules for a folder of one camera's frames (:func:`vctrain.predict.vehicle.folder_ego_camera`)."""
        from vcprep.camera import ego_rows_from_frames, spread
        from vcprep.io import EGO_SAMPLES

        from .vehicle import ego_rows, own_vehicle

        p, ego = self.predictor, None if ego is None else str(ego)
        size = (frames[0].shape[1], frames[0].shape[0])
        same = [f for f in frames if (f.shape[1], f.shape[0]) == size]
        search = lambda: ego_rows_from_frames(spread(same, EGO_SAMPLES), "frames")  # noqa: E731
        if p.takes_frames:
            return cam, None
        if not warps_frames(p) and not reads_road_vps(p):  # a resize model: cut where asked
            if ego in (None, "none"):
                return cam, None
            stated = cam.for_image_size(size).ego_rows if cam is not None else 0
            return cam, (ego_rows(size[1], stated, "frames", ego, None, search), size[1])
        if cam is None:
            return cam, None
        return own_vehicle(cam.for_image_size(size), "frames", ego or "auto", None, search), None

    def _bev_options(self, bev: bool, camera: Any, grid: Any, corridor: float | None) -> BevOptions | None:
        if not bev:
            return None
        from vcprep.bev import CORRIDOR, KITTI_GRID

        return BevOptions(grid=grid or KITTI_GRID, corridor=CORRIDOR if corridor is None else float(corridor),
                          spec=str(camera) if isinstance(camera, (str, Path)) else None)

    def _result(self, prob: np.ndarray, frame: np.ndarray, vp: Any, pose: Any, cam: Camera | None,
                measure: BevMeasure | None, index: int) -> Segmentation:
        from vcprep.warp import pose_from_vp

        at = cam.for_image_size((frame.shape[1], frame.shape[0])) if cam is not None else None
        angles = None
        if at is not None:
            angles = pose_from_vp(at, vp) if vp is not None else (at.pan, at.tilt)
            angles = (float(angles[0]), float(angles[1]))
        return Segmentation(prob, road_mask(prob) != 0, None if vp is None else (float(vp[0]), float(vp[1])),
                            getattr(pose, "status", None), angles, at, measure, index)


@dataclass(frozen=True)
class _Pose:
    vp: Any
    status: str | None
