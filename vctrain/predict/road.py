"""One road for a frame: image files and folders, through a model, the prior or an exported graph.

Every frame goes the way a video's frames go (:class:`~vctrain.predict.frames.FramePredictor`, in
memory): read, its road VP, warp into the model's virtual camera (a graph warps inside itself),
the network, back-projection to the frame's own pixels, write. One set of checks and rules serves
all of them:

* which VPs the frames get (:func:`within_rule`): the model's own rule for ``--within auto``;
* the virtual camera's rectangle: the training's, and beyond it the model's rule
  (:mod:`vctrain.predict.frames`; ``extend`` and ``hybrid``, the default: the rectangle extended
  once for every frame of the folder at the pose it is warped with, :func:`rectangle_views`, so all
  frames share one rectangle);
* a frame that cannot be read or predicted is skipped: its outputs are removed, the other frames
  are still predicted, and :class:`RoadRun` names it (``vctrain predict`` says it on stderr and
  exits 1); a frame that cannot be written (a full disk) ends the run with its error.

Frames are read on one thread, predicted on the caller's and written on a third, in order
(:mod:`vctrain.predict.pipeline`).

A virtual-camera model's masks are those of the store path (the frames warped into a store with
:func:`vcprep.store.warp_dataset`, then read back: :func:`vctrain.predict.predictor.predict_store`),
bit for bit: the warp is the store build's own body and the store's PNGs are lossless. That path
stays for stores that exist already (``--store``) and for ``--keep-store``.
"""
from __future__ import annotations

import time
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import numpy as np
from tqdm import tqdm

from vcprep.camera import Camera, FrameCameras, camera_of_image
from vcprep.dataset import Job, collect_images
from vcprep.errors import InputError, VCError
from vcprep.io import image_size, read_image
from vcprep.vp import frame_poses as poses_of
from vcprep.warp import pose_from_vp

from ..training.checkpoint_data import CheckpointData
from .kinds import RoadPredictor
from .frames import NEEDS_CAMERA, FramePredictor, extends, warps_frames
from .vehicle import MISSED_VEHICLE, ego_rows, folder_ego_camera, frames_ego_rows, own_vehicle, rows_at, \
    sources_ego_rows  # noqa: F401 (the road's own vehicle, importable from here)
from .pipeline import DEPTH, Prefetch, Writer
from .written import write_prediction

__all__ = ["own_vehicle", "ego_rows", "frames_ego_rows", "sources_ego_rows",
           "rows_at", "folder_ego_camera", "RoadRun", "skipped_lines", "within_rule", "virtual_within",
           "model_vp_rule", "frame_poses", "rectangle_views", "views_of", "frames_canvas", "geometry_line", "run_road",
           "out_dir", "Road", "RoadPlan", "plan_files", "plan_arrays", "road_files"]


@dataclass
class RoadRun:
    """What a run of :func:`predict_images` did: the mask files ``written`` (in order) and the
    frames that ``failed`` ((file, error) pairs, each already said on stderr)."""

    written: list[Path] = field(default_factory=list)
    failed: list[tuple[Path, VCError]] = field(default_factory=list)
    seconds: float = 0.0
    ids: list[str] = field(default_factory=list)  # the frames predicted (their item ids), in order

    def fail(self, job: Job, error: VCError) -> None:
        """Count ``job`` as failed (the caller names the failed frames: :meth:`said`)."""
        self.failed.append((job.image, error))

    def said(self) -> list[str]:
        return skipped_lines(self.failed)


def skipped_lines(failed: list[tuple[Path, VCError]]) -> list[str]:
    """One line per failed frame: 'skipped: <file>: <problem> (<fix>)'."""
    return [f"skipped: {e}" if e.file else f"skipped: {f}: {e}" for f, e in failed]


def out_dir(out: str | Path) -> Path:
    """``out`` as a folder (created): an error if it is a file."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a directory", out, "choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    return out


def within_rule(predictor: RoadPredictor, within: str, camera: Camera | FrameCameras | None) -> str:
    """'estimate', 'none' or a CSV path: which road VPs the frames get (``vctrain predict --within``).

    ``auto``: per-frame VPs when the model was trained with them (a virtual-camera model whose
    training store has estimated VPs, a graph exported with ``--vp-input``), else the camera's
    pose. A resize model takes a VP only through its VP channel, by the same rule (crossval's
    ``resize-vp``: each frame's own estimated VP, as it was trained)."""
    if predictor.takes_frames:
        if not predictor.vp_input:
            if within not in ("auto", "none"):
                raise InputError("this graph has the camera's mount pose built in (exported without --vp-input)",
                                 predictor.path, "drop --within, or export with --vp-input")
            return "none"
        return "estimate" if within == "auto" else within
    if not warps_frames(predictor) and not predictor.vp_channel:
        return "none"
    return virtual_within(predictor.data, within, camera)


def virtual_within(data: CheckpointData, within: str, camera: Camera | FrameCameras | None) -> str:
    """:func:`within_rule` for a model warped into its virtual camera (checkpoint ``data``): 'auto'
    estimates VPs when its training store had estimated ones; calibrated poses (one file, a
    per-frame folder) are no VPs, and a per-frame folder already gives every frame its pose."""
    if within == "auto":
        trained = set(data.vp_status) - {"camera", "calibrated"}
        return "estimate" if trained and not isinstance(camera, FrameCameras) else "none"
    if within != "none" and isinstance(camera, FrameCameras):
        raise InputError("--within needs one camera; a per-frame calibration folder already gives every frame its "
                         "exact pose", camera.folder, "drop --within, or give one camera file or preset")
    return within


def model_vp_rule(data: CheckpointData, override: Any = None) -> tuple[Any, str]:
    """(the :class:`~vcprep.vp.VPRule` frames are estimated with, where it comes from): ``override``
    (given), else the rule the model's training VPs were found with, else the detector's defaults
    (a model whose stores record none)."""
    from vcprep.vp import VPRule

    if override is not None:
        return override, "the given"
    recorded = VPRule.from_dict(data.vp_rule)
    return (recorded, "the model's") if recorded is not None else (VPRule(), "the detector's defaults")


def frame_poses(predictor: RoadPredictor, jobs: list[Job], camera: Camera | FrameCameras | None, rule: str,
                vp_rule: Any = None, on_error=None) -> dict:
    """Each frame's pose (:class:`vcprep.vp.ItemPose`: its road VP in source pixels, status, rule)
    by ``rule`` (:func:`within_rule`); {} for 'none'. Estimated VPs follow ``vp_rule`` or the model's
    (:func:`model_vp_rule`) over the folder's sequences (:func:`vcprep.vp.frame_poses`, the
    one rule of ``vcprep warp``, the store path and a study's stores); ``on_error(job, error)``
    takes a frame that cannot be read."""
    if rule == "none":
        return {}
    poses, _ = poses_of(jobs, camera, rule, model_vp_rule(predictor.data, vp_rule)[0],
                        on_error=(lambda i, e: on_error(jobs[i], e)) if on_error else None)
    return poses or {}


def rectangle_views(jobs: list[Job], camera: Camera | FrameCameras, poses: dict,
                    on_error=None) -> list[tuple[Camera, float, float]]:
    """The (camera, pan, tilt) views the training's rectangle is extended for, once each: every frame
    at its camera's average pose and at the pose it is warped with (``poses``: :func:`frame_poses`;
    :func:`vcprep.camera.extend_canvas`), so a camera wider or steeper than the training cameras is
    predicted whole, at the training's pixels per degree. The one rectangle rule of ``vctrain
    predict`` (a folder, a video: :class:`~vctrain.predict.frames.FramePredictor`) and a study's
    test stores."""
    pairs = []
    for j in jobs:
        try:
            cam = camera_of_image(camera, j.image, image_size(j.image))
        except VCError as e:
            if on_error is None:
                raise
            on_error(j, e)
            continue
        pairs.append((cam, poses[j.id].vp if j.id in poses else None))
    return views_of(pairs)


def views_of(pairs: Iterable[tuple[Camera, tuple[float, float] | None]]) -> list[tuple[Camera, float, float]]:
    """:func:`rectangle_views` of frames given as (their camera at their size, the VP they are warped
    with or None: the camera's average pose)."""
    views, seen = [], set()
    for cam, vp in pairs:
        at = pose_from_vp(cam, vp) if vp is not None else (cam.pan, cam.tilt)
        for pan, tilt in ((cam.pan, cam.tilt), at):
            key = (cam, round(pan, 3), round(tilt, 3))
            if key not in seen:
                seen.add(key)
                views.append((cam, pan, tilt))
    return views


def frames_canvas(virtual: Camera, jobs: list[Job], camera: Camera | FrameCameras, poses: dict | None) -> Camera:
    """``virtual`` (the training's) with its rectangle extended for :func:`rectangle_views`."""
    from vcprep.camera import extend_canvas

    return extend_canvas(virtual, rectangle_views(jobs, camera, poses or {}))


def geometry_line(geo: dict[str, Any], rule_source: str = "", ego_source: str = "") -> str:
    """One line for stderr from what frames were warped with (``vp_status`` counts, ``vp_rule``,
    ``ego_rows``, ``rectangle``): 'VPs: 2 accepted, 1 fallback (the model's rule: ...); own vehicle: 3
    bottom rows never warped (the camera's ego_rows); virtual rectangle 554x240'."""
    from vcprep.vp import VPRule

    counts = ", ".join(f"{n} {k}" for k, n in geo["vp_status"].items())
    rule = VPRule.from_dict(geo["vp_rule"]) if isinstance(geo["vp_rule"], dict) else None
    vps = f"VPs: {counts}" + (f" ({rule_source + ' rule: ' if rule_source else ''}{rule.describe()})" if rule else "")
    rows = "/".join(map(str, geo["ego_rows"]))
    ego = (f"own vehicle: {rows} bottom rows never warped" if geo["ego_rows"] != [0] else "own vehicle: none")
    ego += f" ({ego_source})" if ego_source else ""
    dense = geo.get("density")  # (frames the warp enlarges more than the training's: Predictor.density_scale)
    scale = (f"; frames enlarged {dense['magnification']:.2f}x by the warp, so the network runs at "
             f"{dense['scale']:.2f} of its working size (their own pixel density)" if dense else "")
    return f"{vps}; {ego}; virtual rectangle {geo['rectangle'][0]}x{geo['rectangle'][1]}{scale}"


def _road_geometry(run: "RoadRun", poses: dict, fps: dict, camera) -> dict[str, Any]:
    """What a road's frames were warped with, as :func:`vctrain.predict.predictor.warp_geometry`
    reads it from a store's records (an estimated VP's pose carries its rule; a given one none)."""
    from collections import Counter

    per_frame = isinstance(camera, FrameCameras)
    statuses = Counter(poses[i].status if i in poses else ("calibrated" if per_frame else "camera") for i in run.ids)
    rules = [dict(poses[i].rule) for i in run.ids if i in poses and poses[i].rule]
    rects = {tuple(fp.virtual.size) for fp in fps.values() if fp.virtual is not None}
    dense = [(fp.magnification, fp.predictor.density_scale(fp.magnification)) for fp in fps.values()
             if fp.virtual is not None and hasattr(fp.predictor, "density_scale")]
    dense = [d for d in dense if d[1] < 1.0]
    return {"vp_status": dict(sorted(statuses.items())), "vp_rule": rules[0] if rules else None,
            "ego_rows": sorted({int(k[0].ego_rows) for k in fps if k[0] is not None}) or [0],
            "rectangle": list(rects.pop()) if len(rects) == 1 else [0, 0],
            **({"density": {"magnification": max(dense)[0], "scale": max(dense)[1]}} if dense else {})}


def _remove_outputs(out: Path, stem: str) -> None:
    for suffix in ("prob", "mask", "overlay"):
        (out / f"{stem}_{suffix}.png").unlink(missing_ok=True)


def _read(jobs: list[Job]):
    """(job, decoded image or None, the VCError that stopped it or None) of each job, in order."""
    for job in jobs:
        try:
            yield job, read_image(job.image).array, None
        except VCError as e:
            yield job, None, e


class Road:
    """P(road) of frames on the one road: one :class:`~vctrain.predict.frames.FramePredictor` per
    (camera, frame size, own vehicle's rows), made on first use. ``camera``: the frames' (a
    :class:`~vcprep.camera.FrameCameras` gives each file its own); ``views``: the (camera, pan, tilt)
    views every frame's rectangle is extended for (:func:`rectangle_views`; None: each predictor's
    own); ``vehicle``: (rows, at frame height) of the own vehicle a model that reads frames as they
    are predicts 'not road' on, or file -> that per source (:func:`frames_ego_rows`)."""

    def __init__(self, predictor: RoadPredictor, camera: Camera | FrameCameras | None, views: list | None = None,
                 vehicle: tuple[int, int] | dict | None = None):
        self.predictor, self.camera, self.views, self.vehicle = predictor, camera, views, vehicle
        self.fps: dict = {}

    def probability(self, img: np.ndarray, vp: tuple[float, float] | None = None,
                    image: str | Path = "frame") -> np.ndarray:
        """P(road) float32 (h, w) of the decoded frame ``img`` (BGR) warped at ``vp`` (its road VP in
        frame pixels; None: the camera's average pose); ``image`` names its file (its calibration in
        a per-frame folder, its source's own vehicle, errors)."""
        size = (img.shape[1], img.shape[0])
        self.predictor.check_frame_size(size, image)  # (a graph takes frames of its own size only)
        cam = camera_of_image(self.camera, image, size) if self.camera is not None else None
        v = self.vehicle
        rows = rows_at(v.get(image) if isinstance(v, dict) else v, size[1])  # dict: per source
        fp = self.fps.get((cam, size, rows))
        if fp is None:
            fp = self.fps[(cam, size, rows)] = FramePredictor(self.predictor, cam, size, views=self.views,
                                                              ego_rows=rows)
        return fp.predict(img, vp)


@dataclass
class RoadPlan:
    """What a batch of frames is predicted with: the :class:`Road`, which VPs the model takes
    (``rule``: :func:`within_rule`) and each frame's pose (``poses``: item id ->
    :class:`vcprep.vp.ItemPose`), and with ``--bev`` its :class:`~vctrain.predict.bev.BevRun` and
    the poses the bird's-eye view takes."""

    road: Road
    rule: str
    poses: dict
    bev_run: Any = None
    bev_poses: dict = field(default_factory=dict)

    def vp(self, key: str) -> tuple[float, float] | None:
        """The road VP frame ``key`` is warped with (None: its camera's average pose)."""
        return self.poses[key].vp if key in self.poses else None

    def bev_pose(self, key: str) -> tuple:
        """(vp, status) of frame ``key``'s bird's-eye view, () for its camera's pose."""
        pose = self.bev_poses.get(key)
        return (pose.vp, pose.status) if pose else ()


def _needs_camera(predictor: RoadPredictor, camera: Any) -> None:
    if warps_frames(predictor) and camera is None:
        raise InputError("a virtual-camera model needs the camera of the images", predictor.path,
                         NEEDS_CAMERA)


def plan_files(predictor: RoadPredictor, jobs: list[Job], camera: Camera | FrameCameras | None, within: str = "auto",
               vp_rule: Any = None, vehicle: tuple[int, int] | dict | None = None, bev: Any = None,
               on_error: Callable[[Job, VCError], None] | None = None) -> RoadPlan:
    """The :class:`RoadPlan` of image files ``jobs``: their VPs by ``within`` (:func:`within_rule`)
    estimated together (:func:`frame_poses`), the rectangle extended once for all of them
    (:func:`rectangle_views`), ``bev`` (given: :class:`~vctrain.predict.bev.BevOptions`) and its
    poses; ``on_error(job, error)`` takes a frame that cannot be read (raised where None)."""
    _needs_camera(predictor, camera)
    rule = within_rule(predictor, within, camera)
    poses = frame_poses(predictor, jobs, camera if camera is not None else predictor.camera, rule,
                        vp_rule, on_error)
    bev_run, bev_poses = _bev_poses(predictor, bev, jobs, camera, within, rule, poses, vp_rule, on_error)
    views = None
    if extends(predictor):
        views = rectangle_views([j for j in jobs if rule == "none" or j.id in poses], camera, poses, on_error)
    return RoadPlan(Road(predictor, camera, views, vehicle), rule, poses, bev_run, bev_poses)


def plan_arrays(predictor: RoadPredictor, frames: list[np.ndarray], camera: Camera | None, within: str = "auto",
                vp_rule: Any = None, vehicle: tuple[int, int] | None = None, bev: Any = None,
                vps: list | None = None) -> tuple[RoadPlan, list[str]]:
    """(:func:`plan_files`' plan, the frames' ids ``frame_000000``, ...) of decoded ``frames`` of one
    camera, a folder of their files would get: VPs estimated together in order (one sequence;
    :func:`vcprep.vp.array_poses`, the numbers of the files) or given (``vps``: one (u, v) a frame),
    one rectangle for all of them."""
    _needs_camera(predictor, camera)
    from vcprep.vp import ItemPose, array_poses

    rule = within_rule(predictor, within, camera)
    cam = camera if camera is not None else predictor.camera  # (a graph's own)
    ids = [f"frame_{i:06d}" for i in range(len(frames))]
    if vps is not None:
        poses = {i: ItemPose((float(v[0]), float(v[1])), "given") for i, v in zip(ids, vps)} if rule != "none" else {}
    else:
        poses = array_poses(frames, cam, rule, model_vp_rule(predictor.data, vp_rule)[0], ids)
    bev_run, bev_poses = None, {}
    if bev is not None:
        from .bev import BevRun

        bev_run = BevRun(bev, cam, within, predictor.path)
        bev_poses = poses if bev_run.rule == rule else array_poses(
            frames, cam, bev_run.rule, model_vp_rule(predictor.data, vp_rule)[0], ids)
    views = None
    if extends(predictor):
        views = views_of((cam.for_image_size((f.shape[1], f.shape[0])), poses[i].vp if i in poses else None)
                         for i, f in zip(ids, frames))
    return RoadPlan(Road(predictor, camera, views, vehicle), rule, poses, bev_run, bev_poses), ids


def _bev_poses(predictor: RoadPredictor, bev: Any, jobs: list[Job], camera, within: str, rule: str, poses: dict,
               vp_rule: Any, on_error=None) -> tuple[Any, dict]:
    """(``--bev``'s :class:`~vctrain.predict.bev.BevRun`, each frame's pose for it: the model's
    ``poses`` where it takes the same rule, else found by its own); (None, {}) without ``bev``."""
    if bev is None:
        return None, {}
    from .bev import BevRun

    camera = camera if camera is not None else predictor.camera  # a graph's own
    bev_run = BevRun(bev, camera, within, jobs[0].image if jobs else None)
    if bev_run.rule == rule:
        return bev_run, poses
    return bev_run, frame_poses(predictor, jobs, camera, bev_run.rule, vp_rule, on_error)


def road_files(plan: RoadPlan, jobs: list[Job], skip: set[str] = frozenset(), progress: bool = True
               ) -> Iterator[tuple[Job, np.ndarray | None, np.ndarray | None, VCError | None]]:
    """(job, decoded frame, P(road), None) of each image file of ``jobs`` (those whose file is in
    ``skip`` left out), in order, through ``plan``'s road; (job, frame or None, None, error) for
    one that cannot be read or predicted. Read on a thread of its own, :data:`DEPTH` frames ahead."""
    todo = [j for j in jobs if str(j.image) not in skip]
    with Prefetch(_read(todo), DEPTH) as frames:
        for job, img, error in tqdm(frames, total=len(todo), desc="predict", unit="img",
                                    disable=None if progress else True, leave=False):
            try:
                if error is not None:
                    raise error
                prob = plan.road.probability(img, plan.vp(job.id), job.image)
            except VCError as e:
                yield job, img, None, e
                continue
            yield job, img, prob, None


def run_road(predictor: RoadPredictor, images: Iterable[str | Path], out: str | Path,
             camera: Camera | FrameCameras | None, progress: bool = True, overlay: bool = False,
             within: str = "auto", vp_rule: Any = None, say: Callable[[str], None] | None = None,
             ego_source: str = "", vehicle: tuple[int, int] | dict | None = None, bev: Any = None,
             jobs: list[Job] | None = None) -> RoadRun:
    """Predict image files/folders taken with ``camera`` (needed for virtual-camera models; a
    :class:`~vcprep.camera.FrameCameras` gives every image its own calibrated camera and pose);
    writes ``<stem>_mask.png``, ``<stem>_prob.png`` (and ``_overlay.png``) in ``out``. A frame that
    fails is skipped and named in the result (module docstring).

    ``within``: per-image pan/tilt from the road VP ('estimate', a CSV ``id,u,v``, 'none', or
    'auto': :func:`within_rule`); estimated VPs follow ``vp_rule`` or the model's
    (:func:`model_vp_rule`). ``say`` (given) hears one line: which VPs, own vehicle (``ego_source``:
    where its rows come from) and rectangle a virtual-camera model's frames were warped with. ``vehicle``
    (rows, at frame height, or file -> that per source; :func:`frames_ego_rows`): a model that reads
    frames as they are predicts 'not road' on the own vehicle's rows. ``bev`` (given:
    :class:`vctrain.predict.bev.BevOptions`): each frame's BEV and road in metres too, at its pose by
    ``within`` (:mod:`vctrain.predict.bev`). ``jobs``: ``images`` already collected (the caller's)."""
    t0 = time.perf_counter()
    jobs = jobs if jobs is not None else collect_images(images, trees=True)  # (a tree: outputs mirror it)
    out = out_dir(out)
    run = RoadRun()
    plan = plan_files(predictor, jobs, camera, within, vp_rule, vehicle, bev, run.fail)
    writer = Writer(DEPTH)  # read on one thread, the network on this one, written on a third, in order

    def write(job: Job, prob: np.ndarray, img: np.ndarray) -> None:
        inset = plan.bev_run.write(out, job.id, prob, job.image, *plan.bev_pose(job.id)) \
            if plan.bev_run is not None else None
        run.written.append(write_prediction(out, job.id, prob, img if overlay else None, inset)[0])
    try:
        with closing(road_files(plan, jobs, {str(f) for f, _ in run.failed}, progress)) as frames:
            for job, img, prob, error in frames:
                if error is not None:
                    _remove_outputs(out, job.id)
                    run.fail(job, error)
                    continue
                writer.submit(write, job, prob, img)
                run.ids.append(job.id)
        writer.close()
    except BaseException:
        writer.abort()
        raise
    if say is not None and warps_frames(predictor) and run.ids:
        source = model_vp_rule(predictor.data, vp_rule)[1]
        say(geometry_line(_road_geometry(run, plan.poses, plan.road.fps, camera), source, ego_source))
    run.seconds = time.perf_counter() - t0
    return run
